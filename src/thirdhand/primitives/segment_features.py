"""Candidate cuts and the normalised weight-space features of every possible segment.

Used by the primitive-library parser (:mod:`thirdhand.primitives.primitive_library`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.ndimage import uniform_filter1d

from thirdhand.arrays import FloatArray, IntArray
from thirdhand.primitives.checks import PrimitiveError
from thirdhand.primitives.promp import rbf_features


def smoothed_speed(y: FloatArray, dt: float, window: int) -> FloatArray:
    """Speed (units/s), shape (n,), after an averaging low-pass filter of ``window`` samples."""
    v = np.gradient(y, dt, axis=0)
    v = uniform_filter1d(v, size=max(int(window), 1), axis=0, mode="nearest")
    return np.linalg.norm(v, axis=1)


def candidate_cuts(
    y: ArrayLike,
    *,
    dt: float,
    threshold: float,
    window: int = 5,
    min_gap: int = 3,
) -> IntArray:
    """Sample indices where the smoothed speed falls under ``threshold``.

    One cut per run of slow samples (at its slowest sample); runs touching the
    first or last sample are the trajectory's own ends and give no cut.

    Parameters
    ----------
    y : array_like, shape (n, dims)
        Trajectory.
    dt : float
        Sample interval, seconds.
    threshold : float
        Absolute speed threshold, units/s.
    window : int
        Length of the moving-average filter, samples.
    min_gap : int
        Cuts closer than this to each other or to an end are dropped.

    Returns
    -------
    ndarray of int, shape (M,)
        Increasing indices in ``(0, n − 1)``.
    """
    ya = np.asarray(y, dtype=np.float64)
    if ya.ndim == 1:
        ya = ya[:, None]
    n = ya.shape[0]
    sp = smoothed_speed(ya, dt, window)
    slow = sp < threshold
    edges = np.diff(slow.astype(np.int8), prepend=0, append=0)
    starts = np.flatnonzero(edges == 1)
    ends = np.flatnonzero(edges == -1)
    cuts = []
    for a, b in zip(starts, ends, strict=True):
        if a == 0 or b == n:
            continue
        cuts.append(a + int(np.argmin(sp[a:b])))
    out = np.array(cuts, dtype=np.int64)
    keep = (out >= min_gap) & (out <= n - 1 - min_gap)
    out = out[keep]
    if out.size > 1:
        out = out[np.concatenate([[True], np.diff(out) >= min_gap])]
    return out


def resample_segments(
    y: FloatArray, starts: IntArray, ends: IntArray, n_samples: int
) -> FloatArray:
    """Linear temporal scaling of segments ``y[a:b+1]`` to ``n_samples`` samples each.

    Returns
    -------
    ndarray, shape (n_segments, n_samples, dims)
    """
    u = np.linspace(0.0, 1.0, n_samples)
    pos = starts[:, None] + (ends - starts)[:, None] * u[None, :]
    lo = np.clip(np.floor(pos).astype(np.int64), 0, y.shape[0] - 1)
    hi = np.minimum(lo + 1, y.shape[0] - 1)
    frac = (pos - lo)[..., None]
    return y[lo] * (1.0 - frac) + y[hi] * frac


def normalise_segments(seg: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Translate to start at the origin; rotate about z so start→end lies on +x.

    Parameters
    ----------
    seg : ndarray, shape (h, n, dims)

    Returns
    -------
    seg : ndarray, shape (h, n, dims)
    angle : ndarray, shape (h,)
        Rotation removed, radians (zeros for 1-D segments).
    """
    out = seg - seg[:, :1, :]
    h = seg.shape[0]
    if seg.shape[2] < 2:
        return out, np.zeros(h)
    d = out[:, -1, :2]
    ang = np.arctan2(d[:, 1], d[:, 0])
    c, s = np.cos(ang)[:, None], np.sin(ang)[:, None]
    x, yy = out[:, :, 0].copy(), out[:, :, 1].copy()
    out[:, :, 0] = c * x + s * yy
    out[:, :, 1] = -s * x + c * yy
    return out, ang


@dataclass
class SegmentStats:
    """Sufficient statistics of normalised segments for the mixture of ProMPs.

    Sums over a segment's samples (its first sample excluded: it is the previous
    segment's last, and zero after translation) are approximated from the
    segment resampled to ``L`` points, each resampled point standing for
    ``c = (N − 1) / (L − 1)`` original samples; so every sample of a track counts
    once whatever the segmentation.

    Attributes
    ----------
    gram : ndarray, shape (F, F)
        ``Φ_Lᵀ Φ_L`` over the resampled points (block-diagonal per dimension).
    scale : ndarray, shape (h,)
        ``c`` per segment.
    proj : ndarray, shape (h, F)
        ``c Φ_Lᵀ q_L``.
    sq : ndarray, shape (h,)
        ``c ‖q_L‖²``.
    n_obs : ndarray, shape (h,)
        Scalar observations, ``(N − 1) dims``.
    ridge : ndarray, shape (h, F)
        Ridge weights (for initialisation and plots).
    angle : ndarray, shape (h,)
        Rotation about z removed, radians (zeros for 1-D tracks).
    lev_n : ndarray, shape (h,)
        Samples of the level channels in the segment (its first sample excluded, as
        for the shape): each skill has a per-sample Gaussian on the absolute
        levels (a contact force, an arm's angular speed), beside its shape.
    lev_sum, lev_sq : ndarray, shape (h, L)
        Per level channel, the sum and the sum of squares over those samples
        (``L = 0`` without level channels).
    """

    gram: FloatArray
    scale: FloatArray
    proj: FloatArray
    sq: FloatArray
    n_obs: FloatArray
    ridge: FloatArray
    angle: FloatArray
    lev_n: FloatArray
    lev_sum: FloatArray
    lev_sq: FloatArray

    @property
    def n_levels(self) -> int:
        """Number of level channels ``L``."""
        return int(self.lev_sum.shape[1])

    def take(self, idx: NDArray[np.int64] | NDArray[np.bool_]) -> SegmentStats:
        """A subset of the segments."""
        return SegmentStats(
            self.gram,
            self.scale[idx],
            self.proj[idx],
            self.sq[idx],
            self.n_obs[idx],
            self.ridge[idx],
            self.angle[idx],
            self.lev_n[idx],
            self.lev_sum[idx],
            self.lev_sq[idx],
        )

    @staticmethod
    def concat(parts: list[SegmentStats]) -> SegmentStats:
        """Segments of several tracks together."""
        return SegmentStats(
            parts[0].gram,
            *(
                np.concatenate([getattr(p, f) for p in parts])
                for f in (
                    "scale",
                    "proj",
                    "sq",
                    "n_obs",
                    "ridge",
                    "angle",
                    "lev_n",
                    "lev_sum",
                    "lev_sq",
                )
            ),
        )


def segment_stats(
    y: FloatArray,
    starts: IntArray,
    ends: IntArray,
    *,
    n_samples: int = 30,
    n_weights: int = 8,
    regularization: float = 1e-6,
    levels: FloatArray | None = None,
) -> SegmentStats:
    """Statistics of segments ``y[a:b+1]`` after temporal scaling, translation and rotation.

    Parameters
    ----------
    y : ndarray, shape (n, dims)
    starts, ends : ndarray of int, shape (h,)
        First and last sample of each segment (inclusive), ``end > start``.
    n_samples : int
        Common length ``L`` of the temporal scaling.
    n_weights : int
        RBFs per dimension (``F = dims × n_weights``).
    levels : ndarray, shape (n, L), optional
        Level channels on the same samples, summed exactly (cumulative sums) over
        samples ``a+1 … b`` of each segment.
    """
    if np.any(ends <= starts):
        raise PrimitiveError("segment features: every segment needs at least two samples")
    dims = y.shape[1]
    seg = resample_segments(y, starts, ends, n_samples)
    seg, ang = normalise_segments(seg)
    f = rbf_features(np.linspace(0.0, 1.0, n_samples), n_weights)
    gram1 = f.T @ f
    ridge = np.einsum(
        "kn,hnd->hdk", np.linalg.solve(gram1 + regularization * np.eye(n_weights), f.T), seg
    ).reshape(len(starts), -1)
    fr, sr = f[1:], seg[:, 1:, :]
    c = (ends - starts).astype(np.float64) / (n_samples - 1)
    proj = c[:, None] * np.einsum("nk,hnd->hdk", fr, sr).reshape(len(starts), -1)
    sq = c * np.einsum("hnd,hnd->h", sr, sr)
    gram = np.asarray(np.kron(np.eye(dims), fr.T @ fr), dtype=np.float64)
    n_obs = ((ends - starts) * dims).astype(np.float64)
    lev = np.zeros((y.shape[0], 0)) if levels is None else np.asarray(levels, dtype=np.float64)
    if lev.ndim != 2 or lev.shape[0] != y.shape[0]:
        raise PrimitiveError(f"segment features: levels must be ({y.shape[0]}, L), got {lev.shape}")
    c1 = np.vstack([np.zeros((1, lev.shape[1])), np.cumsum(lev, axis=0)])
    c2 = np.vstack([np.zeros((1, lev.shape[1])), np.cumsum(lev**2, axis=0)])
    lev_sum = c1[ends + 1] - c1[starts + 1]
    lev_sq = c2[ends + 1] - c2[starts + 1]
    lev_n = (ends - starts).astype(np.float64)
    return SegmentStats(gram, c, proj, sq, n_obs, ridge, ang, lev_n, lev_sum, lev_sq)
