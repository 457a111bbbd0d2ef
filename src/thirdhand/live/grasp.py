"""The assist's grasp of a tracked part from above, and the straight lift off what it rests on.

The part's box (:func:`part_box`) gives the grasps: the top-down one over its centre
(:func:`top_grasp`), then the execution stage's shape grasps that come from above
(:func:`grasp_targets`). Once grasped, the part may touch what it lies on
(:func:`resting_on`: the table, parts against it) only during the straight lift
that takes it off them (:func:`lift_clear`).

Frames: world, metres; quaternions x y z w.
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from typing import TYPE_CHECKING

import numpy as np

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.live.handover import down_quat
from thirdhand.segment.contact import box_corners

if TYPE_CHECKING:
    from thirdhand.execute.robot import Robot
    from thirdhand.execute.scene import CollisionScene

#: A grasp comes from above when the tool's approach axis has this cosine with straight down.
DOWN_COS = 0.7
#: How much less deep the second try of each grasp from above goes, metres.
SHALLOWER_M = 0.01
#: Most grasp poses tried per assist (each one an IK search).
MAX_GRASPS = 16
#: The straight lift after a grasp: ``lift_m`` times the first of these that leaves the part
#: touching nothing (two legs lying side by side, tilted, meet 6 cm up).
LIFT_STEPS = (1, 2, 3)

Pose = tuple[FloatArray, FloatArray]


def part_box(
    box: tuple[FloatArray, FloatArray] | None, part_size_m: float
) -> tuple[FloatArray, FloatArray]:
    """The centre (part frame) and sides of a part's box, metres, each shape (3,).

    ``box``: its lower and upper corners (the stream's ``geometry``), or None: a cube of
    ``part_size_m`` about the part's origin. Sides are at least 1 mm.
    """
    if box is None:
        return np.zeros(3), np.full(3, part_size_m)
    lo, hi = box
    return 0.5 * (lo + hi), np.maximum(hi - lo, 1e-3)


def top_grasp(centre: FloatArray, size: FloatArray, pos: FloatArray, quat: FloatArray) -> Pose:
    """The top-down grasp of a part: over its box's centre, 2 cm below the box's top, the
    gripper along the part's x.

    Parameters
    ----------
    centre, size : ndarray, shape (3,)
        The part's box (:func:`part_box`), part frame, metres.
    pos : ndarray, shape (3,)
        The part's position, world, metres.
    quat : ndarray, shape (4,)
        Its orientation, x y z w.

    Returns
    -------
    tuple of ndarray, shapes (3,) and (4,)
        The tool pose, world.
    """
    half = size / 2.0
    top = float(np.max(se3.quat_rotate(quat, box_corners((-half, half)))[:, 2]))
    mid = pos + se3.quat_rotate(quat, centre)
    mid = mid + np.array([0.0, 0.0, max(top - 0.02, 0.0)])
    axis = se3.quat_rotate(quat, np.array([1.0, 0.0, 0.0]))
    return mid, down_quat(axis[:2])


def grasp_targets(
    centre: FloatArray, size: FloatArray, pos: FloatArray, quat: FloatArray, first: Pose
) -> list[Pose]:
    """Tool poses (world) to grasp a part from above, the best first.

    ``first`` (the top-down grasp at the top of the part's box, :func:`top_grasp`), then
    the execution stage's shape grasps (:func:`~thirdhand.execute.grasps.shape_grasps`)
    of the box ``centre``, ``size`` (3,) whose approach points down by more than
    :data:`DOWN_COS`, the most vertical and central first, each also
    :data:`SHALLOWER_M` less deep (a flat part's grasp can put the fingertips into the
    table it lies on), at most :data:`MAX_GRASPS` of them. ``pos`` (3,), ``quat`` (4,):
    the part's pose, world.
    """
    from thirdhand.execute.grasps import shape_grasps

    t_wp = se3.matrix_from_pose(pos, quat)
    world_c = pos + se3.quat_rotate(quat, centre)
    ranked = []
    for g in shape_grasps(centre - size / 2.0, centre + size / 2.0):
        t = t_wp @ g.pose
        down = -float(t[2, 2])
        if down > DOWN_COS:
            ranked.append((-round(down, 6), float(np.linalg.norm(t[:3, 3] - world_c)), t))
    ranked.sort(key=lambda r: (r[0], r[1]))
    out = [first]
    for _, _, t in ranked[: MAX_GRASPS // 2]:
        q = se3.quat_from_matrix(t[:3, :3])
        out += [(t[:3, 3], q), (t[:3, 3] + np.array([0.0, 0.0, SHALLOWER_M]), q)]
    return out


def resting_on(
    collisions: Sequence[tuple[str, str]],
    name: str,
    hands: Collection[str],
    objects: Collection[str],
) -> tuple[str, ...]:
    """What the part ``name`` touches as it lies: the table, then the parts it meets there.

    ``collisions``: the pairs in collision with the part grasped where it lies;
    ``objects``: the world's objects (a part is one). Not a hand (``hands``): a hand on the
    part is the person's, and it is an obstacle.
    """
    touching = {b if a == name else a for a, b in collisions if name in (a, b)}
    return ("table", *sorted(o for o in touching - set(hands) - {"table"} if o in objects))


def lift_clear(
    robot: Robot,
    scene: CollisionScene,
    name: str,
    q_grasp: FloatArray,
    resting: Sequence[str],
    lift_m: float,
) -> FloatArray | None:
    """The configuration that has lifted the grasped part ``name`` straight up until it
    touches nothing, or None.

    Lifts of ``lift_m`` times each of :data:`LIFT_STEPS` are tried (an IK search from
    ``q_grasp`` each, valid in ``scene``, in which the part is attached): a part lying
    against a taller one, or one tilted on its side, must rise above it. The motion to
    it is checked densely, the part allowed to touch only what it rested on
    (``resting``, :func:`resting_on`): on the synthetic chair of seed 0 a leg lying
    beside the arm's base met the base half-way up a lift whose end was clear.
    """
    grasp_pose = robot.fk(q_grasp)
    for k in LIFT_STEPS:
        up = np.array([0.0, 0.0, k * lift_m])
        q = robot.ik(
            (grasp_pose[0] + up, grasp_pose[1]),
            q_grasp,
            seed=0,
            n_restarts=4,
            accept=scene.is_valid,
        )
        if q is None:
            continue
        for o in resting:
            scene.allow(name, o)
        try:
            clear = scene.check_path(np.stack([q_grasp, q]))
        finally:
            for o in resting:
                scene.disallow(name, o)
        if clear:
            return np.asarray(q, dtype=np.float64)
    return None


__all__ = [
    "DOWN_COS",
    "LIFT_STEPS",
    "MAX_GRASPS",
    "SHALLOWER_M",
    "grasp_targets",
    "lift_clear",
    "part_box",
    "resting_on",
    "top_grasp",
]
