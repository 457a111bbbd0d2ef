"""Time alignment and averaging of several demonstrations (phase-based or DTW).

``phase``: each demonstration is resampled on its own normalised time ``[0, 1]``
(linear temporal scaling). ``dtw``: each is warped onto a reference (the
medoid by DTW distance) by dynamic time warping, then averaged sample by
sample along the reference's time (one DBA step). Quaternion tracks are
made sign-continuous and sign-consistent across demonstrations, averaged
component-wise and renormalised (the chordal mean, accurate for spreads of
tens of degrees).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from thirdhand.primitives._checks import PrimitiveError, check_trajectory, check_unit_quaternions

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


def phase_resample(t: ArrayLike, y: ArrayLike, n: int) -> FloatArray:
    """Resample ``y`` (m, dims) at ``n`` equally spaced points of normalised time, (n, dims)."""
    ta, ya = check_trajectory(t, y, name="trajectory", min_samples=2)
    z = (ta - ta[0]) / (ta[-1] - ta[0])
    grid = np.linspace(0.0, 1.0, n)
    return np.stack([np.interp(grid, z, col) for col in ya.T], axis=1)


@numba.njit(cache=True, nogil=True)
def _dtw_table(cost: FloatArray, window: int) -> FloatArray:  # pragma: no cover - compiled
    n, m = cost.shape
    acc = np.full((n + 1, m + 1), np.inf)
    acc[0, 0] = 0.0
    for i in range(1, n + 1):
        lo = max(1, i - window)
        hi = min(m, i + window)
        for j in range(lo, hi + 1):
            best = acc[i - 1, j - 1]
            if acc[i - 1, j] < best:
                best = acc[i - 1, j]
            if acc[i, j - 1] < best:
                best = acc[i, j - 1]
            acc[i, j] = cost[i - 1, j - 1] + best
    return acc


def dtw(a: ArrayLike, b: ArrayLike, *, window: int | None = None) -> tuple[IntArray, float]:
    """Dynamic time warping between two trajectories (Euclidean sample distance).

    Parameters
    ----------
    a : array_like, shape (n, dims)
    b : array_like, shape (m, dims)
    window : int, optional
        Sakoe–Chiba band half-width, samples (widened to ``|n − m|`` if smaller).

    Returns
    -------
    path : ndarray of int, shape (k, 2)
        Matched index pairs ``(i, j)`` from ``(0, 0)`` to ``(n−1, m−1)``.
    cost : float
        Summed distance along the path.
    """
    aa = np.asarray(a, dtype=np.float64)
    bb = np.asarray(b, dtype=np.float64)
    aa = aa[:, None] if aa.ndim == 1 else aa
    bb = bb[:, None] if bb.ndim == 1 else bb
    if aa.shape[0] == 0 or bb.shape[0] == 0 or aa.shape[1] != bb.shape[1]:
        raise PrimitiveError(
            f"DTW: expected two non-empty (n, d) arrays, got {aa.shape} and {bb.shape}"
        )
    n, m = aa.shape[0], bb.shape[0]
    w = max(n, m) if window is None else max(int(window), abs(n - m))
    cost = np.sqrt(((aa[:, None, :] - bb[None, :, :]) ** 2).sum(-1))
    acc = _dtw_table(cost, w)
    i, j = n, m
    path = [(n - 1, m - 1)]
    while (i, j) != (1, 1):
        steps = ((i - 1, j - 1), (i - 1, j), (i, j - 1))
        i, j = min(steps, key=lambda s: acc[s])
        path.append((i - 1, j - 1))
    return np.array(path[::-1], dtype=np.int64), float(acc[n, m])


def average(
    trajectories: Sequence[tuple[ArrayLike, ArrayLike]],
    *,
    method: Literal["phase", "dtw"] = "phase",
    n_samples: int | None = None,
    quaternion_columns: slice | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Align and average demonstrations ``[(t, y), …]``.

    Parameters
    ----------
    trajectories : sequence of (t (n_i,), y (n_i, dims))
    method : {"phase", "dtw"}
    n_samples : int, optional
        Samples of the result (default: the median length).
    quaternion_columns : slice, optional
        Columns holding x y z w quaternions (e.g. ``slice(3, 7)`` for pos + quat);
        they are sign-aligned before averaging and renormalised after.

    Returns
    -------
    t : ndarray, shape (n,)
        Seconds from 0 over the mean duration.
    y : ndarray, shape (n, dims)
    """
    if not trajectories:
        raise PrimitiveError("average: no demonstration given")
    data = [
        check_trajectory(t, y, name=f"demonstration {i}") for i, (t, y) in enumerate(trajectories)
    ]
    dims = {y.shape[1] for _, y in data}
    if len(dims) != 1:
        raise PrimitiveError(f"average: demonstrations have different dimensions {sorted(dims)}")
    if quaternion_columns is not None:
        data = [(t, _continuous(y, quaternion_columns, i)) for i, (t, y) in enumerate(data)]
        ref_q = data[0][1][0, quaternion_columns]
        for i, (t, y) in enumerate(data):
            if float(y[0, quaternion_columns] @ ref_q) < 0.0:
                y = y.copy()
                y[:, quaternion_columns] *= -1.0
                data[i] = (t, y)
    n = int(np.median([t.size for t, _ in data])) if n_samples is None else int(n_samples)
    if n < 2:
        raise PrimitiveError(f"average: need at least 2 output samples, got {n}")
    duration = float(np.mean([t[-1] - t[0] for t, _ in data]))
    resampled = np.stack([phase_resample(t, y, n) for t, y in data])
    if method == "phase":
        mean = resampled.mean(axis=0)
    elif method == "dtw":
        mean = _dtw_average(resampled)
    else:
        raise PrimitiveError(f"average: method must be 'phase' or 'dtw', got {method!r}")
    if quaternion_columns is not None:
        q = mean[:, quaternion_columns]
        mean[:, quaternion_columns] = q / np.linalg.norm(q, axis=1, keepdims=True)
    return np.linspace(0.0, duration, n), mean


def _continuous(y: FloatArray, cols: slice, i: int) -> FloatArray:
    out = y.copy()
    out[:, cols] = check_unit_quaternions(y[:, cols], name=f"demonstration {i} orientation")
    return out


def _dtw_average(resampled: FloatArray) -> FloatArray:
    k = resampled.shape[0]
    if k == 1:
        return resampled[0].copy()
    dist = np.zeros((k, k))
    for i in range(k):
        for j in range(i + 1, k):
            dist[i, j] = dist[j, i] = dtw(resampled[i], resampled[j])[1]
    ref = resampled[int(np.argmin(dist.sum(axis=1)))]
    total = np.zeros_like(ref)
    count = np.zeros(ref.shape[0])
    for traj in resampled:
        path, _ = dtw(ref, traj)
        np.add.at(total, path[:, 0], traj[path[:, 1]])
        np.add.at(count, path[:, 0], 1.0)
    return total / count[:, None]
