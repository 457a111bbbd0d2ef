"""Fit one constraint model to a relative-pose track, robustly, with its likelihood.

The likelihood
--------------
Each sample is an inlier with probability ``1 - γ`` or a gross outlier, uniform
over the track's bounding box (and over SO(3) for orientations). An inlier's
position and rotation residuals are isotropic Gaussians of levels ``σ_pos`` and
``σ_rot``; the model's latent configuration (angle, displacement) is integrated
out under a uniform prior over its observed range ``L`` (Laplace
approximation), so that a joint does not win just by absorbing noise along its
free direction: per sample and latent coordinate it pays ``log V`` with
``V = sqrt(L² + 2π σ_latent²)`` and gains ``½ log(2π σ_latent²)``, which cancel
when the range is no wider than the noise. ``σ_pos``, ``σ_rot`` and ``γ`` are
maximum-likelihood estimates (EM), clipped to the bounds of the
:class:`~thirdhand.constraints.types.NoiseModel`; the model's geometry is refitted
with the inlier responsibilities as weights, so outliers lose their pull.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from thirdhand import se3
from thirdhand.constraints import geometry as g
from thirdhand.constraints.kernels import KERNELS, Geometry, Kernel, Projection
from thirdhand.constraints.types import Constraint, ConstraintFitError, NoiseModel

FloatArray = NDArray[np.float64]

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

    def residual_autocorrelation(self) -> float:
        """Lag-1 autocorrelation of the whitened inlier residuals, in [0, 1).

        Residuals are divided by the noise levels and stacked (position, rotation);
        0 when the residuals vanish (a noise-free track).
        """
        e = self.proj.e_pos[self.inlier] / self.sigma_pos
        if self.proj.e_rot is not None:
            e = np.hstack([e, self.proj.e_rot[self.inlier] / self.sigma_rot])
        e = e - e.mean(axis=0)
        den = float(np.sum(e * e))
        if e.shape[0] < 3 or den < 1e-12 * e.size:
            return 0.0
        rho = float(np.sum(e[1:] * e[:-1])) / den
        return min(max(rho, 0.0), 0.99)


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
    ok = np.all(np.isfinite(p), axis=1)
    q = None
    if quat is not None:
        q = np.asarray(quat, dtype=np.float64)
        if q.shape != (p.shape[0], 4):
            raise ConstraintFitError(
                f"{where}: expected quaternions of shape ({p.shape[0]}, 4), got {q.shape}"
            )
        with np.errstate(invalid="ignore"):
            norm = np.linalg.norm(q, axis=1)
        ok &= np.all(np.isfinite(q), axis=1) & (norm > 1e-9)
        q = q[ok] / norm[ok, None]
    n_ok = int(ok.sum())
    if n_ok < MIN_SAMPLES:
        raise ConstraintFitError(
            f"{where}: {n_ok} valid sample(s) of {p.shape[0]}; a constraint fit needs at "
            f"least {MIN_SAMPLES} (samples with a NaN position or quaternion are dropped)"
        )
    p = p[ok]
    if np.ptp(p, axis=0).max() > 1e3:
        raise ConstraintFitError(
            f"{where}: positions span {np.ptp(p, axis=0).max():.3g} m; expected metres "
            "(a relative track of an assembly spans well under a kilometre)"
        )
    return p, q


def _log_outlier(p: FloatArray, oriented: bool) -> float:
    side = np.maximum(np.ptp(p, axis=0), 0.1)
    out = -float(np.sum(np.log(side)))
    return out - math.log(_SO3_VOLUME) if oriented else out


def _inlier_loglik(
    proj: Projection,
    sp: float,
    sr: float,
    inlier: NDArray[np.bool_],
) -> FloatArray:
    """Per-sample inlier log-likelihood, latent integrated out (Laplace), shape (n,)."""
    ll = -1.5 * (_LOG2PI + 2.0 * math.log(sp)) - 0.5 * proj.d2_pos / sp**2
    if proj.d2_rot is not None:
        ll += -1.5 * (_LOG2PI + 2.0 * math.log(sr)) - 0.5 * proj.d2_rot / sr**2
    d = proj.latent.shape[1]
    if d:
        inv_sr2 = 1.0 / sr**2 if proj.e_rot is not None else 0.0
        h = proj.g_pos / sp**2 + proj.g_rot * inv_sr2
        lat = proj.latent[inlier] if inlier.any() else proj.latent
        span = np.ptp(lat, axis=0)
        h_mean = np.mean(h, axis=0)
        log_v = 0.5 * np.log(span**2 + 2.0 * math.pi / h_mean)
        ll += np.sum(0.5 * _LOG2PI - 0.5 * np.log(h) - log_v, axis=1)
    return np.asarray(ll, dtype=np.float64)


def _noise_mle(proj: Projection, resp: FloatArray, sp: float, sr: float) -> tuple[float, float]:
    """Maximum-likelihood noise levels given the responsibilities.

    The latent absorbs part of each residual's degrees of freedom: a fraction
    ``(g_pos/σ_pos²) / H`` of a latent coordinate's information comes from the
    position, the rest from the rotation.
    """
    oriented = proj.e_rot is not None
    absorbed_pos = np.zeros(resp.shape[0])
    if proj.latent.shape[1]:
        hp = proj.g_pos / sp**2
        hr = proj.g_rot / sr**2 if oriented else np.zeros_like(hp)
        absorbed_pos = np.sum(hp / (hp + hr), axis=1)
    total = resp.sum()
    dof_pos = 3.0 * total - resp @ absorbed_pos
    sp_new = math.sqrt(resp @ proj.d2_pos / max(dof_pos, 1e-9))
    sr_new = sr
    if oriented:
        assert proj.d2_rot is not None
        absorbed_rot = proj.latent.shape[1] - absorbed_pos
        dof_rot = 3.0 * total - resp @ absorbed_rot
        sr_new = math.sqrt(resp @ proj.d2_rot / max(dof_rot, 1e-9))
    return sp_new, sr_new


def _total(
    ll_in: FloatArray, inlier: NDArray[np.bool_], log_out: float, n_model: int, oriented: bool
) -> tuple[float, int]:
    """Total log-likelihood (inliers, and outliers at rate γ = their fraction) and ``k``."""
    n = ll_in.shape[0]
    n_out = int(n - inlier.sum())
    ll = float(ll_in[inlier].sum())
    if n_out:
        gamma = n_out / n
        ll += (n - n_out) * math.log1p(-gamma) + n_out * (math.log(gamma) + log_out)
    return ll, n_model + (2 if oriented else 1) + (1 if n_out else 0)


def _trimmed_start(
    kernel: Kernel,
    pos: FloatArray,
    quat: FloatArray | None,
    geom: Geometry,
    proj: Projection,
    n_keep: int,
) -> tuple[Geometry | None, Projection, FloatArray]:
    """Concentration steps of a least-trimmed-squares fit, when residuals are heavy-tailed.

    A least-squares start is pulled by gross outliers, so far that the EM may not
    tell them apart; refitting on the ``n_keep`` samples of smallest residual
    (twice) moves the start back to the bulk of the track.
    """
    w = np.ones(pos.shape[0])
    g_cur: Geometry | None = geom
    for _ in range(_C_STEPS):
        d2 = proj.d2_pos
        d2 = d2 / max(float(np.median(d2)), 1e-300)
        if proj.d2_rot is not None:
            r2 = proj.d2_rot
            d2 = d2 + r2 / max(float(np.median(r2)), 1e-300)
        if d2.max() < _HEAVY_TAIL * (2.0 if proj.e_rot is not None else 1.0):
            break
        cut = np.partition(d2, n_keep - 1)[n_keep - 1]
        w = (d2 <= cut).astype(np.float64)
        g_cur = kernel.fit(pos, quat, w, 1.0)
        if g_cur is None:
            return None, proj, w
        proj = kernel.project(g_cur, pos, quat, 1.0)
    return g_cur, proj, w


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

    w = np.ones(n)
    inlier = np.ones(n, dtype=bool)
    sp, sr = nm.pos_ceiling, nm.rot_ceiling
    geom: Geometry | None = None
    proj: Projection | None = None
    ll_in = np.zeros(n)
    refit = True
    for it in range(_EM_ITERATIONS):
        if refit:
            geom = kernel.fit(pos, quat, w, sp / sr)
        if geom is None:
            return None
        proj = kernel.project(geom, pos, quat, sp / sr)
        if it == 0:
            if max_out:
                geom, proj, w = _trimmed_start(kernel, pos, quat, geom, proj, n - max_out)
                if geom is None:
                    return None
            # Robust start: scales from the median residual, immune to outliers.
            keep = w > 0
            d_latent = proj.latent.shape[1]
            med = float(np.median(proj.d2_pos[keep]))
            sp = math.sqrt(med / _CHI2_3_MEDIAN * 3.0 / max(3.0 - d_latent, 1.0))
            if proj.e_rot is not None:
                assert proj.d2_rot is not None
                sr = math.sqrt(float(np.median(proj.d2_rot[keep])) / _CHI2_3_MEDIAN)
        else:
            sp, sr = _noise_mle(proj, w, sp, sr)
        sp = min(max(sp, lo_p), hi_p)
        sr = min(max(sr, lo_r), hi_r)
        ll_in = _inlier_loglik(proj, sp, sr, inlier)
        new_inlier = np.ones(n, dtype=bool)
        if max_out:
            gain = log_prior + log_out - ll_in
            worst = np.argpartition(-gain, max_out - 1)[:max_out]
            new_inlier[worst[gain[worst] > 0.0]] = False
        converged = it > 0 and np.array_equal(new_inlier, inlier)
        # The geometry depends on the weights only (the noise ratio enters the projection).
        refit = not np.array_equal(new_inlier, w > 0)
        inlier = new_inlier
        w = inlier.astype(np.float64)
        if converged:
            break
        if math.isfinite(stop_above):
            ll, k = _total(ll_in, inlier, log_out, kernel.n_params[int(oriented)], oriented)
            if -2.0 * ll + k * math.log(n) > stop_above:
                break
    assert geom is not None and proj is not None
    ll_in = _inlier_loglik(proj, sp, sr, inlier)
    ll, k = _total(ll_in, inlier, log_out, kernel.n_params[int(oriented)], oriented)
    return ModelFit(
        kernel=kernel,
        geom=geom,
        proj=proj,
        sigma_pos=sp,
        sigma_rot=sr if oriented else math.nan,
        outlier_fraction=float(1.0 - inlier.mean()),
        inlier=inlier,
        weights=w,
        log_likelihood=ll,
        n_params=k,
    )


def _frame_from_axes(x: FloatArray, y_hint: FloatArray) -> FloatArray:
    """Quaternion of a frame whose x axis is ``x`` and whose y axis is nearest ``y_hint``."""
    y = y_hint - (y_hint @ x) * x
    if np.linalg.norm(y) < 1e-9:
        # Any perpendicular: the parent axis least aligned with x.
        y = np.eye(3)[int(np.argmin(np.abs(x)))]
        y = y - (y @ x) * x
    y = y / np.linalg.norm(y)
    z = g.cross3(x, y)
    return se3.quat_from_matrix(np.stack([x, y, z], axis=1))


def _align_x(q: FloatArray, axis: FloatArray) -> FloatArray:
    """Turn orientation ``q`` by the smallest rotation that takes its x axis to ``axis``."""
    x = se3.quat_rotate(q, np.array([1.0, 0.0, 0.0]))
    cos = float(x @ axis)
    if cos < -1.0 + 1e-12:
        turn = np.append(se3.quat_rotate(q, np.array([0.0, 1.0, 0.0])), 0.0)
    else:
        turn = np.append(g.cross3(x, axis), 1.0 + cos)
    return g.quat_mul(turn / np.linalg.norm(turn), q)


def to_constraint(
    fit: ModelFit,
    pos: FloatArray,
    quat: FloatArray | None,
    *,
    confidence: float = 1.0,
    scores: dict[str, float] | None = None,
) -> Constraint:
    """The :class:`Constraint` described by a model fit of a prepared track.

    Latent ranges are measured from the last inlier sample (the constrained pose);
    the axis is turned so that the first inlier lies at a negative configuration.
    """
    geom, proj = fit.geom, fit.proj
    name = fit.kernel.name
    idx = np.flatnonzero(fit.inlier)
    first, last = int(idx[0]), int(idx[-1])
    lat = proj.latent[idx]
    sign = 1.0
    if lat.shape[1] and proj.latent[first, 0] > proj.latent[last, 0]:
        sign = -1.0
    end_lat = proj.latent[last] * sign
    rel = lat * sign - end_lat
    ranges = np.zeros((6, 2))
    axis = None if geom.axis is None else sign * geom.axis
    radius = None
    oriented = quat is not None
    q_end: FloatArray | None = None
    if name in ("fixed", "free"):
        p_end = geom.pos if name == "fixed" else pos[last]
        if oriented:
            assert geom.quat is not None and quat is not None
            q_end = geom.quat if name == "fixed" else quat[last]
        frame_q = q_end if q_end is not None else np.array([0.0, 0.0, 0.0, 1.0])
        frame_p = p_end
        if name == "free":
            local = se3.quat_rotate(g.quat_conj(frame_q), pos[idx] - p_end)
            ranges[:3, 0] = local.min(axis=0)
            ranges[:3, 1] = local.max(axis=0)
            if oriented and quat is not None:
                rv = g.quat_log(g.quat_mul(g.quat_conj(frame_q), quat[idx]))
                ranges[3:, 0] = rv.min(axis=0)
                ranges[3:, 1] = rv.max(axis=0)
            else:
                ranges[3:] = [-math.pi, math.pi]
    elif name == "prismatic":
        assert axis is not None
        p_end = geom.pos + end_lat[0] * axis
        frame_p = p_end
        if oriented:
            assert geom.quat is not None
            q_end = geom.quat
            frame_q = _align_x(q_end, axis)
        else:
            frame_q = _frame_from_axes(axis, np.zeros(3))
        ranges[0] = [rel[:, 0].min(), rel[:, 0].max()]
    else:
        assert axis is not None and geom.lever is not None and geom.axis is not None
        theta_end = proj.latent[last, 0]
        lever_end = g.rotate_about(geom.axis, np.array([theta_end]), geom.lever)[0]
        p_end = geom.pos + lever_end
        if name == "cylindrical":
            p_end = p_end + (proj.latent[last, 1] - geom.lever @ geom.axis) * geom.axis
            ranges[0] = [rel[:, 1].min(), rel[:, 1].max()]
        if name == "screw":
            pitch = geom.extra["pitch"]
            p_end = p_end + (geom.extra["h0"] + pitch * theta_end) * geom.axis
            # Coupled: the translation along the (turned) axis is pitch · angle.
            ranges[0] = np.sort(pitch * np.array([rel[:, 0].min(), rel[:, 0].max()]))
        frame_p = geom.pos + ((p_end - geom.pos) @ axis) * axis
        frame_q = _frame_from_axes(axis, p_end - frame_p)
        radius = float(np.linalg.norm(p_end - frame_p))
        ranges[3] = [rel[:, 0].min(), rel[:, 0].max()]
        if oriented:
            assert geom.quat is not None
            q_end = g.quat_mul(g.quat_axis_angle(geom.axis, np.array([theta_end])), geom.quat)[0]
    w_in = fit.inlier.astype(np.float64)
    rms_pos = math.sqrt(float(w_in @ proj.d2_pos) / w_in.sum())
    rms_rot = None
    if proj.d2_rot is not None:
        rms_rot = math.sqrt(float(w_in @ proj.d2_rot) / w_in.sum())
    if q_end is not None and q_end[3] < 0:
        q_end = -q_end
    if frame_q[3] < 0:
        frame_q = -frame_q
    return Constraint(
        type=name,
        frame_pos=np.asarray(frame_p, dtype=np.float64),
        frame_quat=np.asarray(frame_q, dtype=np.float64),
        axis=axis,
        origin=np.asarray(frame_p, dtype=np.float64),
        pos=np.asarray(p_end, dtype=np.float64),
        quat=q_end,
        ranges=ranges,
        radius=radius,
        pitch=geom.extra.get("pitch") if name == "screw" else None,
        rms_pos=rms_pos,
        rms_rot=rms_rot,
        sigma_pos=fit.sigma_pos,
        sigma_rot=fit.sigma_rot,
        outlier_fraction=fit.outlier_fraction,
        n_samples=int(pos.shape[0]),
        log_likelihood=fit.log_likelihood,
        confidence=confidence,
        scores=dict(scores or {name: fit.bic}),
    )


def _fit_one(
    name: str, pos: ArrayLike, quat: ArrayLike | None, noise: NoiseModel | None
) -> Constraint:
    p, q = prepare_track(pos, quat)
    fit = fit_model(name, p, q, noise=noise)
    if fit is None:
        why = "it needs orientations" if q is None else "the samples are degenerate"
        raise ConstraintFitError(f"track: cannot fit a {name} model: {why}")
    return to_constraint(fit, p, q)


def fit_fixed(
    pos: ArrayLike, quat: ArrayLike | None = None, *, noise: NoiseModel | None = None
) -> Constraint:
    """Fit a fixed (rigid) constraint: robust mean pose.

    Parameters
    ----------
    pos : array_like, shape (n, 3)
        Child positions in the parent frame, metres; NaN rows are dropped.
    quat : array_like, shape (n, 4), optional
        Child orientations in the parent frame, x y z w; None for position-only.
    noise : NoiseModel, optional
        Noise bounds (defaults: 1 mm to 2.5 cm, 0.5° to 6°).

    Returns
    -------
    Constraint
        ``scores`` holds this model's BIC only.
    """
    return _fit_one("fixed", pos, quat, noise)


def fit_prismatic(
    pos: ArrayLike, quat: ArrayLike | None = None, *, noise: NoiseModel | None = None
) -> Constraint:
    """Fit a prismatic constraint: a line of positions at constant orientation.

    Parameters and result as :func:`fit_fixed`; ``axis`` is the line direction,
    ``ranges[0]`` (tx) the observed displacement along it from the final pose.
    """
    return _fit_one("prismatic", pos, quat, noise)


def fit_revolute(
    pos: ArrayLike, quat: ArrayLike | None = None, *, noise: NoiseModel | None = None
) -> Constraint:
    """Fit a revolute constraint: rotation about one axis, positions on a circle.

    Parameters and result as :func:`fit_fixed`; ``axis`` and ``origin`` give the
    joint line, ``ranges[3]`` (rx) the observed angles from the final pose.
    A position-only track needs a finite circle (the points must not be collinear).
    """
    return _fit_one("revolute", pos, quat, noise)


def fit_cylindrical(
    pos: ArrayLike, quat: ArrayLike | None = None, *, noise: NoiseModel | None = None
) -> Constraint:
    """Fit a cylindrical constraint: rotation about and translation along one axis.

    Parameters and result as :func:`fit_fixed`; ``ranges[0]`` (tx) and
    ``ranges[3]`` (rx) are free. Needs orientations.
    """
    return _fit_one("cylindrical", pos, quat, noise)


def fit_screw(
    pos: ArrayLike, quat: ArrayLike | None = None, *, noise: NoiseModel | None = None
) -> Constraint:
    """Fit a screw constraint: rotation about an axis coupled to translation along it.

    Parameters and result as :func:`fit_fixed`; ``pitch`` is the translation per
    radian (metres, along ``axis``), ``ranges[3]`` (rx) the observed angles and
    ``ranges[0]`` (tx) the translation they imply. Needs orientations.
    """
    return _fit_one("screw", pos, quat, noise)


def fit_free(
    pos: ArrayLike, quat: ArrayLike | None = None, *, noise: NoiseModel | None = None
) -> Constraint:
    """Fit the free model: mean pose with a spread at least the noise ceiling.

    Parameters and result as :func:`fit_fixed`; ``ranges`` are the observed
    extents of the motion in the frame of the final pose.
    """
    return _fit_one("free", pos, quat, noise)
