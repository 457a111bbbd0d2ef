"""Where the assist's arm hands the part over: beyond the reach of the finished assembly.

A person turning the assembly over about its root sweeps a sphere whose radius is the
finished assembly's reach (:func:`assembly_reach`). The hand-over pose
(:func:`handover_pose`) lies just beyond it on the arm's side, the gripper pointing
down (:func:`down_quat`); a large part is also tried turned about the vertical and
raised (:func:`handover_targets`), held farthest from the sphere first
(:func:`targets_farthest_first`).

Frames: world, metres; quaternions x y z w.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.live.state import Slot
from thirdhand.segment.contact import body_box, box_corners

#: How far above the hand-over pose its second set of tries is, metres.
HANDOVER_RAISE_M = 0.15

Pose = tuple[FloatArray, FloatArray]


def down_quat(direction: FloatArray) -> FloatArray:
    """A gripper orientation pointing down (tool z = −world z), tool x along ``direction`` (2,)
    (world x when it is zero); shape (4,), x y z w."""
    d = np.asarray(direction, dtype=np.float64)
    n = float(np.linalg.norm(d))
    x = np.array([1.0, 0.0, 0.0]) if n < 1e-9 else np.array([d[0] / n, d[1] / n, 0.0])
    z = np.array([0.0, 0.0, -1.0])
    y = np.cross(z, x)
    return np.asarray(se3.quat_from_matrix(np.stack([x, y, z], axis=1)), dtype=np.float64)


def handover_pose(
    root: FloatArray,
    away: FloatArray,
    reach_m: float,
    handover_m: tuple[float, float, float],
) -> Pose:
    """The hand-over pose: ``handover_m`` (towards the arm beyond ``reach_m``, sideways, up)
    from the root's position ``root`` (3,), along ``away`` (2,, unit: from the person to
    the root); the gripper pointing down, its x along ``away``."""
    side = np.array([-away[1], away[0]])
    up, toward, lateral = handover_m[2], reach_m + handover_m[0], handover_m[1]
    hp = np.array([*(root[:2] + toward * away + lateral * side), root[2] + up])
    return hp, down_quat(away)


def handover_targets(handover: Pose) -> list[Pose]:
    """The hand-over pose, then turned about the vertical and raised (a large part held
    at the first may touch the assembly or the person): yaw 0, ±90°, 180° at the
    pose's height and :data:`HANDOVER_RAISE_M` above it."""
    pos, quat = handover
    out = []
    for dz in (0.0, HANDOVER_RAISE_M):
        for yaw in (0.0, 0.5 * math.pi, -0.5 * math.pi, math.pi):
            turn = np.array([0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)])
            out.append((pos + np.array([0.0, 0.0, dz]), np.asarray(se3.quat_multiply(turn, quat))))
    return out


def targets_farthest_first(
    handover: Pose,
    centre: FloatArray,
    size: FloatArray,
    t_tool_part: FloatArray,
    root0: FloatArray,
) -> list[Pose]:
    """The hand-over tool poses (:func:`handover_targets`) in the order they are tried.

    The part (box ``centre``, ``size`` (3,), part frame), held as grasped
    (``t_tool_part`` (4, 4): its frame in the tool's), farthest from the sphere the person
    sweeps turning the assembly over (the assembly's reach about the root's first
    position ``root0`` (3,)) first: its nearest box corner farthest from ``root0``. The
    person also lifts and moves the assembly: on chair 16 a 42-cm back held 3 cm outside
    the sphere met a leg of the chair turned over above the table, 13 cm nearer the arm.
    """
    corners = box_corners((centre - size / 2.0, centre + size / 2.0))  # part frame
    ranked = []
    for target in handover_targets(handover):
        t_part = se3.matrix_from_pose(*target) @ t_tool_part
        world = corners @ t_part[:3, :3].T + t_part[:3, 3]
        ranked.append((float(np.linalg.norm(world - root0, axis=1).min()), target))
    ranked.sort(key=lambda r: -r[0])
    return [target for _, target in ranked]


def assembly_reach(
    slots: Sequence[Slot],
    names: Sequence[str],
    meta: Mapping[str, Any],
    root: str,
    part_size_m: float = 0.05,
) -> float:
    """How far the finished assembly reaches from its root, metres.

    Every plan step's child is put at its learned pose in its parent (composed from
    the root ``root``, :class:`~thirdhand.live.state.Slot`); the result is the largest
    distance of any corner of any part's box from the root's origin. A person turning
    the assembly over about its root sweeps this sphere. Boxes: the stream's
    ``geometry`` of the body that may fill each step (``names``: the stream's bodies,
    by row), a cube of ``part_size_m`` without one.
    """
    ident = np.array([0.0, 0.0, 0.0, 1.0])
    poses: dict[str, Pose] = {root: (np.zeros(3), ident)}
    body = {root: root}
    pending = list(slots)
    while pending:
        ready = [s for s in pending if s.parent in poses]
        if not ready:
            break  # steps whose parent no step places: not part of the assembly
        for s in ready:
            pp, pq = poses[s.parent]
            if s.child not in poses:
                poses[s.child] = (pp + se3.quat_rotate(pq, s.pos), se3.quat_multiply(pq, s.quat))
                body[s.child] = names[s.candidates[0][1]] if s.candidates else s.child
            pending.remove(s)
    half = np.full(3, part_size_m / 2.0)
    reach = 0.0
    for name, (p, q) in poses.items():
        box = body_box(meta, body[name])
        pts = p + se3.quat_rotate(q, box_corners(box if box is not None else (-half, half)))
        reach = max(reach, float(np.linalg.norm(pts, axis=1).max()))
    return reach


__all__ = [
    "HANDOVER_RAISE_M",
    "assembly_reach",
    "down_quat",
    "handover_pose",
    "handover_targets",
    "targets_farthest_first",
]
