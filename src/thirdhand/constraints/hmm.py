"""A two-state hidden Markov model over constraint states, learned by EM.

State 0 is *free* (no constraint between the two parts), state 1 *constrained*.
The observation of a latent step is the deviation of the child's pose in the
parent from the constraint's pose ``theta``: a translation vector ``dp`` (metres)
and a rotation vector ``dr`` (radians). The constrained state's observation model
is the fixed-constraint model of :mod:`thirdhand.constraints.models`, isotropic
Gaussian noise on both; the free state's is a broad radial-exponential density
over the same vector spaces, so that the two are comparable densities:

- constrained: ``N(dp; 0, σp² I₃) · N(dr; 0, σr² I₃)``
- free: ``exp(-|dp|/λp) / (8π λp³) · exp(-|dr|/λr) / (8π λr³)``

The noise levels, the free spreads, the transition matrix (shared by every pair
of a recording) and each pair's constraint pose are the EM parameters. Steps
without evidence (a body not tracked) have a uniform likelihood: the chain carries
the state through them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from thirdhand import se3
from thirdhand.arrays import FloatArray

_LOG_8PI = math.log(8.0 * math.pi)


@dataclass
class HMMParams:
    """Parameters of the constraint-state HMM.

    Attributes
    ----------
    sigma_pos, sigma_rot : float
        Constrained-state noise, metres and radians (per axis).
    lambda_pos, lambda_rot : float
        Free-state spreads, metres and radians.
    transition : ndarray, shape (2, 2)
        ``transition[i, j] = p(s_{t+1} = j | s_t = i)``.
    initial : ndarray, shape (2,)
        ``p(s_0)``.
    """

    sigma_pos: float = 0.002
    sigma_rot: float = math.radians(1.0)
    lambda_pos: float = 0.05
    lambda_rot: float = math.radians(20.0)
    transition: FloatArray = field(
        default_factory=lambda: np.array([[0.995, 0.005], [0.002, 0.998]])
    )
    initial: FloatArray = field(default_factory=lambda: np.array([0.99, 0.01]))


def deviations(
    pos: FloatArray, quat: FloatArray, theta_pos: FloatArray, theta_quat: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Deviation of a relative-pose track from constraint poses.

    Parameters
    ----------
    pos : ndarray, shape (P, T, 3), metres, parent frame
    quat : ndarray, shape (P, T, 4), x y z w
    theta_pos : ndarray, shape (P, 3), metres, parent frame
    theta_quat : ndarray, shape (P, 4), x y z w

    Returns
    -------
    dp : ndarray, shape (P, T), metres
        Distance of the child's position from ``theta_pos``.
    dr : ndarray, shape (P, T), radians
        Angle between the child's orientation and ``theta_quat``.
    """
    dp = np.linalg.norm(pos - theta_pos[:, None, :], axis=-1)
    dot = np.abs(np.sum(quat * theta_quat[:, None, :], axis=-1))
    dr = 2.0 * np.arccos(np.clip(dot, 0.0, 1.0))
    return dp, dr


def log_emissions(dp: FloatArray, dr: FloatArray, params: HMMParams) -> FloatArray:
    """Log-likelihood of each step's deviation under each state, shape (P, T, 2).

    NaN deviations (no evidence) give 0 for both states.
    """
    sp, sr = params.sigma_pos, params.sigma_rot
    lp, lr = params.lambda_pos, params.lambda_rot
    con = (
        -1.5 * math.log(2 * math.pi) * 2
        - 3 * math.log(sp)
        - 3 * math.log(sr)
        - 0.5 * (dp / sp) ** 2
        - 0.5 * (dr / sr) ** 2
    )
    free = -2 * _LOG_8PI - 3 * math.log(lp) - 3 * math.log(lr) - dp / lp - dr / lr
    out = np.stack([free, con], axis=-1)
    return np.where(np.isfinite(out), out, 0.0)


def forward_backward(
    log_b: FloatArray, transition: FloatArray, initial: FloatArray
) -> tuple[FloatArray, FloatArray, float]:
    """Posterior state marginals of P independent chains (scaled recursion).

    Parameters
    ----------
    log_b : ndarray, shape (P, T, 2)
        Log emission likelihoods.
    transition : ndarray, shape (2, 2)
    initial : ndarray, shape (2,)

    Returns
    -------
    gamma : ndarray, shape (P, T, 2)
        ``p(s_t | all observations)``.
    xi : ndarray, shape (2, 2)
        Expected transition counts summed over chains and steps.
    log_likelihood : float
        Summed over chains.
    """
    n_p, n_t, _ = log_b.shape
    shift = log_b.max(axis=-1, keepdims=True)
    b = np.exp(log_b - shift)
    alpha = np.empty((n_p, n_t, 2))
    scale = np.empty((n_p, n_t))
    a = initial[None, :] * b[:, 0]
    for t in range(n_t):
        if t:
            a = (alpha[:, t - 1] @ transition) * b[:, t]
        s = a.sum(axis=1)
        alpha[:, t] = a / s[:, None]
        scale[:, t] = s
    beta = np.empty((n_p, n_t, 2))
    beta[:, -1] = 1.0
    xi = np.zeros((2, 2))
    for t in range(n_t - 2, -1, -1):
        nb = b[:, t + 1] * beta[:, t + 1]
        beta[:, t] = (nb @ transition.T) / scale[:, t + 1][:, None]
        xi += np.einsum("pi,ij,pj->ij", alpha[:, t], transition, nb / scale[:, t + 1][:, None])
    gamma = alpha * beta
    gamma /= gamma.sum(axis=-1, keepdims=True)
    loglik = float(np.log(scale).sum() + shift.sum())
    return gamma, xi, loglik


def fit_hmm(
    pos: FloatArray,
    quat: FloatArray,
    theta_pos: FloatArray,
    theta_quat: FloatArray,
    *,
    params: HMMParams | None = None,
    n_iter: int = 8,
    sigma_floor: tuple[float, float] = (3e-4, math.radians(0.2)),
    update_shared: bool = True,
) -> tuple[FloatArray, HMMParams, FloatArray, FloatArray]:
    """Learn the HMM by EM and return the posterior of the constrained state.

    Parameters
    ----------
    pos : ndarray, shape (P, T, 3)
        Child position in the parent, per pair and latent step, metres; NaN without
        evidence.
    quat : ndarray, shape (P, T, 4)
        Child orientation in the parent, x y z w; NaN without evidence.
    theta_pos, theta_quat : ndarray, shape (P, 3) and (P, 4)
        Initial constraint poses (e.g. the last relative pose of the recording).
    params : HMMParams, optional
        Initial parameters.
    n_iter : int
        EM iterations.
    sigma_floor : (float, float)
        Lower bounds of the constrained-state noise, metres and radians: a
        noise-free track must not make the likelihood infinite.
    update_shared : bool
        Re-estimate the shared parameters (noise, spreads, transitions); False
        learns only the constraint poses (a further pose of a pair whose shared
        parameters were learned over all pairs).

    Returns
    -------
    posterior : ndarray, shape (P, T)
        ``p(constrained)`` per pair and step.
    params : HMMParams
        The learned shared parameters.
    theta_pos, theta_quat : ndarray, shape (P, 3) and (P, 4)
        The learned constraint poses.
    """
    prm = HMMParams() if params is None else params
    tp = theta_pos.copy()
    tq = theta_quat.copy()
    ok = np.all(np.isfinite(pos), axis=-1) & np.all(np.isfinite(quat), axis=-1)
    p0 = np.where(ok[..., None], pos, 0.0)
    q0 = np.where(ok[..., None], quat, 0.0)
    gamma = np.zeros((*pos.shape[:2], 2))
    for _ in range(n_iter):
        dp, dr = deviations(pos, quat, tp, tq)
        gamma, xi, _ = forward_backward(
            log_emissions(dp, dr, prm),
            prm.transition,
            prm.initial,
        )
        g1 = np.where(ok, gamma[..., 1], 0.0)
        g0 = np.where(ok, gamma[..., 0], 0.0)
        if update_shared:
            _update_shared(prm, g0, g1, dp, dr, xi, sigma_floor)
        # Each pair's constraint pose: the posterior-weighted mean of its constrained steps.
        wp = g1.sum(axis=1)
        has = wp > 1e-6
        if np.any(has):
            tp[has] = np.einsum("pt,ptk->pk", g1[has], p0[has]) / wp[has, None]
            sign = np.sign(np.sum(q0 * tq[:, None, :], axis=-1))
            m = np.einsum("pt,ptk->pk", g1 * sign, q0)
            norm = np.linalg.norm(m, axis=1)
            upd = has & (norm > 1e-9)
            tq[upd] = se3.check_quat(m[upd] / norm[upd, None])
    return gamma[..., 1], prm, tp, tq


def _update_shared(
    prm: HMMParams,
    g0: FloatArray,
    g1: FloatArray,
    dp: FloatArray,
    dr: FloatArray,
    xi: FloatArray,
    sigma_floor: tuple[float, float],
) -> None:
    """M-step of the shared parameters."""
    w1 = g1.sum()
    if w1 > 1e-9:
        prm.sigma_pos = max(sigma_floor[0], math.sqrt(np.nansum(g1 * dp**2) / (3 * w1)))
        prm.sigma_rot = max(sigma_floor[1], math.sqrt(np.nansum(g1 * dr**2) / (3 * w1)))
    w0 = g0.sum()
    if w0 > 1e-9:
        # Free spreads stay well above the constrained noise: the states must not swap.
        prm.lambda_pos = max(5 * prm.sigma_pos, float(np.nansum(g0 * dp) / (3 * w0)))
        prm.lambda_rot = max(5 * prm.sigma_rot, float(np.nansum(g0 * dr) / (3 * w0)))
    trans = xi + 1e-3
    prm.transition = trans / trans.sum(axis=1, keepdims=True)
