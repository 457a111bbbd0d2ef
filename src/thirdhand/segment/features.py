"""State features of the pair-wise interaction CRF: windowed pose variances.

The latent time axis
--------------------
A recording of frames at times ``t`` (seconds) is cut into latent steps of
``1 / latent_rate`` seconds: step ``k`` holds the frames with
``t0 + k / r <= t < t0 + (k + 1) / r``. Its time stamp is the step's centre.

Windows
-------
The window length ``window`` is counted in **latent steps** and is centred on
the step: for step ``k`` the window is the union of the steps
``k - window // 2 … k - window // 2 + window - 1`` (clipped to the recording).
The report's windows look backwards; a centred window removes the half-window
lag that a causal one puts on every detected boundary.

Numerics
--------
Statistics are accumulated per latent step with a *local* reference (the
step's first valid sample is subtracted before summing), so a coordinate of
1.5 m that moves by a micrometre keeps its precision, and per-step statistics
are merged over the window with Chan's parallel update (exact, no cancellation).
Variances are clamped at zero.

Missing data
------------
Only valid samples enter the statistics; each step reports how many valid
samples its window held. A window with fewer than ``min_valid`` samples (a
fraction of its nominal frame count) gives *no evidence*: its state features
are all zero, hence a zero state potential for both labels, and the chain's
transition potentials alone carry the label across a short gap.

Features (before transform), for a pair (A, B) and step ``t``
-------------------------------------------------------------
1. ``ν_π(A) + ν_π(B)``: windowed variance of each body's world position, m²
   (the trace of the covariance: ``ω⁻¹ Σ ||p − mean||²``);
2. ``ν_ρ(A) + ν_ρ(B)``: same for the sign-continuous quaternions (unitless);
3. ``ζ_π(A, B)``: windowed variance of B's position in A's frame,
   ``δ_π = R_A⁻¹ (p_B − p_A)``, m²;
4. ``ζ_ρ(A, B)``: windowed variance of B's orientation in A's frame,
   ``δ_ρ = q_A⁻¹ q_B``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

from thirdhand.arrays import BoolArray, FloatArray, IntArray
from thirdhand.errors import ThirdhandError
from thirdhand.se3_compiled import continuous_quat_rows, relative_pose_rows

#: Names of the four core features, in column order.
RAW_FEATURE_NAMES: tuple[str, ...] = ("nu_pos", "nu_rot", "zeta_pos", "zeta_rot")


class SegmentationError(ThirdhandError, ValueError):
    """Bad input to interaction segmentation (a missing body, too short a recording...)."""


@dataclass(frozen=True)
class LatentAxis:
    """The latent time axis of a recording.

    Attributes
    ----------
    t0 : float
        Start of the first step, seconds (the first frame's time).
    rate : float
        Latent steps per second, Hz.
    n_steps : int
    frame_step : ndarray of int, shape (n_frames,)
        Latent step of every frame.
    frames_per_step : float
        Nominal frames per step (median frame rate / latent rate).
    """

    t0: float
    rate: float
    n_steps: int
    frame_step: IntArray
    frames_per_step: float

    @property
    def times(self) -> FloatArray:
        """Centre of every step, seconds, shape (n_steps,)."""
        return self.t0 + (np.arange(self.n_steps, dtype=np.float64) + 0.5) / self.rate

    @property
    def edges(self) -> FloatArray:
        """Step boundaries, seconds, shape (n_steps + 1,)."""
        return self.t0 + np.arange(self.n_steps + 1, dtype=np.float64) / self.rate


def latent_axis(t: NDArray[np.float64], rate: float) -> LatentAxis:
    """Cut a frame time axis into latent steps.

    Parameters
    ----------
    t : ndarray, shape (n_frames,), seconds, strictly increasing
    rate : float
        Latent steps per second, Hz.
    """
    if not np.isfinite(rate) or rate <= 0:
        raise SegmentationError(f"latent rate must be positive, got {rate} Hz")
    t = np.asarray(t, dtype=np.float64)
    if t.size < 2:
        raise SegmentationError(
            f"a recording of {t.size} frame(s) is too short to segment: need at least 2"
        )
    t0 = float(t[0])
    k = np.floor((t - t0) * rate + 1e-9).astype(np.int64)
    n_steps = int(k[-1]) + 1
    fps = float(1.0 / np.median(np.diff(t))) / rate
    return LatentAxis(t0=t0, rate=float(rate), n_steps=n_steps, frame_step=k, frames_per_step=fps)


# ------------------------------------------------------------------ kernels
@numba.njit(cache=True, nogil=True)
def _block_stats(  # pragma: no cover - compiled
    x: FloatArray, valid: BoolArray, step: IntArray, n_steps: int
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Per-step count, mean and sum of squared deviations (summed over columns)."""
    n, d = x.shape
    cnt = np.zeros(n_steps)
    mean = np.zeros((n_steps, d))
    m2 = np.zeros(n_steps)
    s1 = np.zeros(d)
    ref = np.zeros(d)
    s2 = 0.0
    cur = -1
    c = 0.0
    for i in range(n + 1):
        k = step[i] if i < n else -2
        if k != cur:
            if cur >= 0 and c > 0:
                cnt[cur] = c
                acc = 0.0
                for j in range(d):
                    mu = s1[j] / c
                    mean[cur, j] = ref[j] + mu
                    acc += mu * mu
                m2[cur] = max(s2 - c * acc, 0.0)
            cur = k
            c = 0.0
            s2 = 0.0
            for j in range(d):
                s1[j] = 0.0
        if i == n:
            break
        if not valid[i]:
            continue
        if c == 0.0:
            for j in range(d):
                ref[j] = x[i, j]
        for j in range(d):
            dx = x[i, j] - ref[j]
            s1[j] += dx
            s2 += dx * dx
        c += 1.0
    return cnt, mean, m2


@numba.njit(cache=True, nogil=True)
def _merge_buckets(  # pragma: no cover - compiled
    cnt: FloatArray, mean: FloatArray, m2: FloatArray, lo: int, hi: int, mu: FloatArray
) -> tuple[float, float]:
    """Chan's pairwise merge of latent buckets ``lo … hi − 1`` (empty buckets skipped).

    Returns the merged sample count and sum of squared deviations; the merged
    mean is written into ``mu`` (shape (d,)).
    """
    d = mean.shape[1]
    n = 0.0
    m = 0.0
    for b in range(lo, hi):
        nb = cnt[b]
        if nb == 0.0:
            continue
        if n == 0.0:
            for j in range(d):
                mu[j] = mean[b, j]
            m = m2[b]
            n = nb
            continue
        tot = n + nb
        f = n * nb / tot
        dd = 0.0
        for j in range(d):
            delta = mean[b, j] - mu[j]
            dd += delta * delta
            mu[j] += delta * nb / tot
        m += m2[b] + dd * f
        n = tot
    return n, m


@numba.njit(cache=True, nogil=True)
def _window_merge(  # pragma: no cover - compiled
    cnt: FloatArray, mean: FloatArray, m2: FloatArray, window: int
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Merge per-step statistics over centred windows (Chan et al.).

    Returns the per-step window variance (trace of the covariance), sample count
    and mean (zero where the window is empty).
    """
    k_steps, d = mean.shape
    var = np.zeros(k_steps)
    n_out = np.zeros(k_steps)
    mean_out = np.zeros((k_steps, d))
    mu = np.zeros(d)
    half = window // 2
    for k in range(k_steps):
        n, m = _merge_buckets(cnt, mean, m2, max(k - half, 0), min(k - half + window, k_steps), mu)
        n_out[k] = n
        if n > 0.0:
            var[k] = max(m / n, 0.0)
            for j in range(d):
                mean_out[k, j] = mu[j]
    return var, n_out, mean_out


@numba.njit(cache=True, nogil=True)
def _double_window(  # pragma: no cover - compiled
    cnt: FloatArray,
    mean: FloatArray,
    m2: FloatArray,
    var_s: FloatArray,
    n_s: FloatArray,
    mean_s: FloatArray,
    window: int,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Centred windows of ``2 window`` steps from those of ``window`` steps.

    Window ``k`` of length ``2w`` (steps ``k − w … k + w − 1``) is the union of
    the short windows centred at ``k − w + w // 2`` and ``k + w // 2``: one Chan
    merge per step instead of ``2w``. Near the ends, where a short window is
    clipped, the steps are merged directly (as :func:`_window_merge`).
    """
    k_steps, d = mean.shape
    var = np.zeros(k_steps)
    n_out = np.zeros(k_steps)
    mean_out = np.zeros((k_steps, d))
    mu = np.zeros(d)
    w = window
    for k in range(k_steps):
        if k - w >= 0 and k + w - 1 < k_steps:
            a = k - w + w // 2
            b = k + w // 2
            na, nb = n_s[a], n_s[b]
            tot = na + nb
            n_out[k] = tot
            if tot == 0.0:
                continue
            if na == 0.0 or nb == 0.0:
                src = a if na > 0.0 else b
                var[k] = var_s[src]
                for j in range(d):
                    mean_out[k, j] = mean_s[src, j]
                continue
            dd = 0.0
            for j in range(d):
                delta = mean_s[b, j] - mean_s[a, j]
                dd += delta * delta
                mean_out[k, j] = mean_s[a, j] + delta * nb / tot
            m = var_s[a] * na + var_s[b] * nb + dd * na * nb / tot
            var[k] = max(m / tot, 0.0)
            continue
        n, m = _merge_buckets(cnt, mean, m2, max(k - w, 0), min(k + w, k_steps), mu)
        n_out[k] = n
        if n > 0.0:
            var[k] = max(m / n, 0.0)
            for j in range(d):
                mean_out[k, j] = mu[j]
    return var, n_out, mean_out


# ------------------------------------------------------------------ public
def windowed_variance(
    x: FloatArray, valid: BoolArray, axis: LatentAxis, window: int
) -> tuple[FloatArray, FloatArray]:
    """Windowed variance of a multi-dimensional signal over the latent axis.

    Parameters
    ----------
    x : ndarray, shape (n_frames, d)
        Signal; rows where ``valid`` is False are ignored (may be NaN).
    valid : ndarray of bool, shape (n_frames,)
    axis : LatentAxis
    window : int
        Window length in latent steps, centred.

    Returns
    -------
    var : ndarray, shape (n_steps,)
        ``n⁻¹ Σ ||x − mean||²`` over the window's valid samples (0 where none).
    count : ndarray, shape (n_steps,)
        Number of valid samples in the window.
    """
    var, count, _ = windowed_moments(x, valid, axis, window)
    return var, count


def windowed_moments(
    x: FloatArray, valid: BoolArray, axis: LatentAxis, window: int
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """As :func:`windowed_variance`, also returning the window mean, shape (n_steps, d)."""
    if window < 1:
        raise SegmentationError(f"window must be at least 1 latent step, got {window}")
    xv = np.ascontiguousarray(x, dtype=np.float64)
    vb = np.ascontiguousarray(valid, dtype=np.bool_)
    cnt, mean, m2 = _block_stats(xv, vb, axis.frame_step, axis.n_steps)
    return _window_merge(cnt, mean, m2, int(window))


@dataclass(frozen=True)
class BodyStats:
    """Windowed variances of one body on a latent axis.

    Attributes
    ----------
    var_pos : ndarray, shape (n_steps,), m²
    var_rot : ndarray, shape (n_steps,), unitless (quaternion components)
    count : ndarray, shape (n_steps,)
        Valid samples per window.
    distance : ndarray, shape (n_steps,), metres, or None
        For a pair: window mean of the distance between the two origins.
    mean_pos : ndarray, shape (n_steps, 3), metres, or None
        For a pair: window mean of B's position in A's frame (zero where no sample).
    mean_quat : ndarray, shape (n_steps, 4), x y z w, or None
        For a pair: window mean of B's sign-continuous quaternion in A's frame,
        not normalised (zero where no sample).
    """

    var_pos: FloatArray
    var_rot: FloatArray
    count: FloatArray
    distance: FloatArray | None = None
    mean_pos: FloatArray | None = None
    mean_quat: FloatArray | None = None


def _moments_multi(
    x: FloatArray, valid: BoolArray, axis: LatentAxis, windows: tuple[int, ...]
) -> list[tuple[FloatArray, FloatArray, FloatArray]]:
    """:func:`windowed_moments` for several windows, accumulating the steps once."""
    for w in windows:
        if w < 1:
            raise SegmentationError(f"window must be at least 1 latent step, got {w}")
    xv = np.ascontiguousarray(x, dtype=np.float64)
    vb = np.ascontiguousarray(valid, dtype=np.bool_)
    cnt, mean, m2 = _block_stats(xv, vb, axis.frame_step, axis.n_steps)
    out: list[tuple[FloatArray, FloatArray, FloatArray]] = []
    for w in windows:
        half = [o for o, v in zip(windows, out, strict=False) if 2 * o == w]
        if half:  # a window twice as long as one already done: one merge per step
            short = out[windows.index(half[0])]
            out.append(_double_window(cnt, mean, m2, *short, int(half[0])))
        else:
            out.append(_window_merge(cnt, mean, m2, int(w)))
    return out


def body_stats_multi(
    pos: FloatArray,
    quat: FloatArray,
    valid: BoolArray,
    axis: LatentAxis,
    windows: tuple[int, ...],
) -> list[BodyStats]:
    """:func:`body_stats` for several windows (latent steps), one per window."""
    v = np.asarray(valid, dtype=np.bool_)
    q = continuous_quat_rows(np.where(v[:, None], quat, 0.0).astype(np.float64), v)
    mp = _moments_multi(np.asarray(pos, np.float64), v, axis, windows)
    mr = _moments_multi(q, v, axis, windows)
    return [BodyStats(var_pos=p[0], var_rot=r[0], count=p[1]) for p, r in zip(mp, mr, strict=True)]


def pair_stats_multi(
    a: tuple[FloatArray, FloatArray, BoolArray],
    b: tuple[FloatArray, FloatArray, BoolArray],
    axis: LatentAxis,
    windows: tuple[int, ...],
    *,
    distance: bool = True,
) -> list[BodyStats]:
    """:func:`pair_stats` for several windows (latent steps): the relative pose once.

    ``distance=False`` skips the window-mean distance (``BodyStats.distance`` None).
    """
    v = np.asarray(a[2], dtype=np.bool_) & np.asarray(b[2], dtype=np.bool_)
    dp, dq = relative_pose_rows(
        np.asarray(a[0], np.float64),
        np.asarray(a[1], np.float64),
        np.asarray(b[0], np.float64),
        np.asarray(b[1], np.float64),
        v,
    )
    mp = _moments_multi(dp, v, axis, windows)
    mr = _moments_multi(dq, v, axis, windows)
    if not distance:
        return [
            BodyStats(var_pos=p[0], var_rot=r[0], count=p[1], mean_pos=p[2], mean_quat=r[2])
            for p, r in zip(mp, mr, strict=True)
        ]
    dist = np.sqrt(np.einsum("ij,ij->i", dp, dp))[:, None]
    md = _moments_multi(dist, v, axis, windows)
    return [
        BodyStats(
            var_pos=p[0],
            var_rot=r[0],
            count=p[1],
            distance=d[2][:, 0],
            mean_pos=p[2],
            mean_quat=r[2],
        )
        for p, r, d in zip(mp, mr, md, strict=True)
    ]


def body_stats(
    pos: FloatArray, quat: FloatArray, valid: BoolArray, axis: LatentAxis, window: int
) -> BodyStats:
    """Windowed position and orientation variances of one body (ν_π, ν_ρ).

    Parameters
    ----------
    pos : ndarray, shape (n_frames, 3), metres, world frame
    quat : ndarray, shape (n_frames, 4), x y z w
    valid : ndarray of bool, shape (n_frames,)
    axis : LatentAxis
    window : int
        Latent steps, centred.
    """
    v = np.asarray(valid, dtype=np.bool_)
    q = continuous_quat_rows(np.where(v[:, None], quat, 0.0).astype(np.float64), v)
    vp, n = windowed_variance(np.asarray(pos, np.float64), v, axis, window)
    vr, _ = windowed_variance(q, v, axis, window)
    return BodyStats(var_pos=vp, var_rot=vr, count=n)


def pair_stats(
    a: tuple[FloatArray, FloatArray, BoolArray],
    b: tuple[FloatArray, FloatArray, BoolArray],
    axis: LatentAxis,
    window: int,
) -> BodyStats:
    """Windowed variances of B's pose in A's frame (ζ_π, ζ_ρ).

    Parameters
    ----------
    a, b : tuple (pos (n_frames, 3) metres world frame, quat (n_frames, 4) x y z w,
        valid (n_frames,) bool)
    axis : LatentAxis
    window : int
        Latent steps, centred.
    """
    v = np.asarray(a[2], dtype=np.bool_) & np.asarray(b[2], dtype=np.bool_)
    dp, dq = relative_pose_rows(
        np.asarray(a[0], np.float64),
        np.asarray(a[1], np.float64),
        np.asarray(b[0], np.float64),
        np.asarray(b[1], np.float64),
        v,
    )
    vp, n = windowed_variance(dp, v, axis, window)
    vr, _ = windowed_variance(dq, v, axis, window)
    dist = np.sqrt(np.einsum("ij,ij->i", dp, dp))[:, None]
    _, _, mean_dist = windowed_moments(dist, v, axis, window)
    return BodyStats(var_pos=vp, var_rot=vr, count=n, distance=mean_dist[:, 0])


def raw_pair_features(sa: BodyStats, sb: BodyStats, sab: BodyStats) -> FloatArray:
    """The four core features of a pair, shape (n_steps, 4), columns :data:`RAW_FEATURE_NAMES`."""
    return np.stack(
        [sa.var_pos + sb.var_pos, sa.var_rot + sb.var_rot, sab.var_pos, sab.var_rot], axis=1
    )


__all__ = [
    "RAW_FEATURE_NAMES",
    "BodyStats",
    "LatentAxis",
    "SegmentationError",
    "body_stats",
    "body_stats_multi",
    "latent_axis",
    "pair_stats",
    "pair_stats_multi",
    "raw_pair_features",
    "windowed_moments",
    "windowed_variance",
]
