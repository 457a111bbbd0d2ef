"""Time parametrisation of a joint-space waypoint path under velocity and acceleration limits.

Each straight segment between waypoints is run rest-to-rest with one
trapezoidal (or triangular) profile of the path parameter ``s ∈ [0, 1]``
shared by all joints: ``q(t) = q_a + s(t) (q_b − q_a)``. The profile's limits
are the tightest over the joints (``ṡ ≤ min_j v_j / |Δq_j|``,
``s̈ ≤ min_j a_j / |Δq_j|``), so the motion stays on the collision-checked
straight segments and each segment takes the least time its limits allow.
Stopping at every waypoint is slower than blending, but the planner's
shortcut paths have few waypoints, and the executed path is exactly the
checked one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from thirdhand.arrays import FloatArray
from thirdhand.errors import ThirdhandError


@dataclass(frozen=True)
class Trajectory:
    """A sampled joint trajectory.

    Attributes
    ----------
    t : ndarray, shape (m,)
        Sample times from 0, seconds, strictly increasing; the last is the duration.
    q : ndarray, shape (m, dof)
        Joint positions, radians.
    qd : ndarray, shape (m, dof)
        Joint velocities, rad/s.
    waypoint_times : ndarray, shape (n,)
        Time at which each input waypoint is reached, seconds.
    """

    t: FloatArray
    q: FloatArray
    qd: FloatArray
    waypoint_times: FloatArray

    @property
    def duration_s(self) -> float:
        """Total duration, seconds."""
        return float(self.t[-1])


def _profile(
    vmax: FloatArray, amax: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Rest-to-rest unit-distance profiles: peak speed, acceleration, ramp time, duration."""
    full = vmax * vmax / amax <= 1.0
    v_peak = np.where(full, vmax, np.sqrt(amax))
    t_ramp = v_peak / amax
    duration = np.where(full, 1.0 / vmax + vmax / amax, 2.0 * t_ramp)
    return v_peak, amax, t_ramp, duration


def time_parametrize(
    path: ArrayLike,
    vel_limits: ArrayLike,
    acc_limits: ArrayLike,
    *,
    rate_hz: float = 100.0,
    scale: float = 1.0,
) -> Trajectory:
    """Time a waypoint path rest-to-rest per segment and sample it at ``rate_hz``.

    Parameters
    ----------
    path : array_like, shape (n, dof)
        Waypoints, radians; consecutive duplicates are allowed (zero-time segments).
    vel_limits, acc_limits : array_like, shape (dof,)
        Per-joint limits, rad/s and rad/s² (``robot.velocity_limits``,
        ``robot.acceleration_limits``).
    rate_hz : float
        Sampling rate; the last sample is at the exact end time.
    scale : float
        Fraction of the limits used, in (0, 1].

    Returns
    -------
    Trajectory

    Raises
    ------
    ThirdhandError
        On wrong shapes or non-positive limits, rate or scale.
    """
    p = np.asarray(path, dtype=np.float64)
    if p.ndim != 2 or p.shape[0] < 1:
        raise ThirdhandError(f"path: expected shape (n, dof), got {p.shape}")
    dof = p.shape[1]
    v = np.asarray(vel_limits, dtype=np.float64) * scale
    a = np.asarray(acc_limits, dtype=np.float64) * scale
    if v.shape != (dof,) or a.shape != (dof,):
        raise ThirdhandError(f"limits: expected shape ({dof},), got {v.shape} and {a.shape}")
    if not (np.all(v > 0) and np.all(a > 0) and rate_hz > 0 and 0 < scale <= 1):
        raise ThirdhandError("limits, rate and scale must be positive (scale at most 1)")
    d = np.diff(p, axis=0)
    absd = np.abs(d)
    with np.errstate(divide="ignore"):
        vs = np.min(np.where(absd > 0, v / absd, np.inf), axis=1) if len(d) else np.zeros(0)
        acc = np.min(np.where(absd > 0, a / absd, np.inf), axis=1) if len(d) else np.zeros(0)
    moving = np.isfinite(vs)
    vs = np.where(moving, vs, 1.0)
    acc = np.where(moving, acc, 1.0)
    v_peak, acc, t_ramp, dur = _profile(vs, acc)
    dur = np.where(moving, dur, 0.0)
    starts = np.concatenate([[0.0], np.cumsum(dur)])
    total = float(starts[-1])
    n_samples = int(np.floor(total * rate_hz + 1e-9)) + 1
    t = np.arange(n_samples) / rate_hz
    if t[-1] < total - 1e-12:
        t = np.append(t, total)
    if len(d) == 0:
        return Trajectory(t, np.repeat(p[:1], len(t), axis=0), np.zeros((len(t), dof)), starts)
    seg = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(d) - 1)
    seg = np.where(dur[seg] > 0, seg, _next_moving(dur, seg))
    tau = np.clip(t - starts[seg], 0.0, dur[seg])
    tr, vp, ac, du = t_ramp[seg], v_peak[seg], acc[seg], dur[seg]
    up = tau < tr
    down = tau > du - tr
    s = np.where(up, 0.5 * ac * tau**2, vp * (tau - 0.5 * tr))
    s = np.where(down, 1.0 - 0.5 * ac * (du - tau) ** 2, s)
    sd = np.where(up, ac * tau, np.where(down, ac * (du - tau), vp))
    s = np.where(dur[seg] > 0, np.clip(s, 0.0, 1.0), 1.0)
    sd = np.where(dur[seg] > 0, sd, 0.0)
    q = p[seg] + s[:, None] * d[seg]
    qd = sd[:, None] * d[seg]
    return Trajectory(t, q, qd, starts)


def _next_moving(dur: FloatArray, seg: NDArray[np.intp]) -> NDArray[np.intp]:
    """For a zero-length segment, the last moving segment before it (or the first one)."""
    moving = np.flatnonzero(dur > 0)
    if moving.size == 0:
        return np.zeros_like(seg)
    k = np.searchsorted(moving, seg, side="right") - 1
    return np.asarray(moving[np.clip(k, 0, moving.size - 1)], dtype=np.intp)
