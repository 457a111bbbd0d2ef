"""Re-aiming a carried part: the arm's target corrected for where the part sits in the hand.

Closing the fingers moves a part in the hand (a tapered leg turns a few degrees
as flat pads meet its slanted faces) and a carry can slip it further; the plan
assumed the grasp as planned. A cell whose parts are tracked (the motion capture
that records the person tracks the parts the robot handles as well) measures the
part's pose in the hand and moves the hand so that the *part* follows its planned
path: the planned tool pose ``T`` becomes ``T · G_plan · G_now⁻¹``, where
``G = T_tool⁻¹ · T_part`` is the part's pose in the tool frame. These are the pure
functions; :class:`~thirdhand.simulate.runner.Simulation` measures and applies them.
"""

from __future__ import annotations

import numpy as np

from thirdhand import se3
from thirdhand.arrays import BoolArray, FloatArray

#: Damping of the least-squares inverse of the tool Jacobian, metres (and radians).
DAMPING = 0.02

#: Share of the part's remaining error from its planned pose added to the aim offset
#: per measurement (every 10 ms: the offset settles in about 0.2 s).
GAIN = 0.05

#: Largest aim offset, metres and radians (beyond it the part is off by more than an
#: arm's tracking can explain: the offset stops growing).
MAX_OFFSET_M = 0.02
MAX_OFFSET_RAD = np.deg2rad(5.0)


def tool_correction(g_plan: FloatArray, g_now: FloatArray, weight: float) -> FloatArray:
    """The correction (4, 4) of the tool pose, tool frame, by which the part follows its path.

    Parameters
    ----------
    g_plan, g_now : ndarray, shape (4, 4)
        The part's pose in the tool frame as planned and as measured now.
    weight : float
        0 (no correction) to 1 (the whole correction); in between, the rotation
        vector and translation are scaled (a correction blended in along a motion).

    Returns
    -------
    ndarray, shape (4, 4)
        ``C`` with the corrected tool pose ``T · C`` for a planned tool pose ``T``.
    """
    full = np.asarray(g_plan, dtype=np.float64) @ se3.transform_invert(g_now)
    w = float(np.clip(weight, 0.0, 1.0))
    out = np.eye(4)
    out[:3, :3] = se3.matrix_from_rotvec(w * se3.rotvec_from_matrix(full[:3, :3]))
    out[:3, 3] = w * full[:3, 3]
    return out


def integrate_offset(
    offset: FloatArray,
    planned: FloatArray,
    measured: FloatArray,
    gain: float = GAIN,
    across: FloatArray | None = None,
) -> FloatArray:
    """The aim offset (6,) after one measurement: ``offset + gain · (planned ⊖ measured)``.

    The offset shifts the part's target pose (position, world frame, metres; rotation
    vector about the part's origin, world frame, radians) so that an arm that lags its
    path (tracking error, an unmodelled payload) still brings the part to its planned
    pose; integral action, bounded by :data:`MAX_OFFSET_M` and :data:`MAX_OFFSET_RAD`.

    Parameters
    ----------
    offset : ndarray, shape (6,)
    planned, measured : ndarray, shape (4, 4)
        The part's planned and measured world poses.
    across : ndarray, shape (3,), optional
        An axis (world frame, any length): only the position error across it is
        integrated (a part pressed into its pocket along the axis is moved sideways,
        not pushed harder).
    """
    tw = pose_twist(measured, planned)
    if across is not None:
        a = np.asarray(across, dtype=np.float64)
        n = float(np.linalg.norm(a))
        if n > 0.0:
            tw[:3] -= (tw[:3] @ a) / n**2 * a
    out = np.asarray(offset, dtype=np.float64) + gain * tw
    p, r = out[:3], out[3:]
    np_, nr = float(np.linalg.norm(p)), float(np.linalg.norm(r))
    if np_ > MAX_OFFSET_M:
        p = p * (MAX_OFFSET_M / np_)
    if nr > MAX_OFFSET_RAD:
        r = r * (MAX_OFFSET_RAD / nr)
    return np.concatenate([p, r])


def shifted(pose: FloatArray, offset: FloatArray) -> FloatArray:
    """``pose`` (4, 4) moved by ``offset`` (6,): translated, and turned about its origin."""
    out = np.array(pose, dtype=np.float64)
    out[:3, :3] = se3.matrix_from_rotvec(offset[3:]) @ out[:3, :3]
    out[:3, 3] = out[:3, 3] + offset[:3]
    return out


def pose_twist(current: FloatArray, target: FloatArray) -> FloatArray:
    """The world-frame twist (6,) from ``current`` to ``target`` (4, 4): ``[dp (m), dθ (rad)]``."""
    dp = target[:3, 3] - current[:3, 3]
    dr = se3.rotvec_from_matrix(target[:3, :3] @ current[:3, :3].T)
    return np.concatenate([dp, dr])


def joint_step(
    jacobian: FloatArray,
    twist: FloatArray,
    damping: float = DAMPING,
    free: BoolArray | None = None,
) -> FloatArray:
    """Joint change (dof,) that moves the tool by ``twist`` (6,): damped least squares.

    Parameters
    ----------
    jacobian : ndarray, shape (6, dof)
        The tool's world-frame Jacobian, translational rows first.
    free : ndarray of bool, shape (dof,), optional
        The joints that may move (the others, at a limit, keep their angle); all by
        default.
    """
    j = np.array(jacobian, dtype=np.float64)
    if free is not None:
        j[:, ~np.asarray(free, dtype=bool)] = 0.0
    a = j @ j.T + damping**2 * np.eye(6)
    return np.asarray(j.T @ np.linalg.solve(a, twist), dtype=np.float64)


def blend(t: float, t_end: float) -> float:
    """Weight 0 → 1 of a correction blended in smoothly (``t`` from 0 to ``t_end`` s)."""
    if t_end <= 0.0:
        return 1.0
    s = float(np.clip(t / t_end, 0.0, 1.0))
    return s * s * (3.0 - 2.0 * s)
