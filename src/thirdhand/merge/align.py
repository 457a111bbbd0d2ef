"""Aligning one recording to a reference: clock offset and drift, rigid world transform.

Model
-----
A sample at time ``t`` (seconds on the other recording's axis) happened at
``t_ref = (1 + drift) * t + offset`` on the reference axis, and a point ``x`` in
the other recording's world frame is ``x_ref = R x + p`` in the reference's. A
body tracked by both systems gives, at simultaneous samples, pairs of positions
of the same physical point (the body's tracked origin is assumed to be the same
point in both systems; the residuals say when it is not).

Estimation
----------
1. **Coarse time** (:func:`estimate_time`): the speed and angular speed of every
   shared body do not depend on the world frame, so the offset is the lag that
   maximises their normalised cross-correlation (gaps masked out) on a uniform
   grid, refined by a parabola through the peak. Over long recordings the lag is
   measured again in windows and a line through those lags gives the drift.
2. **Rigid transform** (:func:`estimate_transform`): RANSAC over minimal sets of
   three simultaneous position pairs (Kabsch), then Kabsch on the inliers with
   the inlier threshold trimmed to a multiple of the median residual, repeated.
3. **Joint refinement**: offset, drift and transform together by least squares
   on the inlier pairs, the reference position linearly interpolated at the
   mapped time; the inliers are chosen again once after it.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.demonstration import Demonstration, _interpolate_track
from thirdhand.errors import ThirdhandError

#: Grid step of the motion signals cross-correlated for the coarse offset, seconds.
GRID_S = 0.005
#: Half width of the centred difference giving speeds on the grid, grid steps.
SPEED_HALF_WIDTH = 4
#: Smallest overlap of two motion signals, as a fraction of the shorter one.
MIN_OVERLAP = 0.3
#: Recordings at least this long get a drift estimate from windowed lags, seconds.
DRIFT_MIN_DURATION_S = 20.0
#: RANSAC iterations and starting inlier threshold (metres).
RANSAC_ITERATIONS = 200
RANSAC_THRESHOLD_M = 0.02
#: Trimmed Kabsch: inliers lie within this many median residuals (and at least the floor).
TRIM_FACTOR = 4.0
TRIM_FLOOR_M = 1e-4
#: Most pairs used by the joint refinement (evenly thinned beyond).
MAX_REFINE_PAIRS = 20000
#: Longest interval between two reference samples a pair may be interpolated across, s.
PAIR_MAX_GAP_S = 0.1
#: Span of the cubic Savitzky-Golay smoother of the clock's last refinement, seconds
#: (see :func:`smooth_track`).
REF_SMOOTH_S = 0.2
#: Smallest fraction of both recordings' shared-body samples the smoother must reach
#: (in evenly spaced runs as long as its window) for that refinement to run.
MIN_SMOOTHED_FRACTION = 0.8


class MergeError(ThirdhandError, ValueError):
    """Recordings cannot be merged (nothing to align them by, no overlap, bad options)."""


@dataclass(frozen=True)
class BodyResidual:
    """Fit residuals of one shared body, inlier pairs only.

    Attributes
    ----------
    body : str
    pairs, inliers : int
        Simultaneous samples paired, and those kept by the robust fit.
    rms_m, median_m, max_m : float
        Position residual ``|R x + p - x_ref(t_ref)|``, metres.
    angle_median_deg : float or None
        Median orientation residual, degrees (None for a position-only body).
    """

    body: str
    pairs: int
    inliers: int
    rms_m: float
    median_m: float
    max_m: float
    angle_median_deg: float | None


@dataclass(frozen=True)
class Alignment:
    """How one recording maps onto the reference.

    Attributes
    ----------
    offset_s : float
        ``t_ref = (1 + drift) * t + offset_s``.
    drift : float
        Clock rate difference, seconds per second (1e-6 = 1 ppm).
    translation : tuple of 3 floats
        ``p`` of ``x_ref = R x + p``, metres.
    rotation : tuple of 4 floats
        ``R`` as a unit quaternion x y z w.
    bodies : tuple of str
        Shared bodies the alignment used.
    time_source, frame_source : str
        ``"motion"`` (estimated from the shared bodies), ``"given"`` (an option)
        or ``"start times"`` (the recordings' absolute start times).
    residuals : tuple of BodyResidual
    smoothed : bool
        The clock's last refinement ran on smoothed tracks of both recordings
        (:func:`smooth_track`; only when both are evenly sampled enough).
    """

    offset_s: float
    drift: float
    translation: tuple[float, float, float]
    rotation: tuple[float, float, float, float]
    bodies: tuple[str, ...] = ()
    time_source: str = "given"
    frame_source: str = "given"
    residuals: tuple[BodyResidual, ...] = field(default_factory=tuple)
    smoothed: bool = False

    def map_time(self, t: FloatArray) -> FloatArray:
        """Times of the other recording on the reference axis, seconds."""
        return (1.0 + self.drift) * np.asarray(t, dtype=np.float64) + self.offset_s

    def map_pose(self, p: FloatArray, q: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Poses of the other recording's world frame in the reference's."""
        return se3.pose_compose(np.asarray(self.translation), np.asarray(self.rotation), p, q)

    @property
    def rotation_deg(self) -> float:
        """Angle of the rotation between the world frames, degrees."""
        w = min(1.0, abs(self.rotation[3]))
        return float(np.degrees(2.0 * np.arccos(w)))


# ---------------------------------------------------------------- time
def _motion_signals(demo: Demonstration, body: str, grid: FloatArray) -> list[FloatArray]:
    """Speed (m/s) and, for oriented bodies, angular speed (rad/s) on ``grid``; NaN in gaps."""
    pos, quat, valid = _interpolate_track(demo.t, demo.track(body), grid, PAIR_MAX_GAP_S)
    k = SPEED_HALF_WIDTH
    h = 2 * k * GRID_S
    out = []
    sp = np.full(grid.size, np.nan)
    ok = np.zeros(grid.size, bool)
    ok[k:-k] = valid[2 * k :] & valid[: -2 * k]
    d = pos[2 * k :] - pos[: -2 * k]
    sp[k:-k] = np.linalg.norm(d, axis=1) / h
    sp[~ok] = np.nan
    out.append(sp)
    if demo.info(body).oriented:
        ang = np.full(grid.size, np.nan)
        a = se3.quat_angle(quat[2 * k :], quat[: -2 * k]) / h
        ang[k:-k] = a
        ang[~ok] = np.nan
        out.append(ang)
    return out


def _xcorr(
    refs: Sequence[FloatArray], others: Sequence[FloatArray], min_overlap: int
) -> tuple[FloatArray, FloatArray]:
    """Normalised masked cross-correlation summed over signal pairs.

    Returns ``(lags, score)``: lag ``k`` (grid steps) pairs ``other[j]`` with
    ``ref[j + k]``; the score is the correlation coefficient over the overlap times
    the square root of the overlap's share of ``min_overlap / MIN_OVERLAP`` samples,
    so that a short overlap that happens to correlate does not beat the whole one.
    """
    from scipy.signal import correlate

    na, nb = refs[0].size, others[0].size
    num = np.zeros(na + nb - 1)
    ea = np.zeros_like(num)
    eb = np.zeros_like(num)
    count = np.zeros_like(num)
    for a, b in zip(refs, others, strict=True):
        ma, mb = np.isfinite(a), np.isfinite(b)
        if ma.sum() < 3 or mb.sum() < 3:
            continue
        a0 = np.where(ma, a - np.nanmean(a), 0.0)
        b0 = np.where(mb, b - np.nanmean(b), 0.0)
        fa, fb = ma.astype(float), mb.astype(float)
        num += correlate(a0, b0, mode="full", method="fft")
        ea += correlate(a0**2, fb, mode="full", method="fft")
        eb += correlate(fa, b0**2, mode="full", method="fft")
        count = np.maximum(count, correlate(fa, fb, mode="full", method="fft"))
    lags = np.arange(-(nb - 1), na, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        r = num / np.sqrt(ea * eb)
    full = max(min_overlap / MIN_OVERLAP, 1.0)
    bad = (count < min_overlap - 0.5) | ~np.isfinite(r)
    r = np.where(bad, 0.0, r) * np.sqrt(np.clip(count / full, 0.0, 1.0))
    r[bad] = -np.inf
    return lags, r


def _peak(lags: FloatArray, r: FloatArray) -> tuple[float, float]:
    """Lag of the largest correlation, refined by a parabola; and that correlation."""
    i = int(np.argmax(r))
    if not np.isfinite(r[i]):
        return float("nan"), float("-inf")
    frac = 0.0
    if 0 < i < r.size - 1 and np.isfinite(r[i - 1]) and np.isfinite(r[i + 1]):
        den = r[i - 1] - 2 * r[i] + r[i + 1]
        if den < 0:
            frac = 0.5 * (r[i - 1] - r[i + 1]) / den
    return float(lags[i] + frac), float(r[i])


def estimate_time(
    ref: Demonstration, other: Demonstration, bodies: Sequence[str]
) -> tuple[float, float, float]:
    """Coarse clock mapping from the motion of shared bodies.

    Returns
    -------
    offset : float
        Seconds, ``t_ref ≈ (1 + drift) t + offset``.
    drift : float
        Seconds per second (0 for recordings shorter than
        :data:`DRIFT_MIN_DURATION_S`).
    peak : float
        Normalised correlation at the peak (1 for identical motion).

    Raises
    ------
    MergeError
        When the shared bodies never move while tracked by both.
    """
    ga = ref.t[0] + np.arange(int(ref.duration / GRID_S) + 1) * GRID_S
    gb = other.t[0] + np.arange(int(other.duration / GRID_S) + 1) * GRID_S
    sa: list[FloatArray] = []
    sb: list[FloatArray] = []
    for body in bodies:
        a, b = _motion_signals(ref, body, ga), _motion_signals(other, body, gb)
        n = min(len(a), len(b))
        sa += a[:n]
        sb += b[:n]
    shorter = min(
        max(int(np.isfinite(s).sum()) for s in sa), max(int(np.isfinite(s).sum()) for s in sb)
    )
    lags, r = _xcorr(sa, sb, max(10, int(MIN_OVERLAP * shorter)))
    lag, peak = _peak(lags, r)
    if not np.isfinite(lag):
        raise MergeError(
            f"the shared bod{'y' if len(bodies) == 1 else 'ies'} {', '.join(bodies)} "
            "overlap too little in time to estimate the clock offset; give --offset"
        )
    offset = float(ga[0] - gb[0] + lag * GRID_S)
    drift = 0.0
    if other.duration >= DRIFT_MIN_DURATION_S:
        drift, offset = _windowed_drift(sa, sb, ga, gb, lag, offset)
    return offset, drift, peak


def _windowed_drift(
    sa: list[FloatArray],
    sb: list[FloatArray],
    ga: FloatArray,
    gb: FloatArray,
    lag: float,
    offset: float,
    n_windows: int = 4,
) -> tuple[float, float]:
    """Drift and offset from the lags of ``n_windows`` windows of the other recording."""
    edges = np.linspace(0, gb.size, n_windows + 1).astype(int)
    centres, offsets, weights = [], [], []
    search = round(2.0 / GRID_S)  # windows look within ±2 s of the global lag
    for lo, hi in itertools.pairwise(edges):
        # The reference segment this window can reach.
        a_lo = max(0, lo + int(np.floor(lag)) - search)
        a_hi = min(ga.size, hi + int(np.ceil(lag)) + search)
        if a_hi - a_lo < hi - lo:
            continue
        wa = [s[a_lo:a_hi] for s in sa]
        wb = [s[lo:hi] for s in sb]
        n_valid = max(int(np.isfinite(s).sum()) for s in wb)
        if n_valid < 0.5 * (hi - lo):
            continue
        lags, r = _xcorr(wa, wb, int(0.8 * n_valid))
        k, peak = _peak(lags, r)
        if not np.isfinite(k) or peak < 0.5:
            continue
        centres.append(gb[lo])
        offsets.append(ga[a_lo] - gb[lo] + k * GRID_S)
        weights.append(peak)
    if len(centres) < 3:
        return 0.0, offset
    # offset(t) = offset + drift * t, measured at each window's start.
    slope, intercept = np.polyfit(centres, offsets, 1, w=weights)
    return float(slope), float(intercept)


# ---------------------------------------------------------------- pairs
@dataclass
class _Pairs:
    """Simultaneous samples of the shared bodies: the other's time and poses, the reference's."""

    body: NDArray[np.int64]
    t: FloatArray
    x: FloatArray
    q: FloatArray
    x_ref: FloatArray
    q_ref: FloatArray
    oriented: NDArray[np.bool_]


def _pairs(
    ref: Demonstration,
    other: Demonstration,
    bodies: Sequence[str],
    offset: float,
    drift: float,
) -> _Pairs:
    cols: list[list[FloatArray]] = [[] for _ in range(6)]
    idx, ori = [], []
    for i, body in enumerate(bodies):
        v = other.valid(body)
        t = other.t[v]
        tau = (1.0 + drift) * t + offset
        p_ref, q_ref, ok = _interpolate_track(ref.t, ref.track(body), tau, PAIR_MAX_GAP_S)
        both = ref.info(body).oriented and other.info(body).oriented
        for c, arr in zip(
            cols,
            (t[ok], other.pos(body)[v][ok], other.quat(body)[v][ok], p_ref[ok], q_ref[ok]),
            strict=False,
        ):
            c.append(arr)
        idx.append(np.full(int(ok.sum()), i, dtype=np.int64))
        ori.append(np.full(int(ok.sum()), both))
    return _Pairs(
        body=np.concatenate(idx),
        t=np.concatenate(cols[0]),
        x=np.concatenate(cols[1]).reshape(-1, 3),
        q=np.concatenate(cols[2]).reshape(-1, 4),
        x_ref=np.concatenate(cols[3]).reshape(-1, 3),
        q_ref=np.concatenate(cols[4]).reshape(-1, 4),
        oriented=np.concatenate(ori),
    )


def _kabsch(x: FloatArray, y: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``R`` (quaternion) and ``p`` minimising ``Σ |R x + p − y|²``."""
    p, q, _ = se3.kabsch(x, y[None])
    return p[0], q[0]


def _residual(x: FloatArray, y: FloatArray, p: FloatArray, q: FloatArray) -> FloatArray:
    return np.asarray(np.linalg.norm(se3.quat_rotate(q, x) + p - y, axis=1))


def estimate_transform(
    x: FloatArray, y: FloatArray, *, seed: int = 0
) -> tuple[FloatArray, FloatArray, NDArray[np.bool_]]:
    """Robust rigid transform ``y ≈ R x + p`` from paired points (RANSAC, trimmed Kabsch).

    Parameters
    ----------
    x, y : ndarray, shape (m, 3)
        Paired positions, metres: the other recording's and the reference's.
    seed : int
        Seed of the RANSAC draws.

    Returns
    -------
    p : ndarray, shape (3,)
    q : ndarray, shape (4,), x y z w
    inliers : ndarray of bool, shape (m,)

    Raises
    ------
    MergeError
        Fewer than 3 pairs, or points that do not span a plane.
    """
    m = x.shape[0]
    if m < 3:
        raise MergeError(f"only {m} simultaneous samples of the shared bodies; at least 3 needed")
    spread = np.linalg.svd(x - x.mean(axis=0), compute_uv=False)
    if spread[1] < 1e-6 * max(1.0, spread[0]):
        raise MergeError(
            "the shared bodies move along a line only: the rotation between the world frames "
            "is not determined; give --transform"
        )
    rng = np.random.default_rng(seed)
    best = np.ones(m, bool)
    best_count = -1
    for _ in range(RANSAC_ITERATIONS if m > 3 else 1):
        s = rng.choice(m, size=3, replace=False)
        xs = x[s]
        if np.linalg.norm(np.cross(xs[1] - xs[0], xs[2] - xs[0])) < 1e-8:
            continue
        p, q = _kabsch(xs, y[s])
        inl = _residual(x, y, p, q) < RANSAC_THRESHOLD_M
        if inl.sum() > best_count:
            best, best_count = inl, int(inl.sum())
    inl = best if best_count >= 3 else np.ones(m, bool)
    p, q = _kabsch(x[inl], y[inl])
    for _ in range(10):
        r = _residual(x, y, p, q)
        thr = max(TRIM_FACTOR * float(np.median(r[inl])), TRIM_FLOOR_M)
        new = r < thr
        if new.sum() < 3 or np.array_equal(new, inl):
            break
        inl = new
        p, q = _kabsch(x[inl], y[inl])
    return p, q, inl


# ---------------------------------------------------------------- refinement
def smooth_track(
    t: FloatArray, pos: FloatArray, span_s: float = REF_SMOOTH_S
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Positions smoothed by a cubic Savitzky-Golay filter over ``span_s``, run by run.

    The joint refinement differentiates the reference's interpolated positions
    with respect to time; between raw samples that derivative is the difference
    of two noisy samples, which at 2 mm of noise and 0.1 m/s swamps the motion
    (the clock offset then erred by 3–5 ms). A cubic fit over 0.2 s keeps human
    motion (its pass band reaches about 6 Hz) and leaves noise-free tracks as
    they were to micrometres. Runs are split at gaps longer than
    :data:`PAIR_MAX_GAP_S`; a run shorter than the window is left raw.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Sample times of the tracked samples, seconds, increasing.
    pos : ndarray, shape (n, 3)
        Positions at those times, metres.
    span_s : float
        Window span, seconds.

    Returns
    -------
    smoothed : ndarray, shape (n, 3)
    done : ndarray of bool, shape (n,)
        The samples the filter reached (the others are returned raw).
    """
    from scipy.signal import savgol_filter

    out = np.array(pos, dtype=np.float64, copy=True)
    done = np.zeros(t.size, dtype=bool)
    if t.size < 5:
        return out, done
    dt = np.diff(t)
    step = float(np.median(dt))
    # the filter assumes even spacing: a missing sample ends a run
    cuts = np.flatnonzero(dt > 1.5 * step) + 1
    window = max(5, round(span_s / step) | 1)
    for a, b in zip(np.r_[0, cuts], np.r_[cuts, t.size], strict=True):
        if b - a >= window:
            out[a:b] = savgol_filter(out[a:b], window, 3, axis=0)
            done[a:b] = True
    return out, done


def _smoothed(
    demo: Demonstration, bodies: Sequence[str], drop_t: dict[str, FloatArray]
) -> tuple[Demonstration, float]:
    """The bodies with smoothed positions (``drop_t`` untracked), and the fraction smoothed."""
    tracks = {}
    reached, total = 0, 0
    for body in bodies:
        v = demo.valid(body) & ~np.isin(demo.t, drop_t.get(body, np.zeros(0)))
        pos = np.full_like(demo.pos(body), np.nan)
        pos[v], done = smooth_track(demo.t[v], demo.pos(body)[v])
        reached += int(done.sum())
        total += int(v.sum())
        tracks[body] = (pos, demo.quat(body), v)
    return demo.select(list(bodies)).replace(tracks=tracks), reached / max(total, 1)


def _refine(
    ref: Demonstration,
    bodies: Sequence[str],
    pairs: _Pairs,
    inl: NDArray[np.bool_],
    start: tuple[float, float, FloatArray, FloatArray],
    *,
    fit_time: bool,
    fit_frame: bool,
    fit_drift: bool = True,
) -> tuple[float, float, FloatArray, FloatArray]:
    """Least squares over offset, drift and transform on the inlier pairs."""
    from scipy.optimize import least_squares

    offset0, drift0, p0, q0 = start
    sel = np.flatnonzero(inl)
    if sel.size > MAX_REFINE_PAIRS:
        sel = sel[np.linspace(0, sel.size - 1, MAX_REFINE_PAIRS).astype(int)]
    t, x, b = pairs.t[sel], pairs.x[sel], pairs.body[sel]
    tracks = []
    for body in bodies:
        v = ref.valid(body)
        tracks.append((ref.t[v], ref.pos(body)[v]))
    t_scale = max(float(np.ptp(t)), 1.0)

    def ref_at(tau: FloatArray) -> FloatArray:
        out = np.empty((tau.size, 3))
        for i, (ts, ps) in enumerate(tracks):
            m = b == i
            for k in range(3):
                out[m, k] = np.interp(tau[m], ts, ps[:, k])
        return out

    def unpack(theta: FloatArray) -> tuple[float, float, FloatArray, FloatArray]:
        off, dr = offset0, drift0
        p, q = p0, q0
        j = 0
        if fit_time:
            off = float(theta[0])
            j = 1
            if fit_drift:
                dr = float(theta[1]) / t_scale
                j = 2
        if fit_frame:
            q = se3.quat_from_rotvec(theta[j : j + 3])
            p = theta[j + 3 : j + 6]
        return off, dr, p, q

    def fun(theta: FloatArray) -> FloatArray:
        off, dr, p, q = unpack(theta)
        pred = se3.quat_rotate(q, x) + p
        return np.asarray((pred - ref_at((1.0 + dr) * t + off)).ravel())

    theta0: list[float] = []
    if fit_time:
        theta0 += [offset0, drift0 * t_scale] if fit_drift else [offset0]
    if fit_frame:
        theta0 += [*se3.rotvec_from_quat(q0), *p0]
    if not theta0:
        return start
    sol = least_squares(fun, np.asarray(theta0), method="lm", xtol=1e-14, ftol=1e-14)
    off, dr, p, q = unpack(sol.x)
    return off, dr, np.asarray(p, float), np.asarray(q, float)


def _residuals(
    bodies: Sequence[str], pairs: _Pairs, inl: NDArray[np.bool_], p: FloatArray, q: FloatArray
) -> tuple[BodyResidual, ...]:
    r = _residual(pairs.x, pairs.x_ref, p, q)
    q_pred = se3.quat_multiply(q, pairs.q)
    ang = np.degrees(se3.quat_angle(q_pred, pairs.q_ref))
    out = []
    for i, body in enumerate(bodies):
        m = pairs.body == i
        mi = m & inl
        ri = r[mi]
        oriented = bool(pairs.oriented[m].any())
        out.append(
            BodyResidual(
                body=body,
                pairs=int(m.sum()),
                inliers=int(mi.sum()),
                rms_m=float(np.sqrt(np.mean(ri**2))) if ri.size else float("nan"),
                median_m=float(np.median(ri)) if ri.size else float("nan"),
                max_m=float(ri.max()) if ri.size else float("nan"),
                angle_median_deg=float(np.median(ang[mi])) if oriented and ri.size else None,
            )
        )
    return tuple(out)


def align(
    ref: Demonstration,
    other: Demonstration,
    bodies: Sequence[str],
    *,
    offset: float | None = None,
    drift: float | None = None,
    transform: tuple[Sequence[float], Sequence[float]] | None = None,
    fit_drift: bool = True,
    smooth: bool = False,
    seed: int = 0,
) -> Alignment:
    """Align ``other`` to ``ref`` (see the module documentation).

    Parameters
    ----------
    ref, other : Demonstration
    bodies : sequence of str
        Bodies tracked by both (same names in both). May be empty when both
        ``offset`` and ``transform`` are given.
    offset, drift : float, optional
        A known clock mapping (drift defaults to 0 when only ``offset`` is given);
        else estimated from the motion of ``bodies``.
    transform : (p, q), optional
        A known world transform ``x_ref = R(q) x + p`` (p in metres, q x y z w);
        else estimated from ``bodies``.
    fit_drift : bool
        Estimate a drift; False keeps it 0.
    smooth : bool
        Refine the clock once more on smoothed tracks of both recordings
        (:func:`smooth_track`), when the filter reaches most samples of both. It
        helps when noise exceeds the motion between samples (2 mm at 0.1 m/s:
        offset error 2.8 → 0.28 ms) and costs where the tracks are jerky and
        gappy (the IKEA AR-tag copies: 0.18 → 1.3 ms), hence off by default.
    seed : int
        Seed of the RANSAC draws.

    Raises
    ------
    MergeError
        Nothing to align by, too little overlap, degenerate motion.
    """
    time_source = "given" if offset is not None else "motion"
    frame_source = "given" if transform is not None else "motion"
    if not bodies:
        if transform is None:
            raise MergeError("no shared body and no transform given")
        if offset is None:
            raise MergeError("no shared body to estimate the clock offset from; give --offset")
        return Alignment(
            offset_s=float(offset),
            drift=float(drift or 0.0),
            translation=_tuple3(transform[0]),
            rotation=_tuple4(se3.check_quat(np.asarray(transform[1], float))),
        )
    if offset is None:
        off, dr, _ = estimate_time(ref, other, bodies)
        if not fit_drift:
            dr = 0.0
    else:
        off, dr = float(offset), float(drift or 0.0)
    pairs = _pairs(ref, other, bodies, off, dr)
    p: FloatArray
    q: FloatArray
    if transform is None:
        p, q, inl = estimate_transform(pairs.x, pairs.x_ref, seed=seed)
    else:
        p = np.asarray(transform[0], float)
        q = se3.check_quat(np.asarray(transform[1], float))
        inl = np.ones(pairs.t.size, bool)
        if pairs.t.size < 3:
            raise MergeError(f"only {pairs.t.size} simultaneous samples of the shared bodies")
    fit_time = offset is None
    fixed_frame = transform is not None
    state = (off, dr, p, q)

    def refine_on(
        fit_ref: Demonstration, fit_pairs: _Pairs, fit_inl: NDArray[np.bool_]
    ) -> tuple[_Pairs, NDArray[np.bool_]]:
        """Refine ``state`` on these tracks; the raw pairs and inliers at the result."""
        nonlocal state
        state = _refine(
            fit_ref,
            bodies,
            fit_pairs,
            fit_inl,
            state,
            fit_time=fit_time,
            fit_frame=not fixed_frame,
            fit_drift=fit_drift,
        )
        raw = _pairs(ref, other, bodies, state[0], state[1])
        return raw, _trim(raw, state, keep_all=fixed_frame)

    for _ in range(2):
        pairs, inl = refine_on(ref, pairs, inl)
    smoothed = False
    if fit_time and smooth:
        # A last refinement on smoothed tracks of both recordings (the same filter on
        # each, the other's outlier samples dropped first): the clock is fitted to
        # the motion's time derivative, which raw noisy samples swamp. Only when the
        # filter reaches most samples of both: smoothing one side and not the other
        # (a gappy tracker's short runs stay raw) biases the fit instead.
        drop = {b: pairs.t[(pairs.body == i) & ~inl] for i, b in enumerate(bodies)}
        ref_s, f_ref = _smoothed(ref, bodies, {})
        other_s, f_other = _smoothed(other, bodies, drop)
        smoothed = min(f_ref, f_other) >= MIN_SMOOTHED_FRACTION
        if smoothed:
            pairs_s = _pairs(ref_s, other_s, bodies, state[0], state[1])
            pairs, inl = refine_on(ref_s, pairs_s, _trim(pairs_s, state, keep_all=False))
    off, dr, p, q = state
    return Alignment(
        offset_s=off,
        drift=dr,
        translation=_tuple3(p),
        rotation=_tuple4(q if q[3] >= 0 else -q),
        bodies=tuple(bodies),
        time_source=time_source,
        frame_source=frame_source,
        residuals=_residuals(bodies, pairs, inl, p, q),
        smoothed=smoothed,
    )


def _trim(
    pairs: _Pairs, state: tuple[float, float, FloatArray, FloatArray], *, keep_all: bool
) -> NDArray[np.bool_]:
    """Inlier pairs: within :data:`TRIM_FACTOR` median residuals (all of them: ``keep_all``)."""
    r = _residual(pairs.x, pairs.x_ref, state[2], state[3])
    if keep_all:
        return np.ones(r.size, bool)
    return np.asarray(r < max(TRIM_FACTOR * float(np.median(r)), TRIM_FLOOR_M))


def _tuple3(v: Sequence[float] | FloatArray) -> tuple[float, float, float]:
    a = [float(x) for x in v]
    return (a[0], a[1], a[2])


def _tuple4(v: Sequence[float] | FloatArray) -> tuple[float, float, float, float]:
    a = [float(x) for x in v]
    return (a[0], a[1], a[2], a[3])
