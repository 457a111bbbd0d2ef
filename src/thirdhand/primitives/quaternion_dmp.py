"""Orientation DMPs: the quaternion DMP of Ude et al. (2014) and the seven-DMP variant.

:class:`QuaternionDMP` works on the unit-quaternion group: with ``ω`` the angular
velocity in the parent (base) frame, ``e = 2 log(g ⊗ q̄)`` the rotation vector that
takes the current orientation to the goal, and the same phase and gains as
:class:`~thirdhand.primitives.dmp.DMP`::

    tau² ω̇ = K e − D tau ω − K e0 x + f(x),     q̇ = ½ ω ⊗ q

(``e0`` is ``e`` at the start, the analogue of the ``(g − y0) x`` term; the
forcing term is switched off after ``tau`` as in :mod:`~thirdhand.primitives.dmp`).
Integrated with RK4 on ``(q, ω)`` and a renormalisation after each step.

:class:`PoseDMP` puts a position DMP beside either that orientation DMP
(``orientation="quaternion"``) or, as in the 3rdHand report, one scalar DMP per
quaternion component renormalised after integration (``orientation="seven"``).
"""

from __future__ import annotations

import math
from typing import Literal

import numba
import numpy as np
from numpy.typing import ArrayLike

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.primitives.checks import PrimitiveError, check_trajectory, check_unit_quaternions
from thirdhand.primitives.dmp import (
    DMP,
    TransformationSystem,
    forcing_features,
    phase,
    tail_gate,
)

# The quaternion logarithm and exponential (half rotation vectors) of thirdhand.se3.
quat_log = se3.quat_log
quat_exp = se3.quat_exp


@numba.njit(cache=True, nogil=True)
def _derivative(  # pragma: no cover - compiled
    q: FloatArray,
    w: FloatArray,
    g: FloatArray,
    drive: FloatArray,
    k_tau2: float,
    d_tau: float,
    qdot: FloatArray,
    wdot: FloatArray,
) -> None:
    """``(q̇, ω̇)`` of one state into ``qdot`` (4,) and ``wdot`` (3,).

    ``e = 2 log(g ⊗ q̄)`` (the rotation vector of the shorter turn), ``ω̇ = K/tau² e −
    D/tau ω + drive`` and ``q̇ = ½ (ω, 0) ⊗ q``, as :func:`thirdhand.se3.quat_multiply`
    and :func:`thirdhand.se3.rotvec_from_quat` compute them.
    """
    x2, y2, z2, w2 = -q[0], -q[1], -q[2], q[3]
    x1, y1, z1, w1 = g[0], g[1], g[2], g[3]
    px = w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2
    py = w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2
    pz = w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2
    pw = w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2
    if pw < 0.0:
        px, py, pz, pw = -px, -py, -pz, -pw
    sn = math.sqrt(px * px + py * py + pz * pz)
    scale = 2.0 * math.atan2(sn, pw) / sn if sn > 1e-12 else 2.0
    wdot[0] = k_tau2 * (px * scale) - d_tau * w[0] + drive[0]
    wdot[1] = k_tau2 * (py * scale) - d_tau * w[1] + drive[1]
    wdot[2] = k_tau2 * (pz * scale) - d_tau * w[2] + drive[2]
    ax, ay, az = w[0], w[1], w[2]
    bx, by, bz, bw = q[0], q[1], q[2], q[3]
    qdot[0] = 0.5 * (ax * bw + ay * bz - az * by)
    qdot[1] = 0.5 * (-ax * bz + ay * bw + az * bx)
    qdot[2] = 0.5 * (ax * by - ay * bx + az * bw)
    qdot[3] = 0.5 * (-ax * bx - ay * by - az * bz)


@numba.njit(cache=True, nogil=True)
def _integrate(  # pragma: no cover - compiled
    q0: FloatArray,
    w0: FloatArray,
    g: FloatArray,
    drive: FloatArray,
    k_tau2: float,
    d_tau: float,
    h: float,
    n: int,
    m: int,
) -> tuple[FloatArray, FloatArray]:
    """RK4 on ``(q, ω)`` with ``m`` substeps of ``h`` per output step, renormalised.

    Parameters
    ----------
    q0 : ndarray, shape (b, 4)
        Start orientations x y z w.
    w0 : ndarray, shape (b, 3)
        Start angular velocities, rad/s.
    g : ndarray, shape (4,)
    drive : ndarray, shape (2 m (n − 1) + 1, b, 3)
        The forcing minus the start-offset term on the half-substep grid, over tau².

    Returns
    -------
    q : ndarray, shape (n, b, 4)
    w : ndarray, shape (n, b, 3)
    """
    b = q0.shape[0]
    q_out = np.empty((n, b, 4))
    w_out = np.empty((n, b, 3))
    kq = np.empty((4, 4))
    kw = np.empty((4, 3))
    qs = np.empty(4)
    ws = np.empty(3)
    q = np.empty(4)
    w = np.empty(3)
    for r in range(b):
        q[:] = q0[r]
        w[:] = w0[r]
        q_out[0, r] = q
        w_out[0, r] = w
        for i in range(1, n):
            for sub in range(m):
                j = 2 * ((i - 1) * m + sub)
                _derivative(q, w, g, drive[j, r], k_tau2, d_tau, kq[0], kw[0])
                for c in range(4):
                    qs[c] = q[c] + 0.5 * h * kq[0, c]
                for c in range(3):
                    ws[c] = w[c] + 0.5 * h * kw[0, c]
                _derivative(qs, ws, g, drive[j + 1, r], k_tau2, d_tau, kq[1], kw[1])
                for c in range(4):
                    qs[c] = q[c] + 0.5 * h * kq[1, c]
                for c in range(3):
                    ws[c] = w[c] + 0.5 * h * kw[1, c]
                _derivative(qs, ws, g, drive[j + 1, r], k_tau2, d_tau, kq[2], kw[2])
                for c in range(4):
                    qs[c] = q[c] + h * kq[2, c]
                for c in range(3):
                    ws[c] = w[c] + h * kw[2, c]
                _derivative(qs, ws, g, drive[j + 2, r], k_tau2, d_tau, kq[3], kw[3])
                for c in range(4):
                    q[c] = q[c] + h / 6.0 * (kq[0, c] + 2 * kq[1, c] + 2 * kq[2, c] + kq[3, c])
                for c in range(3):
                    w[c] = w[c] + h / 6.0 * (kw[0, c] + 2 * kw[1, c] + 2 * kw[2, c] + kw[3, c])
                norm = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
                for c in range(4):
                    q[c] /= norm
            q_out[i, r] = q
            w_out[i, r] = w
    return q_out, w_out


def angular_velocity(s: FloatArray, q: FloatArray) -> FloatArray:
    """Angular velocity in the base frame, rad/s, shape (n, 3), from a continuous track (n, 4).

    ``ω = 2 vec(q̇ ⊗ q̄)`` with ``q̇`` by second-order finite differences.
    """
    qd = np.gradient(q, s, axis=0, edge_order=2)
    return 2.0 * se3.quat_multiply(qd, se3.quat_conjugate(q))[:, :3]


class QuaternionDMP(TransformationSystem):
    """Orientation DMP on unit quaternions (Ude, Nemec, Petrič, Morimoto 2014).

    Parameters
    ----------
    n_weights : int
        RBFs per rotation axis.
    alpha : float
        Damping ``D``; stiffness ``alpha² / 4``.
    alpha_x : float, optional
        Phase decay (default: phase 0.01 at the demonstrated duration).
    regularization : float
        Ridge coefficient.
    substeps : int
        RK4 steps per output sample.

    Attributes
    ----------
    weights_ : ndarray, shape (n_weights, 3)
    tau_, dt_ : float
        Demonstrated duration and sample interval, seconds.
    start_, goal_ : ndarray, shape (4,), x y z w
    start_velocity_ : ndarray, shape (3,), rad/s, base frame
    """

    def __init__(
        self,
        n_weights: int = 30,
        *,
        alpha: float = 25.0,
        alpha_x: float | None = None,
        regularization: float = 1e-10,
        substeps: int = 2,
    ) -> None:
        super().__init__(n_weights, alpha=alpha, alpha_x=alpha_x, regularization=regularization)
        self.substeps = substeps

    def fit(self, t: ArrayLike, q: ArrayLike, *, name: str = "orientation track") -> QuaternionDMP:
        """Learn from one orientation track.

        Parameters
        ----------
        t : array_like, shape (n,)
            Strictly increasing times, seconds.
        q : array_like, shape (n, 4)
            Quaternions x y z w; normalised and made sign-continuous here (sign
            flips in the input are harmless).
        """
        ta, qa = check_trajectory(t, q, name=name)
        qa = check_unit_quaternions(qa, name=name)
        s = ta - ta[0]
        tau = float(s[-1])
        w = angular_velocity(s, qa)
        wd = np.gradient(w, s, axis=0, edge_order=2)
        g, q0 = qa[-1], qa[0]
        e = 2.0 * quat_log(se3.quat_multiply(g, se3.quat_conjugate(qa)))
        e0 = e[0]
        x = phase(s, tau, self.alpha_x_)
        k, d = self.stiffness, self.alpha
        target = tau**2 * wd - k * e + d * tau * w + k * e0 * x[:, None]
        self._fit_weights(x, target)
        self.tau_ = tau
        self.start_, self.goal_ = q0.copy(), g.copy()
        self.start_velocity_ = w[0].copy()
        self.dt_ = float(np.median(np.diff(s)))
        return self

    def rollout(
        self,
        *,
        start: ArrayLike | None = None,
        goal: ArrayLike | None = None,
        start_velocity: ArrayLike | None = None,
        duration: float | None = None,
        run_time: float | None = None,
        dt: float | None = None,
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Integrate from one or several starts.

        Parameters
        ----------
        start : array_like, shape (4,) or (batch, 4), optional
            Start orientations x y z w; default the demonstrated one.
        goal : array_like, shape (4,), optional
        start_velocity : array_like, shape (3,) or (batch, 3), optional
            rad/s in the base frame; default the demonstrated one (time-scaled).
        duration, run_time, dt : float, optional
            As in :meth:`DMP.rollout`.

        Returns
        -------
        s : ndarray, shape (n,)
        q : ndarray, shape (n, 4) or (n, batch, 4)
            Unit quaternions x y z w (batch axis only when ``start`` is 2-D).
        w : ndarray, shape (n, 3) or (n, batch, 3)
            Angular velocity, rad/s, base frame.
        """
        tau, s = self.time_grid(duration, run_time, dt, "quaternion DMP")
        n, run = len(s), float(s[-1])
        q0 = self.start_ if start is None else np.asarray(start, dtype=np.float64)
        batched = q0.ndim == 2
        q = np.atleast_2d(q0).copy()
        if q.shape[-1] != 4 or not np.isfinite(q).all():
            raise PrimitiveError(
                f"quaternion DMP rollout: start must be (4,) or (b, 4), got {q.shape}"
            )
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        g = self.goal_ if goal is None else np.asarray(goal, dtype=np.float64).reshape(4)
        g = g / np.linalg.norm(g)
        if start_velocity is None:
            w = np.broadcast_to(self.start_velocity_ * self.tau_ / tau, (q.shape[0], 3)).copy()
        else:
            w = np.broadcast_to(
                np.asarray(start_velocity, dtype=np.float64), (q.shape[0], 3)
            ).copy()
        k, d = self.stiffness, self.alpha
        e0 = 2.0 * quat_log(se3.quat_multiply(g, se3.quat_conjugate(q)))
        # forcing minus the start-offset term on a half-step grid, for the RK4 stages
        m = self.substeps
        fine = np.linspace(0.0, run, 2 * m * (n - 1) + 1)
        x = phase(fine, tau, self.alpha_x_)
        fx = forcing_features(x, *self.basis()) @ self.weights_
        gate = tail_gate(fine, tau)[:, None, None]
        drive = gate * (fx[:, None, :] - k * e0[None] * x[:, None, None]) / tau**2
        h = (s[1] - s[0]) / m
        # The RK4 loop is compiled (numba): a 60-s constraint motion is ~3,000 steps of
        # 4 stages, 2.5 s per rollout in numpy against milliseconds compiled.
        q_out, w_out = _integrate(
            np.ascontiguousarray(q),
            np.ascontiguousarray(w),
            np.ascontiguousarray(g),
            np.ascontiguousarray(drive),
            k / tau**2,
            d / tau,
            float(h),
            n,
            m,
        )
        if not batched:
            return s, q_out[:, 0], w_out[:, 0]
        return s, q_out, w_out


class PoseDMP:
    """Position DMP plus an orientation DMP for a 6-DoF pose trajectory.

    Parameters
    ----------
    n_weights : int
        RBFs per dimension.
    orientation : {"quaternion", "seven"}
        ``"quaternion"``: :class:`QuaternionDMP` (Ude et al. 2014). ``"seven"``: one
        scalar DMP per quaternion component, renormalised after integration (the
        3rdHand report's variant).
    alpha : float
        Damping ``D``.

    Attributes
    ----------
    position_ : DMP
    orientation_ : QuaternionDMP or DMP
    """

    def __init__(
        self,
        n_weights: int = 30,
        *,
        orientation: Literal["quaternion", "seven"] = "quaternion",
        alpha: float = 25.0,
    ) -> None:
        if orientation not in ("quaternion", "seven"):
            raise PrimitiveError(
                f"orientation must be 'quaternion' or 'seven', got {orientation!r}"
            )
        self.n_weights = n_weights
        self.orientation = orientation
        self.alpha = alpha

    def fit(
        self, t: ArrayLike, pos: ArrayLike, quat: ArrayLike, *, name: str = "pose trajectory"
    ) -> PoseDMP:
        """Learn from one trajectory: ``pos`` (n, 3) metres and ``quat`` (n, 4) x y z w."""
        ta, pa = check_trajectory(t, pos, name=name)
        _, qa = check_trajectory(ta, quat, name=name)
        qa = check_unit_quaternions(qa, name=name)
        self.position_ = DMP(self.n_weights, alpha=self.alpha).fit(ta, pa, name=name)
        self.orientation_: QuaternionDMP | DMP
        if self.orientation == "quaternion":
            self.orientation_ = QuaternionDMP(self.n_weights, alpha=self.alpha).fit(
                ta, qa, name=name
            )
        else:
            self.orientation_ = DMP(self.n_weights, alpha=self.alpha).fit(ta, qa, name=name)
        return self

    def rollout(
        self,
        *,
        start_pos: ArrayLike | None = None,
        start_quat: ArrayLike | None = None,
        goal_pos: ArrayLike | None = None,
        goal_quat: ArrayLike | None = None,
        duration: float | None = None,
        run_time: float | None = None,
        at_rest: bool = False,
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Roll out the pose.

        Parameters
        ----------
        start_pos, goal_pos : array_like, shape (3,), metres, optional
        start_quat, goal_quat : array_like, shape (4,), x y z w, optional
        duration, run_time : float, optional
            As in :meth:`DMP.rollout`.
        at_rest : bool
            Start with zero velocity instead of the demonstrated one.

        Returns
        -------
        s : ndarray, shape (n,), seconds
        pos : ndarray, shape (n, 3), metres
        quat : ndarray, shape (n, 4), x y z w, unit
        """
        s, p, _ = self.position_.rollout(
            start=start_pos,
            goal=goal_pos,
            start_velocity=np.zeros(3) if at_rest else None,
            duration=duration,
            run_time=run_time,
        )
        o = self.orientation_
        if isinstance(o, QuaternionDMP):
            _, q, _ = o.rollout(
                start=start_quat,
                goal=goal_quat,
                start_velocity=np.zeros(3) if at_rest else None,
                duration=duration,
                run_time=run_time,
            )
        else:
            g = None if goal_quat is None else _near(goal_quat, o.goal_)
            st = None if start_quat is None else _near(start_quat, o.start_)
            _, q7, _ = o.rollout(
                start=st,
                goal=g,
                start_velocity=np.zeros(4) if at_rest else None,
                duration=duration,
                run_time=run_time,
            )
            norms = np.linalg.norm(q7, axis=1, keepdims=True)
            if (norms < 1e-9).any():
                raise PrimitiveError("seven-DMP rollout passed through a zero quaternion")
            q = q7 / norms
        return s, p, q


def _near(q: ArrayLike, ref: FloatArray) -> FloatArray:
    """``q`` or ``−q``, whichever is closer to ``ref`` (component-wise DMPs need one sign)."""
    qa = np.asarray(q, dtype=np.float64).reshape(4)
    qa = qa / np.linalg.norm(qa)
    return -qa if float(qa @ ref) < 0.0 else qa
