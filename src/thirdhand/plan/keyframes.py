"""Keyframes: the moment each constraint is created, with a snapshot of every body."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from thirdhand.arrays import FloatArray
from thirdhand.constraints.detect import ConstraintInstance
from thirdhand.demonstration import Demonstration


@dataclass
class Keyframe:
    """One stage of the plan: all body poses when a constraint is established.

    Attributes
    ----------
    time : float
        Seconds on the demonstration's time axis.
    frame : int
        Index of the frame used.
    poses : dict of str to (ndarray (3,), ndarray (4,))
        Each body's position (metres, world frame) and orientation (x y z w): the
        last valid sample at or before ``time`` (bodies never seen until then are
        left out).
    parent, child : str
        The constraint that appears.
    """

    time: float
    frame: int
    poses: dict[str, tuple[FloatArray, FloatArray]]
    parent: str
    child: str


def snapshot(
    demo: Demonstration, time: float
) -> tuple[int, dict[str, tuple[FloatArray, FloatArray]]]:
    """Every body's last valid pose at or before ``time`` (seconds), and the frame index."""
    i = int(np.clip(np.searchsorted(demo.t, time, side="right") - 1, 0, demo.n_frames - 1))
    poses = {}
    for name in demo.body_names:
        ok = np.flatnonzero(demo.valid(name)[: i + 1])
        if ok.size:
            j = ok[-1]
            poses[name] = (demo.pos(name)[j].copy(), demo.quat(name)[j].copy())
    return i, poses


def keyframes(demo: Demonstration, instances: Sequence[ConstraintInstance]) -> list[Keyframe]:
    """One keyframe per constraint instance, at its start, in time order.

    Parameters
    ----------
    demo : Demonstration
    instances : sequence of ConstraintInstance
        Detected in ``demo``.
    """
    out = []
    for inst in sorted(instances, key=lambda c: c.start):
        frame, poses = snapshot(demo, inst.start)
        out.append(Keyframe(inst.start, frame, poses, inst.parent, inst.child))
    return out
