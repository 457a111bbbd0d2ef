"""Feature statistics as LeRobot defines them (``lerobot/datasets/compute_stats.py``, 0.4.x).

Per episode and feature column: ``min``, ``max``, ``mean``, ``std`` (population),
``count`` (frames) and the quantiles ``q01``, ``q10``, ``q50``, ``q90``, ``q99``
read off a 5000-bin histogram spanning ``[min - 1e-10, max + 1e-10]``, linearly
interpolated inside the bin that holds the target count ``q * count``. An
episode of one frame gets its mean as every quantile.

Images (video frames) are sampled as LeRobot samples them (every frame up to
100, then ``count ** 0.75`` frames evenly spread, at most 10 000), frames of
300 pixels or more on a side are subsampled to about 150, and the statistics
are per colour channel over all pixels, divided by 255, of shape (3, 1, 1);
``count`` is the number of frames sampled.

The dataset's statistics (``meta/stats.json``) aggregate the episodes':
min of mins, max of maxes, the count-weighted mean, the pooled standard
deviation, and each quantile as the count-weighted mean of the episodes'
(LeRobot's ``aggregate_stats``: not a quantile of the pooled frames).

One difference from LeRobot 0.4.4: it squares uint8 pixels in uint8, so the
square wraps at 256 and its image ``std`` is wrong (often clipped to 0); here
the standard deviation is that of the pixel values.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

#: The quantiles LeRobot computes, and their keys.
QUANTILES = (0.01, 0.10, 0.50, 0.90, 0.99)
QUANTILE_KEYS = tuple(f"q{round(q * 100):02d}" for q in QUANTILES)
#: Every statistic, in LeRobot's order.
STAT_KEYS = ("min", "max", "mean", "std", "count", *QUANTILE_KEYS)
_BINS = 5000

Stats = dict[str, NDArray[np.generic]]


def _quantile(column: NDArray[np.float64], lo: float, hi: float, q: float) -> float:
    edges = np.linspace(lo - 1e-10, hi + 1e-10, _BINS + 1)
    hist, _ = np.histogram(column, bins=edges)
    cumsum = np.cumsum(hist)
    target = q * column.size
    idx = int(np.searchsorted(cumsum, target))
    if idx == 0:
        return float(edges[0])
    if idx >= cumsum.size:
        return float(edges[-1])
    before = cumsum[idx - 1]
    inside = cumsum[idx] - before
    if inside == 0:
        return float(edges[idx])
    return float(edges[idx] + (target - before) / inside * (edges[idx + 1] - edges[idx]))


def column_stats(values: NDArray[np.generic], *, count: int | None = None) -> Stats:
    """Statistics of every column of ``values``.

    Parameters
    ----------
    values : ndarray, shape (n_samples, n)
        One row per sample. ``min`` and ``max`` keep its dtype; the rest are float64.
    count : int, optional
        The ``count`` to state (the number of frames); ``n_samples`` by default.

    Returns
    -------
    dict
        Each of :data:`STAT_KEYS` -> ndarray of shape (n,); ``count`` of shape (1,).
    """
    x = np.asarray(values)
    as_float = x.astype(np.float64)
    stats: Stats = {
        "min": x.min(axis=0),
        "max": x.max(axis=0),
        "mean": as_float.mean(axis=0),
        "std": as_float.std(axis=0),
        "count": np.array([x.shape[0] if count is None else count], dtype=np.int64),
    }
    if x.shape[0] < 2:
        for key in QUANTILE_KEYS:
            stats[key] = stats["mean"].copy()
        return stats
    lo, hi = as_float.min(axis=0), as_float.max(axis=0)
    for key, q in zip(QUANTILE_KEYS, QUANTILES, strict=True):
        stats[key] = np.array(
            [_quantile(as_float[:, j], lo[j], hi[j], q) for j in range(x.shape[1])]
        )
    return stats


def sample_indices(n_frames: int) -> NDArray[np.int64]:
    """The frames LeRobot samples for image statistics, shape (n_samples,)."""
    n = n_frames if n_frames < 100 else max(100, min(int(n_frames**0.75), 10_000))
    return np.round(np.linspace(0, n_frames - 1, n)).astype(np.int64)


def image_stats(frames: NDArray[np.uint8]) -> Stats:
    """Per-channel statistics of RGB frames, in [0, 1], each of shape (3, 1, 1).

    Parameters
    ----------
    frames : ndarray of uint8, shape (n_frames, height, width, 3)
    """
    sampled = frames[sample_indices(frames.shape[0])]
    _, h, w, _ = sampled.shape
    if max(h, w) >= 300:
        step = int(w / 150) if w > h else int(h / 150)
        sampled = sampled[:, ::step, ::step]
    stats = column_stats(sampled.reshape(-1, 3), count=sampled.shape[0])
    return {
        k: v if k == "count" else (np.asarray(v, dtype=np.float64) / 255.0).reshape(3, 1, 1)
        for k, v in stats.items()
    }


def aggregate(per_episode: Sequence[Stats]) -> Stats:
    """One feature's statistics over episodes, as LeRobot's ``aggregate_stats``."""
    counts = np.stack([s["count"] for s in per_episode]).astype(np.float64)
    total = counts.sum(axis=0)
    means = np.stack([np.asarray(s["mean"], dtype=np.float64) for s in per_episode])
    while counts.ndim < means.ndim:
        counts = counts[..., None]
    mean = (means * counts).sum(axis=0) / total
    var = np.stack([np.asarray(s["std"], dtype=np.float64) ** 2 for s in per_episode])
    pooled = ((var + (means - mean) ** 2) * counts).sum(axis=0) / total
    out: Stats = {
        "min": np.min(np.stack([s["min"] for s in per_episode]), axis=0),
        "max": np.max(np.stack([s["max"] for s in per_episode]), axis=0),
        "mean": mean,
        "std": np.sqrt(pooled),
        "count": np.array([int(sum(int(s["count"][0]) for s in per_episode))], dtype=np.int64),
    }
    for key in QUANTILE_KEYS:
        qs = np.stack([np.asarray(s[key], dtype=np.float64) for s in per_episode])
        out[key] = (qs * counts).sum(axis=0) / total
    return out
