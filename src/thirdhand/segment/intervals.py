"""Intervals from per-step labels and back, on the latent time axis.

Latent step ``k`` spans ``[edges[k], edges[k + 1])`` seconds. A run of 1s over
steps ``i … j`` becomes the interval ``[edges[i], edges[j + 1]]``; an interval
``[s, e]`` labels the steps whose centre lies in it, so
``labels_from_intervals(intervals_from_labels(y)) == y`` exactly.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from thirdhand.arrays import FloatArray, IntArray
from thirdhand.demonstration import InteractionInterval, Labels


def runs(labels: IntArray) -> list[tuple[int, int]]:
    """Runs of non-zero labels as ``(first, last_exclusive)`` step indices."""
    y = np.asarray(labels) != 0
    d = np.diff(np.concatenate([[0], y.astype(np.int8), [0]]))
    starts = np.flatnonzero(d == 1)
    ends = np.flatnonzero(d == -1)
    return [(int(a), int(b)) for a, b in zip(starts, ends, strict=True)]


def intervals_from_labels(labels: IntArray, edges: FloatArray) -> list[tuple[float, float]]:
    """Intervals in seconds of the runs of 1s.

    Parameters
    ----------
    labels : ndarray of int, shape (n_steps,)
    edges : ndarray, shape (n_steps + 1,), seconds
        Latent step boundaries.
    """
    return [(float(edges[a]), float(edges[b])) for a, b in runs(labels)]


def clip_intervals(
    intervals: Iterable[tuple[float, float]], t0: float, t1: float
) -> list[tuple[float, float]]:
    """Intervals cut to the recording ``[t0, t1]`` s (a latent step's edge may lie past it)."""
    return [(max(s, t0), min(e, t1)) for s, e in intervals if e >= t0 and s <= t1]


def labels_from_intervals(
    intervals: Iterable[tuple[float, float]], centres: FloatArray
) -> IntArray:
    """Per-step labels: 1 where the step's centre lies in some ``[start, end]``.

    Parameters
    ----------
    intervals : iterable of (start, end), seconds
    centres : ndarray, shape (n_steps,), seconds, increasing
    """
    y = np.zeros(len(centres), dtype=np.int64)
    for s, e in intervals:
        lo = np.searchsorted(centres, s, side="left")
        hi = np.searchsorted(centres, e, side="right")
        y[lo:hi] = 1
    return y


def pair_intervals(labels: Labels, a: str, b: str) -> list[tuple[float, float]]:
    """Ground-truth intervals of the unordered pair ``{a, b}``, seconds."""
    return [
        (i.start, i.end)
        for i in labels.interactions
        if (i.a == a and i.b == b) or (i.a == b and i.b == a)
    ]


def to_interaction_intervals(
    a: str, b: str, intervals: Iterable[tuple[float, float]]
) -> list[InteractionInterval]:
    """Intervals as core :class:`InteractionInterval` records."""
    return [InteractionInterval(a, b, s, e) for s, e in intervals]


__all__ = [
    "clip_intervals",
    "intervals_from_labels",
    "labels_from_intervals",
    "pair_intervals",
    "runs",
    "to_interaction_intervals",
]
