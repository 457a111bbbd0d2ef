"""Discrete dynamic movement primitives (Ijspeert-style) in any dimension.

Time convention (fixed, tested)
-------------------------------
A demonstration sampled at times ``t_0 < … < t_N`` has duration ``tau = t_N − t_0``;
the rollout time ``s`` starts at 0 at the first sample. The phase is
``x(s) = exp(−alpha_x s / tau)`` (1 at the start, 0.01 at ``s = tau`` by default)
and the transformation system is the goal-offset form of Pastor et al. (2009)::

    tau² ÿ = K (g − y) − D tau ẏ − K (g − y0) x + f(x),
    f(x)   = x Σ_i ψ_i(x) w_i / Σ_i ψ_i(x),   ψ_i(x) = exp(−h_i (x − c_i)²)

with ``D = alpha`` and ``K = alpha² / 4`` (critically damped). Beyond the
demonstrated duration ``f(x) − K (g − y0) x`` is switched off: a demonstration
that stops abruptly leaves large weights on the last RBFs, and ``x`` alone
would let them (and a fraction ``x`` of a changed ``g − y0``) act long after
``tau`` and throw the motion off the goal it has reached; without them the
critically damped spring settles on the goal.

The system is linear in ``(y, ẏ)`` and its input is a known function of time, so
the rollout is the exact solution for an input that is linear between samples
(first-order hold): a matrix exponential and two FFT convolutions, with no
per-step Python loop and no integration drift.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from scipy.linalg import expm

from thirdhand.arrays import FloatArray
from thirdhand.primitives.checks import PrimitiveError, check_trajectory

#: Phase at the end of the demonstrated duration (sets ``alpha_x``).
FINAL_PHASE = 0.01


def phase(s: ArrayLike, tau: float, alpha_x: float) -> FloatArray:
    """Canonical phase ``exp(−alpha_x s / tau)``, shape of ``s`` (``s`` in seconds)."""
    return np.exp(-alpha_x * np.asarray(s, dtype=np.float64) / tau)


def tail_gate(s: ArrayLike, tau: float) -> FloatArray:
    """1 up to ``tau`` (inclusive, to rounding), 0 after; shape of ``s``."""
    sa = np.asarray(s, dtype=np.float64)
    return (sa <= tau * (1.0 + 1e-12)).astype(np.float64)


def basis_centres(n_weights: int, alpha_x: float) -> tuple[FloatArray, FloatArray]:
    """Centres ``c_i`` (equally spaced in time) and widths ``h_i`` of the phase RBFs.

    Returns
    -------
    centres, widths : ndarray, shape (n_weights,)
    """
    if n_weights < 1:
        raise PrimitiveError(f"DMP: expected at least 1 weight per dimension, got {n_weights}")
    c = np.exp(-alpha_x * np.linspace(0.0, 1.0, n_weights))
    if n_weights == 1:
        return c, np.ones(1)
    dc = np.abs(np.diff(c))
    h = 1.0 / np.concatenate([dc, dc[-1:]]) ** 2
    return c, h


def forcing_features(x: ArrayLike, centres: FloatArray, widths: FloatArray) -> FloatArray:
    """Features ``x ψ_i(x) / Σ ψ(x)``, shape (n, n_weights), so that ``f = features @ w``."""
    xa = np.asarray(x, dtype=np.float64)[:, None]
    psi = np.exp(-widths * (xa - centres) ** 2)
    return psi * xa / np.maximum(psi.sum(axis=1, keepdims=True), 1e-300)


def _powers(m: FloatArray, n: int) -> FloatArray:
    """``m^k`` for k = 0 … n−1, shape (n, 2, 2), by doubling (log2 n batched matmuls)."""
    out = np.empty((n, *m.shape))
    out[0] = np.eye(m.shape[0])
    filled, p = 1, m
    while filled < n:
        take = min(filled, n - filled)
        out[filled : filled + take] = out[:take] @ p
        filled += take
        p = p @ p
    return out


def _convolve(a: FloatArray, b: FloatArray) -> FloatArray:
    """Full linear convolution along axis 0 of ``a`` (na, ...) and ``b`` (nb, ...), the other
    axes broadcast: (na + nb - 1, ...). By FFT (numpy's: ``scipy.signal`` costs execution
    about a second to import, for this one function)."""
    n = a.shape[0] + b.shape[0] - 1
    size = 1 << max(n - 1, 0).bit_length()
    spectrum = np.fft.rfft(a, size, axis=0) * np.fft.rfft(b, size, axis=0)
    return np.asarray(np.fft.irfft(spectrum, size, axis=0)[:n], dtype=np.float64)


def linear_rollout(
    s: FloatArray, u: FloatArray, e0: FloatArray, v0: FloatArray, *, k: float, d: float, tau: float
) -> tuple[FloatArray, FloatArray]:
    """Exact solution of ``ë = −k/tau² e − d/tau ė + u(s)`` for ``u`` linear between samples.

    Parameters
    ----------
    s : ndarray, shape (n,)
        Uniform time grid starting at 0, seconds.
    u : ndarray, shape (n, dims)
        Input (acceleration) at the grid times.
    e0, v0 : ndarray, shape (dims,)
        Initial value and derivative.
    k, d, tau : float
        Stiffness, damping and time constant.

    Returns
    -------
    e, ed : ndarray, shape (n, dims)
    """
    n = s.size
    dt = float(s[1] - s[0])
    a = np.array([[0.0, 1.0], [-k / tau**2, -d / tau]])
    big = np.zeros((4, 4))
    big[:2, :2] = a * dt
    big[1, 2] = dt
    big[2, 3] = 1.0
    ex = expm(big)
    phi, g1, g2 = ex[:2, :2], ex[:2, 2], ex[:2, 3]
    pw = _powers(phi, n)
    free = np.einsum("nij,jd->nid", pw, np.stack([e0, v0]))
    h0 = pw @ (g1 - g2)
    h1 = pw @ g2
    out = free.copy()
    if n > 1:
        c0 = _convolve(h0[:, :, None], u[:, None, :])[: n - 1]
        c1 = _convolve(h1[:, :, None], u[:, None, :])[1:n]
        forced = c0 + c1 - h1[1:n, :, None] * u[0]
        out[1:] += forced
    return out[:, 0, :], out[:, 1, :]


class TransformationSystem:
    """What a position DMP and a quaternion DMP share: gains, phase, weight fit, time grid.

    Parameters
    ----------
    n_weights : int
        Basis functions of the forcing term.
    alpha : float
        Damping ``D``; the stiffness is ``K = alpha² / 4`` (critically damped).
    alpha_x : float, optional
        Phase decay; default ``-log(FINAL_PHASE)`` (the phase ends at 0.01).
    regularization : float
        Ridge term of the weight fit, relative to the trace of the Gram matrix.
    """

    #: Fitted by the subclass: duration (s), median sample interval (s), weights.
    tau_: float
    dt_: float
    weights_: FloatArray

    def __init__(
        self,
        n_weights: int = 30,
        *,
        alpha: float = 25.0,
        alpha_x: float | None = None,
        regularization: float = 1e-10,
    ) -> None:
        self.n_weights = n_weights
        self.alpha = alpha
        self.alpha_x = alpha_x
        self.regularization = regularization

    @property
    def stiffness(self) -> float:
        """``K = alpha² / 4``."""
        return self.alpha**2 / 4.0

    @property
    def alpha_x_(self) -> float:
        """The phase decay actually used."""
        return float(-np.log(FINAL_PHASE)) if self.alpha_x is None else float(self.alpha_x)

    def basis(self) -> tuple[FloatArray, FloatArray]:
        """Centres and widths of the forcing term's phase RBFs (:func:`basis_centres`)."""
        return basis_centres(self.n_weights, self.alpha_x_)

    def _fit_weights(self, x: FloatArray, target: FloatArray) -> None:
        """Ridge least squares of the forcing weights: ``features(x) @ W ≈ target``."""
        feats = forcing_features(x, *self.basis())
        gram = feats.T @ feats
        gram[np.diag_indices_from(gram)] += self.regularization * max(np.trace(gram), 1e-12)
        self.weights_ = np.linalg.solve(gram, feats.T @ target).astype(np.float64, copy=False)

    def time_grid(
        self, duration: float | None, run_time: float | None, dt: float | None, what: str
    ) -> tuple[float, FloatArray]:
        """``tau`` and the output times (from 0, at least two) of a rollout.

        Raises
        ------
        PrimitiveError
            If the duration, run time or step is not positive.
        """
        tau = self.tau_ if duration is None else float(duration)
        run = tau if run_time is None else float(run_time)
        step = self.dt_ * tau / self.tau_ if dt is None else float(dt)
        if not (tau > 0 and run > 0 and step > 0):
            raise PrimitiveError(
                f"{what} rollout: duration, run time and dt must be > 0, got {tau}, {run}, {step}"
            )
        return tau, np.linspace(0.0, run, max(round(run / step) + 1, 2))


class DMP(TransformationSystem):
    """Discrete DMP over ``dims`` independent dimensions sharing one phase.

    Parameters
    ----------
    n_weights : int
        RBFs per dimension.
    alpha : float
        Damping ``D``; the stiffness is ``alpha² / 4``.
    alpha_x : float, optional
        Phase decay; default gives ``x(tau) = 0.01``.
    regularization : float
        Ridge coefficient of the weight fit.

    Attributes
    ----------
    weights_ : ndarray, shape (n_weights, dims)
    tau_ : float
        Demonstrated duration, seconds.
    start_, goal_, start_velocity_ : ndarray, shape (dims,)
        Demonstrated start, end and initial velocity (units of the data, per second).
    dt_ : float
        Median sample interval of the demonstration, seconds.
    """

    # --------------------------------------------------------------------- fit
    def fit(self, t: ArrayLike, y: ArrayLike, *, name: str = "demonstration") -> DMP:
        """Learn the forcing term from one demonstration.

        Parameters
        ----------
        t : array_like, shape (n,)
            Strictly increasing times, seconds.
        y : array_like, shape (n, dims) or (n,)
            Positions (any unit); at least 3 finite samples.
        name : str
            Names the trajectory in error messages.
        """
        ta, ya = check_trajectory(t, y, name=name)
        s = ta - ta[0]
        tau = float(s[-1])
        yd = np.gradient(ya, s, axis=0, edge_order=2)
        ydd = np.gradient(yd, s, axis=0, edge_order=2)
        x = phase(s, tau, self.alpha_x_)
        g, y0 = ya[-1], ya[0]
        k, d = self.stiffness, self.alpha
        target = tau**2 * ydd - k * (g - ya) + d * tau * yd + k * (g - y0) * x[:, None]
        self._fit_weights(x, target)
        self.tau_ = tau
        self.start_, self.goal_ = y0.copy(), g.copy()
        self.start_velocity_ = yd[0].copy()
        self.dt_ = float(np.median(np.diff(s)))
        return self

    def forcing(self, x: ArrayLike) -> FloatArray:
        """Forcing term ``f(x)``, shape (n, dims)."""
        return forcing_features(np.atleast_1d(x), *self.basis()) @ self.weights_

    # ----------------------------------------------------------------- rollout
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
        """Integrate the DMP (exactly, see module docstring).

        Parameters
        ----------
        start, goal : array_like, shape (dims,), optional
            Default to the demonstrated ones.
        start_velocity : array_like, shape (dims,), optional
            Defaults to the demonstrated initial velocity (scaled by the new duration).
        duration : float, optional
            ``tau`` of the motion, seconds; defaults to the demonstrated one.
        run_time : float, optional
            How long to integrate; defaults to ``duration``.
        dt : float, optional
            Step of the output grid; defaults to the demonstration's.

        Returns
        -------
        s : ndarray, shape (n,)
            Times from 0, seconds.
        y, yd : ndarray, shape (n, dims)
            Positions and velocities.
        """
        tau, s = self.time_grid(duration, run_time, dt, "DMP")
        dims = self.weights_.shape[1]
        y0 = self.start_ if start is None else _vec(start, dims, "start")
        g = self.goal_ if goal is None else _vec(goal, dims, "goal")
        if start_velocity is None:
            v0 = self.start_velocity_ * self.tau_ / tau
        else:
            v0 = _vec(start_velocity, dims, "start velocity")
        x = phase(s, tau, self.alpha_x_)
        k = self.stiffness
        gate = tail_gate(s, tau)[:, None]
        u = gate * (self.forcing(x) - k * (g - y0) * x[:, None]) / tau**2
        e, ed = linear_rollout(s, u, y0 - g, v0, k=k, d=self.alpha, tau=tau)
        return s, e + g, ed


def _vec(v: ArrayLike, dims: int, what: str) -> FloatArray:
    a = np.asarray(v, dtype=np.float64).reshape(-1)
    if a.size != dims or not np.isfinite(a).all():
        raise PrimitiveError(f"DMP rollout: {what} must be {dims} finite numbers, got {a}")
    return a
