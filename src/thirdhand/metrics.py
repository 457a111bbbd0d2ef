"""Scores of learned constraints against ground truth.

- :func:`pose_errors`: position (m) and rotation (degrees) error of each detected
  true constraint.
- :func:`corrections` / :func:`wrong_parameters`: the constraint parameters a
  user would still correct.

A *parameter* is one DOF of one constraint (tx ty tz rx ry rz: 6 per constraint,
30 for the chair's five constraints, 24 for our bench's four; the report's bench
had 28). It is wrong when the learned pose is off along that DOF by more than
5 mm / 5° (the position error's component along the parent's axis; the rotation
error's rotation-vector component in the child frame, ignoring a rotation about a
DOF that is free in the truth), or when its range is wrong: free vs locked
disagree, or a free range differs by more than 5 mm / 5° at either end. A
constraint that was not detected at all counts all its 6 parameters as wrong.

Used by ``thirdhand learn``'s report (against a recording's labels) and by the
experiments in :mod:`research.plan_accuracy`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from thirdhand import se3

if TYPE_CHECKING:
    from thirdhand.constraints.detect_types import ConstraintInstance
    from thirdhand.demonstration import ConstraintEvent

__all__ = ["corrections", "pose_errors", "wrong_parameters"]


def _match(
    instances: Sequence[ConstraintInstance], truth: Sequence[ConstraintEvent]
) -> list[tuple[ConstraintEvent, ConstraintInstance | None]]:
    final = {(i.parent, i.child): i for i in instances if i.end is None}
    return [(ev, final.get((ev.parent, ev.child))) for ev in truth if not ev.removed]


def pose_errors(
    instances: Sequence[ConstraintInstance], truth: Sequence[ConstraintEvent]
) -> list[tuple[float, float]]:
    """Position (m) and rotation (degrees) error of each detected true constraint.

    Missing constraints are left out (see :func:`corrections`).
    """
    out = []
    for ev, inst in _match(instances, truth):
        if inst is not None:
            dp = float(np.linalg.norm(inst.pos - np.asarray(ev.pos)))
            dr = float(np.degrees(se3.quat_angle(inst.quat, np.asarray(ev.quat))))
            out.append((dp, dr))
    return out


def wrong_parameters(inst: ConstraintInstance | None, ev: ConstraintEvent) -> int:
    """Parameters (of 6) of one constraint a user would correct (module notes)."""
    if inst is None:
        return 6
    tol_t, tol_r = 0.005, math.radians(5.0)
    dp = inst.pos - np.asarray(ev.pos)
    q_true = np.asarray(ev.quat, dtype=np.float64)
    rv = se3.rotvec_from_quat(se3.quat_multiply(se3.quat_conjugate(q_true), inst.quat))
    truth_ranges = ev.free_dofs.array()
    free_true = truth_ranges[:, 1] > truth_ranges[:, 0]
    # A spin about a truly free axis is not an error: take it out of the rotation.
    for k in range(3):
        if free_true[3 + k]:
            rv[k] = 0.0
    est = inst.ranges
    if not np.allclose(inst.frame_quat, [0, 0, 0, 1], atol=1e-9):
        est = np.zeros((6, 2))
        est[3] = (-math.pi, math.pi) if inst.ranges[3, 1] > inst.ranges[3, 0] else (0, 0)
    free_est = est[:, 1] > est[:, 0]
    wrong = 0
    for k in range(6):
        tol = tol_t if k < 3 else tol_r
        off = abs(dp[k]) if k < 3 else abs(rv[k - 3])
        bad_range = free_true[k] != free_est[k] or (
            free_true[k] and np.any(np.abs(est[k] - truth_ranges[k]) > tol)
        )
        wrong += int(off > tol or bad_range)
    return wrong


def corrections(
    instances: Sequence[ConstraintInstance], truth: Sequence[ConstraintEvent]
) -> tuple[int, int]:
    """Wrong parameters and total parameters (6 per true constraint)."""
    pairs = _match(instances, truth)
    return sum(wrong_parameters(i, ev) for ev, i in pairs), 6 * len(pairs)
