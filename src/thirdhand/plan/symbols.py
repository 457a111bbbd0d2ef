"""Constraint symbols: instances clustered into slots across demonstrations.

Two instances are the same slot when they have the same parent, their child
positions in the parent frame are within ``pos_tol`` and their orientations
within ``rot_tol``, where a rotation about a free axis does not count: for two
instances that both spin freely the angle compared is the one between their free
axes (in the parent frame). Which part went into a slot does not matter: four
identical legs give four slot symbols whichever leg went where.

Clusters are named ``c1…cK`` by position: sorted by parent name, then by the
slot's x, y and z in the parent frame (rounded to the millimetre), so the names
do not depend on the order of the demonstrations or of the steps.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.constraints.detect import ConstraintInstance


@dataclass
class Symbol:
    """A slot: where children go on a parent.

    Attributes
    ----------
    name : str
        ``c1``, ``c2``...
    parent : str
    pos : ndarray, shape (3,)
        Mean child position in the parent, metres.
    quat : ndarray, shape (4,)
        Mean child orientation in the parent, x y z w.
    type : str
        The members' most common type.
    frame_pos, frame_quat : ndarray, shape (3,) and (4,)
        Constraint frame in the child frame (of the first member with a free DOF).
    ranges : ndarray, shape (6, 2)
        DOF ranges: the widest of the members of the chosen type.
    members : list of ConstraintInstance
    """

    name: str
    parent: str
    pos: FloatArray
    quat: FloatArray
    type: str
    frame_pos: FloatArray
    frame_quat: FloatArray
    ranges: FloatArray
    members: list[ConstraintInstance] = field(default_factory=list)

    @property
    def confidence(self) -> float:
        """Mean confidence of the members."""
        return float(np.mean([m.confidence for m in self.members])) if self.members else 0.0


def free_axis(inst: ConstraintInstance) -> FloatArray | None:
    """The free rotation axis of an instance in the parent frame, shape (3,), or None."""
    free = [k for k in range(3) if inst.ranges[3 + k, 1] > inst.ranges[3 + k, 0]]
    if len(free) != 1:
        return None
    e = np.zeros(3)
    e[free[0]] = 1.0
    in_child = se3.quat_rotate(inst.frame_quat, e)
    return np.asarray(se3.quat_rotate(inst.quat, in_child), dtype=np.float64)


def slot_distance(a: ConstraintInstance, b: ConstraintInstance) -> tuple[float, float]:
    """Position (m) and orientation (rad) distance of two instances, free spin excluded.

    Instances with different parents are infinitely far apart.
    """
    if a.parent != b.parent:
        return math.inf, math.inf
    dp = float(np.linalg.norm(a.pos - b.pos))
    xa, xb = free_axis(a), free_axis(b)
    if xa is not None and xb is not None:
        return dp, float(np.arccos(np.clip(xa @ xb, -1.0, 1.0)))
    return dp, float(se3.quat_angle(a.quat, b.quat))


def assign_symbols(
    instances: Sequence[ConstraintInstance],
    *,
    pos_tol: float = 0.02,
    rot_tol: float = math.radians(20.0),
) -> list[Symbol]:
    """Cluster constraint instances (of one or several demonstrations) into symbols.

    Each instance's ``symbol`` is set to its cluster's name.

    Parameters
    ----------
    instances : sequence of ConstraintInstance
    pos_tol : float
        Largest position distance within a slot, metres.
    rot_tol : float
        Largest orientation distance within a slot (free spin excluded), radians.

    Returns
    -------
    list of Symbol
        Sorted by name (``c1`` first).
    """
    clusters: list[list[ConstraintInstance]] = []
    for inst in instances:
        best, best_d = None, math.inf
        for c in clusters:
            dp, dr = slot_distance(c[0], inst)
            if dp <= pos_tol and dr <= rot_tol and dp < best_d:
                best, best_d = c, dp
        if best is None:
            clusters.append([inst])
        else:
            best.append(inst)

    def key(c: list[ConstraintInstance]) -> tuple[str, tuple[float, ...]]:
        p: FloatArray = np.round(np.stack([m.pos for m in c]).mean(axis=0), 3)
        return c[0].parent, (float(p[0]), float(p[1]), float(p[2]))

    out = []
    for i, c in enumerate(sorted(clusters, key=key), start=1):
        types = [m.type for m in c]
        typ = max(sorted(set(types)), key=types.count)
        same = [m for m in c if m.type == typ]
        with_free = [m for m in same if m.free_dofs.free()] or same
        ranges = np.stack([m.ranges for m in same])
        name = f"c{i}"
        for m in c:
            m.symbol = name
        out.append(
            Symbol(
                name=name,
                parent=c[0].parent,
                pos=np.mean([m.pos for m in c], axis=0),
                quat=se3.quat_mean([m.quat for m in c]),
                type=typ,
                frame_pos=with_free[0].frame_pos.copy(),
                frame_quat=with_free[0].frame_quat.copy(),
                ranges=np.stack([ranges[:, :, 0].min(axis=0), ranges[:, :, 1].max(axis=0)], axis=1),
                members=list(c),
            )
        )
    return out
