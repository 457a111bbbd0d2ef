"""What a simulated step is judged by: pose errors, slip, and the step's status (pure functions).

The pose error is the learned constraint's violation
(:func:`thirdhand.execute.goals.dof_violation`): the child's pose in its parent's
frame against the constraint pose, ignoring what the free DOFs allow. Slip is how
far the part's corners moved in the tool frame since the fingers closed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from thirdhand.arrays import FloatArray
from thirdhand.execute.goals import dof_violation, invert
from thirdhand.task.constraint import Constraint

#: Statuses of a simulated step, from best to worst.
STATUSES = ("done", "slipped", "dropped", "jammed", "failed")


@dataclass(frozen=True)
class PoseError:
    """A part's pose against its learned constraint.

    Attributes
    ----------
    position_mm : float
        Norm of the translation violation, millimetres.
    angle_deg : float
        Norm of the rotation violation, degrees.
    """

    position_mm: float
    angle_deg: float


def pose_error(parent_world: FloatArray, child_world: FloatArray, c: Constraint) -> PoseError:
    """The child's error against constraint ``c`` given both world poses (4, 4)."""
    v = dof_violation(invert(parent_world) @ child_world, c)
    return PoseError(float(np.linalg.norm(v[:3]) * 1e3), float(np.rad2deg(np.linalg.norm(v[3:]))))


def box_corners(lo: FloatArray, hi: FloatArray) -> FloatArray:
    """The 8 corners (8, 3) of an axis-aligned box."""
    return np.array([[(hi if (i >> k) & 1 else lo)[k] for k in range(3)] for i in range(8)])


def slip_mm(t_tool_part: FloatArray, t_tool_part_0: FloatArray, corners: FloatArray) -> float:
    """Largest move of the part's corners (8, 3) in the tool frame between two grips, mm."""
    a = corners @ t_tool_part[:3, :3].T + t_tool_part[:3, 3]
    b = corners @ t_tool_part_0[:3, :3].T + t_tool_part_0[:3, 3]
    return float(np.max(np.linalg.norm(a - b, axis=1)) * 1e3)


def displacement_mm(before: FloatArray, after: FloatArray, corners: FloatArray) -> float:
    """Largest move of a part's corners (8, 3) between two world poses (4, 4), mm."""
    return slip_mm(after, before, corners)


def step_status(
    *,
    planned: bool,
    held: bool,
    slip: float,
    error: PoseError | None,
    blocked: bool,
    position_tolerance: float,
    angle_tolerance: float,
    slip_tolerance: float,
    drop_distance: float,
) -> str:
    """The verdict on one step.

    Parameters
    ----------
    planned : bool
        The planner found motions for the step.
    held : bool
        The part was still between the fingers at the end of the carry.
    slip : float
        Largest slip in the hand during the carry, mm.
    error : PoseError or None
        The part's error when it was fastened (None: never placed).
    blocked : bool
        At its goal pose's approach the part touched another body than the hand.
    position_tolerance, angle_tolerance, slip_tolerance, drop_distance : float
        mm, degrees, mm, mm.

    Returns
    -------
    str
        ``failed`` (not planned), ``dropped`` (lost the fingers, or slipped past
        ``drop_distance``), ``slipped`` (slipped past ``slip_tolerance`` and ended
        off its goal), ``done`` (within tolerance), ``jammed`` (stopped off its
        goal against another body) or ``failed`` (off its goal otherwise).
    """
    if not planned:
        return "failed"
    if not held or slip > drop_distance:
        return "dropped"
    ok = (
        error is not None
        and error.position_mm <= position_tolerance
        and error.angle_deg <= angle_tolerance
    )
    if ok:
        return "done"
    if slip > slip_tolerance:
        return "slipped"
    return "jammed" if blocked else "failed"
