"""Fit one constraint model to a relative-pose track, robustly, with its likelihood.

The likelihood
--------------
Each sample is an inlier or a gross outlier, uniform over the track's bounding
box (and over SO(3) for orientations), at rate ``γ``. An inlier's position and
rotation residuals are isotropic Gaussians of levels ``σ_pos`` and ``σ_rot``;
the model's latent configuration (angle, displacement) is integrated out under
a uniform prior over its observed range ``L`` (Laplace approximation), so that a
joint does not win just by absorbing noise along its free direction: per sample
and latent coordinate it pays ``log V`` with ``V = sqrt(L² + 2π σ_latent²)`` and
gains ``½ log(2π σ_latent²)``, which cancel when the range is no wider than the
noise.

The fit
-------
Hard EM: a least-squares fit (with least-trimmed-squares concentration steps
when the residuals are heavy-tailed), noise levels from the median residual,
then alternately: classify samples (outlier when the uniform density, at prior
odds 1:19, beats the inlier density; at most ``NoiseModel.max_outliers`` of
them), refit the geometry on the inliers, and re-estimate ``σ_pos``, ``σ_rot``
by maximum likelihood (the latent's share of each residual's degrees of freedom
removed), clipped to the :class:`~thirdhand.constraints.types.NoiseModel`
bounds. The ``free`` model has no outliers and a spread of at least the ceiling.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from thirdhand.arrays import FloatArray
from thirdhand.constraints.geometry import col_ptp, masked_median
from thirdhand.constraints.kernels import KERNELS, Geometry, Kernel, Projection
from thirdhand.constraints.types import ConstraintFitError, NoiseModel

#: Fewest valid samples a track must have.
MIN_SAMPLES = 5
#: Volume of SO(3) in rotation-vector measure (the density of a uniform rotation).
_SO3_VOLUME = 8.0 * math.pi**2
_LOG2PI = math.log(2.0 * math.pi)
#: Median of a chi-square with 3 degrees of freedom (robust start of σ).
_CHI2_3_MEDIAN = 2.365974
_EM_ITERATIONS = 5
#: Concentration steps of the trimmed start, and the squared residual (in units of
#: its median) beyond which residuals count as heavy-tailed (outliers present).
_C_STEPS = 3
_HEAVY_TAIL = 25.0
#: Prior odds of a sample being a gross outlier, when classifying samples.
_OUTLIER_PRIOR = 0.05


@dataclass
class ModelFit:
    """One model fitted to a track, with what model selection needs.

    Attributes
    ----------
    kernel : Kernel
    geom : Geometry
    proj : Projection
    sigma_pos, sigma_rot : float
        Noise levels, metres and radians (``sigma_rot`` NaN for position-only).
    outlier_fraction : float
    inlier : ndarray of bool, shape (n,)
        Samples whose inlier responsibility is at least one half.
    weights : ndarray, shape (n,)
        Weights of the last geometric fit (1 for inliers, 0 for outliers).
    log_likelihood : float
        Total, nats.
    n_params : int
        Free parameters, for the BIC.
    """

    kernel: Kernel
    geom: Geometry
    proj: Projection
    sigma_pos: float
    sigma_rot: float
    outlier_fraction: float
    inlier: NDArray[np.bool_]
    weights: FloatArray
    log_likelihood: float
    n_params: int

    @property
    def bic(self) -> float:
        """Bayesian information criterion ``-2 log L + k log n`` (lower is better)."""
        return self.bic_at(float(self.weights.shape[0]))

    def bic_at(self, n_eff: float) -> float:
        """BIC with ``n_eff`` effective samples: the log-likelihood is scaled by ``n_eff / n``.

        Successive samples of a track are not independent (the sensor's error is
        correlated in time); counting each as a full observation overstates the
        evidence for a more flexible model.
        """
        n = self.weights.shape[0]
        return -2.0 * self.log_likelihood * n_eff / n + self.n_params * math.log(n_eff)

    def residual_correlation_time(self) -> float:
        """Integrated autocorrelation time of the whitened inlier residuals, samples (>= 1).

        ``τ = 1 + 2 Σ_k ρ_k`` over the lags ``k`` of Geyer's initial positive
        sequence (pairs ``ρ_2j + ρ_2j+1`` summed while positive), with ``ρ_k`` the
        lag-``k`` autocorrelation of the residuals divided by the noise levels and
        stacked (position, rotation). An AR(1) error of lag-1 correlation ``ρ``
        gives ``(1 + ρ) / (1 - ρ)``; white noise 1; an error that is white noise
        plus a slow wander (a tracker drifting, a pose-dependent error along a
        path) the wander's correlation length times its share of the variance,
        which the lag-1 correlation alone understates by an order of magnitude.
        1 when the residuals vanish (a noise-free track).
        """
        e_rot = self.proj.e_rot
        return _correlation_time(
            self.proj.e_pos,
            self.proj.e_pos if e_rot is None else e_rot,
            e_rot is not None,
            self.inlier,
            self.sigma_pos,
            self.sigma_rot,
        )


@njit(cache=True, error_model="numpy")
def _correlation_time(
    e_pos: FloatArray,
    e_rot: FloatArray,
    oriented: bool,
    inlier: NDArray[np.bool_],
    sp: float,
    sr: float,
) -> float:  # pragma: no cover - compiled
    """:meth:`ModelFit.residual_correlation_time` of the residuals ``(n, 3)``."""
    idx = np.flatnonzero(inlier)
    m = idx.size
    if m < 3:
        return 1.0
    k = 6 if oriented else 3
    e = np.empty((m, k))
    for r in range(m):
        i = idx[r]
        for c in range(3):
            e[r, c] = e_pos[i, c] / sp
            if oriented:
                e[r, 3 + c] = e_rot[i, c] / sr
    for c in range(k):
        mean = 0.0
        for r in range(m):
            mean += e[r, c]
        mean /= m
        for r in range(m):
            e[r, c] -= mean
    den = 0.0
    for r in range(m):
        for c in range(k):
            den += e[r, c] * e[r, c]
    if den < 1e-12 * m * k:
        return 1.0
    tau = -1.0
    max_lag = m // 2
    lag = 0
    while lag + 1 <= max_lag:
        pair = 0.0
        for d in (lag, lag + 1):
            num = 0.0
            for r in range(d, m):
                for c in range(k):
                    num += e[r, c] * e[r - d, c]
            pair += num / den
        if pair <= 0.0:
            break
        tau += 2.0 * pair
        lag += 2
    return max(tau, 1.0)


def prepare_track(
    pos: ArrayLike, quat: ArrayLike | None = None, *, where: str = "track"
) -> tuple[FloatArray, FloatArray | None]:
    """Validate a relative-pose track and drop its invalid samples.

    Parameters
    ----------
    pos : array_like, shape (n, 3)
        Child positions in the parent frame, metres.
    quat : array_like, shape (n, 4), optional
        Child orientations in the parent frame, x y z w (any signs, any norms).
    where : str
        Name of the track for error messages.

    Returns
    -------
    pos : ndarray, shape (m, 3)
        The samples whose position (and quaternion) are finite, quaternion non-zero.
    quat : ndarray, shape (m, 4) or None
        Unit quaternions of those samples.

    Raises
    ------
    ConstraintFitError
        For wrong shapes, or fewer than :data:`MIN_SAMPLES` valid samples.
    """
    p = np.asarray(pos, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ConstraintFitError(f"{where}: expected positions of shape (n, 3), got {p.shape}")
    q = None
    if quat is not None:
        q = np.asarray(quat, dtype=np.float64)
        if q.shape != (p.shape[0], 4):
            raise ConstraintFitError(
                f"{where}: expected quaternions of shape ({p.shape[0]}, 4), got {q.shape}"
            )
    n_all = p.shape[0]
    p, q_unit, n_ok = _clean_track(
        np.ascontiguousarray(p), np.ascontiguousarray(q) if q is not None else _NO_QUAT
    )
    if n_ok < MIN_SAMPLES:
        hint = ""
        if q is not None:
            n_pos = int(np.all(np.isfinite(np.asarray(pos, dtype=np.float64)), axis=1).sum())
            if n_pos >= MIN_SAMPLES:
                hint = (
                    f"; {n_pos - n_ok} more have a position but no orientation: pass "
                    "quat=None for a position-only fit"
                )
        raise ConstraintFitError(
            f"{where}: {n_ok} valid sample(s) of {n_all}; a constraint fit needs at "
            f"least {MIN_SAMPLES} (samples with a NaN position or quaternion are dropped)" + hint
        )
    span = float(col_ptp(p).max())
    if span > 1e3:
        raise ConstraintFitError(
            f"{where}: positions span {span:.3g} m; expected metres "
            "(a relative track of an assembly spans well under a kilometre)"
        )
    return p, None if q is None else q_unit


#: Stand-in for the quaternions of a position-only track in the compiled kernels.
_NO_QUAT = np.zeros((0, 4))


@njit(cache=True, error_model="numpy")
def _clean_track(
    p: FloatArray, q: FloatArray
) -> tuple[FloatArray, FloatArray, int]:  # pragma: no cover - compiled
    """Rows of ``p (n, 3)`` (and ``q (n, 4)``, unless empty) that are finite, with a
    quaternion norm above 1e-9; the quaternions normalised; and their number."""
    n = p.shape[0]
    oriented = q.shape[0] > 0
    ok = np.empty(n, dtype=np.bool_)
    norm = np.ones(n)
    for i in range(n):
        good = np.isfinite(p[i, 0]) and np.isfinite(p[i, 1]) and np.isfinite(p[i, 2])
        if oriented:
            s = q[i, 0] * q[i, 0] + q[i, 1] * q[i, 1] + q[i, 2] * q[i, 2] + q[i, 3] * q[i, 3]
            norm[i] = math.sqrt(s)
            good = good and np.isfinite(norm[i]) and norm[i] > 1e-9
        ok[i] = good
    idx = np.flatnonzero(ok)
    p_out = np.empty((idx.size, 3))
    q_out = np.empty((idx.size if oriented else 0, 4))
    for r in range(idx.size):
        i = idx[r]
        for c in range(3):
            p_out[r, c] = p[i, c]
        if oriented:
            for c in range(4):
                q_out[r, c] = q[i, c] / norm[i]
    return p_out, q_out, idx.size


@njit(cache=True, error_model="numpy")
def _log_outlier(p: FloatArray, oriented: bool) -> float:  # pragma: no cover - compiled
    """Log-density of a gross outlier: uniform over the track's bounding box (sides at
    least 10 cm) and, when oriented, over SO(3)."""
    side = col_ptp(p)
    out = 0.0
    for a in range(side.shape[0]):
        out += math.log(max(side[a], 0.1))
    return -out - math.log(_SO3_VOLUME) if oriented else -out


def _inlier_loglik(
    proj: Projection,
    sp: float,
    sr: float,
    inlier: NDArray[np.bool_],
) -> FloatArray:
    """Per-sample inlier log-likelihood, latent integrated out (Laplace), shape (n,)."""
    oriented = proj.d2_rot is not None
    return _loglik(
        proj.d2_pos,
        proj.d2_rot if proj.d2_rot is not None else proj.d2_pos,
        proj.latent,
        proj.g_pos,
        proj.g_rot,
        inlier,
        sp,
        sr,
        oriented,
    )


@njit(cache=True, error_model="numpy")
def _loglik(
    d2p: FloatArray,
    d2r: FloatArray,
    lat: FloatArray,
    gp: FloatArray,
    gr: FloatArray,
    inlier: NDArray[np.bool_],
    sp: float,
    sr: float,
    oriented: bool,
) -> FloatArray:  # pragma: no cover - compiled
    n, d = lat.shape
    ll = np.empty(n)
    c_pos = -1.5 * (_LOG2PI + 2.0 * math.log(sp))
    sp2 = sp**2
    sr2 = sr**2
    c_rot = -1.5 * (_LOG2PI + 2.0 * math.log(sr)) if oriented else 0.0
    for i in range(n):
        ll[i] = c_pos - 0.5 * d2p[i] / sp2
        if oriented:
            ll[i] += c_rot - 0.5 * d2r[i] / sr2
    if d == 0:
        return ll
    inv_sr2 = 1.0 / sr2 if oriented else 0.0
    any_in = False
    for i in range(n):
        if inlier[i]:
            any_in = True
            break
    log_v = np.empty(d)
    for j in range(d):
        lo = math.inf
        hi = -math.inf
        h_sum = 0.0
        for i in range(n):
            if inlier[i] or not any_in:
                lo = min(lo, lat[i, j])
                hi = max(hi, lat[i, j])
            h_sum += gp[i, j] / sp2 + gr[i, j] * inv_sr2
        span = hi - lo
        log_v[j] = 0.5 * math.log(span**2 + 2.0 * math.pi / (h_sum / n))
    for i in range(n):
        acc = 0.0
        for j in range(d):
            h = gp[i, j] / sp2 + gr[i, j] * inv_sr2
            acc += 0.5 * _LOG2PI - 0.5 * math.log(h) - log_v[j]
        ll[i] += acc
    return ll


@njit(cache=True, error_model="numpy")
def _noise_levels(
    d2p: FloatArray,
    d2r: FloatArray,
    gp: FloatArray,
    gr: FloatArray,
    resp: FloatArray,
    sp: float,
    sr: float,
    oriented: bool,
) -> tuple[float, float]:  # pragma: no cover - compiled
    """Maximum-likelihood noise levels given the responsibilities ``resp (n,)``.

    The latent absorbs part of each residual's degrees of freedom: a fraction
    ``(g_pos/σ_pos²) / H`` of a latent coordinate's information comes from the
    position, the rest from the rotation.
    """
    n, d = gp.shape
    sp2 = sp**2
    sr2 = sr**2
    total = 0.0
    absorbed = 0.0
    sum_p = 0.0
    sum_r = 0.0
    for i in range(n):
        a = 0.0
        for j in range(d):
            hp = gp[i, j] / sp2
            hr = gr[i, j] / sr2 if oriented else 0.0
            a += hp / (hp + hr)
        total += resp[i]
        absorbed += resp[i] * a
        sum_p += resp[i] * d2p[i]
        if oriented:
            sum_r += resp[i] * d2r[i]
    sp_new = math.sqrt(sum_p / max(3.0 * total - absorbed, 1e-9))
    sr_new = sr
    if oriented:
        # The rotation's share of the latent: d - absorbed_pos per sample.
        dof_rot = 3.0 * total - (d * total - absorbed)
        sr_new = math.sqrt(sum_r / max(dof_rot, 1e-9))
    return sp_new, sr_new


@njit(cache=True, error_model="numpy")
def _classify(
    ll_in: FloatArray,
    inlier: NDArray[np.bool_],
    w: FloatArray,
    log_out: float,
    log_prior: float,
    max_out: int,
) -> tuple[NDArray[np.bool_], bool, bool, float, int]:  # pragma: no cover - compiled
    """New inliers: the (at most ``max_out``) samples the outlier density explains better.

    Returns the new inlier mask, whether it equals ``inlier`` and ``w > 0``, the sum
    of ``ll_in`` over the new inliers and the number of new outliers.
    """
    n = ll_in.shape[0]
    new = np.ones(n, dtype=np.bool_)
    if max_out:
        gain = log_prior + log_out - ll_in
        n_pos = 0
        for i in range(n):
            if gain[i] > 0.0:
                n_pos += 1
        cut = 0.0
        if n_pos > max_out:
            cut = np.partition(-gain, max_out - 1)[max_out - 1]
        for i in range(n):
            if gain[i] > 0.0 and (n_pos <= max_out or -gain[i] <= cut):
                new[i] = False
    same_in = True
    same_w = True
    ll_sum = 0.0
    n_out = 0
    for i in range(n):
        if new[i] != inlier[i]:
            same_in = False
        if new[i] != (w[i] > 0.0):
            same_w = False
        if new[i]:
            ll_sum += ll_in[i]
        else:
            n_out += 1
    return new, same_in, same_w, ll_sum, n_out


@njit(cache=True, error_model="numpy")
def _em_step(
    d2p: FloatArray,
    d2r: FloatArray,
    lat: FloatArray,
    gp: FloatArray,
    gr: FloatArray,
    inlier: NDArray[np.bool_],
    w: FloatArray,
    oriented: bool,
    start: bool,
    par: FloatArray,
    max_out: int,
) -> tuple[
    float, float, FloatArray, NDArray[np.bool_], bool, bool, float, int
]:  # pragma: no cover - compiled
    """One EM step after a geometric fit and projection: noise levels, likelihood, classes.

    ``par`` holds ``σ_pos, σ_rot`` (the current levels), their bounds ``lo_pos,
    hi_pos, lo_rot, hi_rot``, the outlier log-density, the outlier log prior odds,
    and the median squared position and rotation residuals when known (else NaN).
    At the ``start`` the levels come from the median residuals of the samples of
    positive weight ``w``, else by maximum likelihood (:func:`_noise_levels`); then
    :func:`_loglik` with the old inliers and :func:`_classify`. Returns ``σ_pos,
    σ_rot``, the per-sample inlier log-likelihood and what :func:`_classify` returns.
    """
    sp, sr = par[0], par[1]
    if start:
        # Robust start: scales from the median residual, immune to outliers.
        d_latent = lat.shape[1]
        med = par[8] if not math.isnan(par[8]) else masked_median(d2p, w)
        sp = math.sqrt(med / _CHI2_3_MEDIAN * 3.0 / max(3.0 - d_latent, 1.0))
        if oriented:
            med_r = par[9] if not math.isnan(par[9]) else masked_median(d2r, w)
            sr = math.sqrt(med_r / _CHI2_3_MEDIAN)
    else:
        sp, sr = _noise_levels(d2p, d2r, gp, gr, w, sp, sr, oriented)
    sp = min(max(sp, par[2]), par[3])
    sr = min(max(sr, par[4]), par[5])
    ll_in = _loglik(d2p, d2r, lat, gp, gr, inlier, sp, sr, oriented)
    new, same_in, same_w, ll_sum, n_out = _classify(ll_in, inlier, w, par[6], par[7], max_out)
    return sp, sr, ll_in, new, same_in, same_w, ll_sum, n_out


def _total_parts(
    ll_sum: float, n_out: int, n: int, log_out: float, n_model: int, oriented: bool
) -> tuple[float, int]:
    """Total log-likelihood (inliers, and outliers at rate γ = their fraction) and ``k``.

    From the inliers' summed log-likelihood ``ll_sum`` and the number of outliers.
    """
    ll = ll_sum
    if n_out:
        gamma = n_out / n
        ll += (n - n_out) * math.log1p(-gamma) + n_out * (math.log(gamma) + log_out)
    return ll, n_model + (2 if oriented else 1) + (1 if n_out else 0)


@njit(cache=True, error_model="numpy")
def _masked_sum(x: FloatArray, mask: NDArray[np.bool_]) -> tuple[float, int]:  # pragma: no cover
    """Sum and number of the entries of ``x`` where ``mask`` holds."""
    total = 0.0
    count = 0
    for i in range(x.shape[0]):
        if mask[i]:
            total += x[i]
            count += 1
    return total, count


def _trimmed_start(
    kernel: Kernel,
    pos: FloatArray,
    quat: FloatArray | None,
    geom: Geometry,
    proj: Projection,
    n_keep: int,
    force: bool = False,
) -> tuple[Geometry | None, Projection, FloatArray, tuple[float, float]]:
    """Concentration steps of a least-trimmed-squares fit, when residuals are heavy-tailed.

    With ``force`` the steps are taken whatever the residuals' tails (the second
    start of :func:`fit_model`).

    A least-squares start is pulled by gross outliers, so far that the EM may not
    tell them apart; refitting on the ``n_keep`` samples of smallest residual
    (twice) moves the start back to the bulk of the track. Also returns the median
    squared position and rotation residuals when no sample was trimmed (NaN else).
    """
    w = np.ones(pos.shape[0])
    g_cur: Geometry | None = geom
    medians = (math.nan, math.nan)
    for step in range(_C_STEPS):
        oriented = proj.d2_rot is not None
        heavy, w_new, med_p, med_r = _trim_weights(
            proj.d2_pos,
            proj.d2_rot if proj.d2_rot is not None else proj.d2_pos,
            oriented,
            n_keep,
            0.0 if force else _HEAVY_TAIL * (2.0 if oriented else 1.0),
        )
        if not heavy:
            if step == 0:
                medians = (med_p, med_r)
            break
        w = w_new
        g_cur = kernel.fit(pos, quat, w, 1.0)
        if g_cur is None:
            return None, proj, w, medians
        proj = kernel.project(g_cur, pos, quat, 1.0)
    return g_cur, proj, w, medians


@njit(cache=True, error_model="numpy")
def _trim_weights(
    d2p: FloatArray, d2r: FloatArray, oriented: bool, n_keep: int, heavy: float
) -> tuple[bool, FloatArray, float, float]:  # pragma: no cover - compiled
    """Whether the squared residuals (in units of their medians) are heavy-tailed, the
    weights keeping the ``n_keep`` smallest of them, and the two medians."""
    med_p = np.median(d2p)
    med_r = np.median(d2r) if oriented else math.nan
    d2 = d2p / max(med_p, 1e-300)
    if oriented:
        d2 = d2 + d2r / max(med_r, 1e-300)
    if d2.max() < heavy:
        return False, np.ones(d2.shape[0]), med_p, med_r
    cut = np.partition(d2, n_keep - 1)[n_keep - 1]
    return True, (d2 <= cut).astype(np.float64), med_p, med_r


def fit_model(
    name: str,
    pos: FloatArray,
    quat: FloatArray | None,
    *,
    noise: NoiseModel | None = None,
    stop_above: float = math.inf,
) -> ModelFit | None:
    """Fit one model robustly (EM over inlier/outlier and noise), on a prepared track.

    Parameters
    ----------
    name : str
        A key of :data:`thirdhand.constraints.kernels.KERNELS`.
    pos : ndarray, shape (n, 3)
        Valid child positions in the parent frame, metres (see :func:`prepare_track`).
    quat : ndarray, shape (n, 4) or None
        Unit child orientations in the parent frame, x y z w.
    noise : NoiseModel, optional
    stop_above : float
        Stop iterating as soon as the model's BIC (after its robust start) is above
        this: a model far behind another needs no converged score to lose.

    Returns
    -------
    ModelFit or None
        None when the model cannot describe the track at all (a cylindrical joint
        on a position-only track, a circle through collinear points).
    """
    nm = noise or NoiseModel()
    fit = _fit_em(name, pos, quat, nm, stop_above, force_trim=False)
    if (
        fit is not None
        and fit.kernel.name != "free"
        and nm.max_outliers > 0.0
        and fit.outlier_fraction == 0.0
        and fit.sigma_pos >= nm.pos_ceiling * (1.0 - 1e-9)
    ):
        # Pinned at its ceiling with no outlier: the least-squares start may have been
        # pulled onto a stretch the model does not describe (a grasp shift at an end
        # stop) without its residuals looking heavy-tailed. A second start from the
        # trimmed fit; the higher likelihood is kept.
        alt = _fit_em(name, pos, quat, nm, stop_above, force_trim=True)
        if alt is not None and alt.log_likelihood > fit.log_likelihood:
            return alt
    return fit


def _fit_em(
    name: str,
    pos: FloatArray,
    quat: FloatArray | None,
    nm: NoiseModel,
    stop_above: float,
    *,
    force_trim: bool,
) -> ModelFit | None:
    """The EM of :func:`fit_model` from its least-squares (or, forced, trimmed) start."""
    kernel = KERNELS[name]
    free = name == "free"
    oriented = quat is not None
    n = pos.shape[0]
    lo_p, hi_p = (nm.pos_ceiling, math.inf) if free else (nm.pos_floor, nm.pos_ceiling)
    lo_r, hi_r = (nm.rot_ceiling, math.inf) if free else (nm.rot_floor, nm.rot_ceiling)
    log_out = _log_outlier(pos, oriented)
    # At most this many samples may be called outliers: a model that needs more is
    # a bad model of the track, not a good model of part of it.
    max_out = 0 if free else int(nm.max_outliers * n)
    log_prior = math.log(_OUTLIER_PRIOR) - math.log1p(-_OUTLIER_PRIOR)
    n_model = kernel.n_params[int(oriented)]

    w = np.ones(n)
    inlier = np.ones(n, dtype=bool)
    sp, sr = nm.pos_ceiling, nm.rot_ceiling
    geom: Geometry | None = None
    proj: Projection | None = None
    ll_sum, n_out, same_in = 0.0, 0, False
    refit = True
    reproject = kernel.uses_ratio(oriented)
    for it in range(_EM_ITERATIONS):
        if refit:
            geom = kernel.fit(pos, quat, w, sp / sr)
        if geom is None:
            return None
        if refit or reproject or proj is None:
            proj = kernel.project(geom, pos, quat, sp / sr)
        medians = (math.nan, math.nan)
        if it == 0 and max_out:
            geom, proj, w, medians = _trimmed_start(
                kernel, pos, quat, geom, proj, n - max_out, force_trim
            )
            if geom is None:
                return None
        rot = proj.d2_rot is not None
        sp, sr, ll_in, new_inlier, same_in, same_w, ll_sum, n_out = _em_step(
            proj.d2_pos,
            proj.d2_rot if proj.d2_rot is not None else proj.d2_pos,
            proj.latent,
            proj.g_pos,
            proj.g_rot,
            inlier,
            w,
            rot,
            it == 0,
            np.array([sp, sr, lo_p, hi_p, lo_r, hi_r, log_out, log_prior, *medians]),
            max_out,
        )
        converged = it > 0 and same_in
        # The geometry depends on the weights only (the noise ratio enters the projection).
        refit = not same_w
        inlier = new_inlier
        w = inlier.astype(np.float64)
        if converged:
            break
        if math.isfinite(stop_above):
            ll, k = _total_parts(ll_sum, n_out, n, log_out, n_model, oriented)
            if -2.0 * ll + k * math.log(n) > stop_above:
                break
    assert geom is not None and proj is not None
    if not same_in:
        # The last step scored the samples with the previous inliers' latent ranges.
        ll_in = _inlier_loglik(proj, sp, sr, inlier)
        ll_sum, n_in = _masked_sum(ll_in, inlier)
        n_out = n - n_in
    ll, k = _total_parts(ll_sum, n_out, n, log_out, n_model, oriented)
    return ModelFit(
        kernel=kernel,
        geom=geom,
        proj=proj,
        sigma_pos=sp,
        sigma_rot=sr if oriented else math.nan,
        outlier_fraction=n_out / n,
        inlier=inlier,
        weights=w,
        log_likelihood=ll,
        n_params=k,
    )
