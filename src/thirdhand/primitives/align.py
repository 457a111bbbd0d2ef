"""Time alignment and averaging of several demonstrations (phase-based or DTW).

``phase``: each demonstration is resampled on its own normalised time ``[0, 1]``
(linear temporal scaling). ``dtw``: each is warped onto a reference (the
medoid by DTW distance) by dynamic time warping, then averaged sample by
sample along the reference's time (one DBA step). Quaternion tracks are made
sign-continuous and averaged in the tangent space of the reference track
(the first demonstration, or the DTW medoid) at each of its samples: every
matched orientation becomes the rotation vector ``2 log(q_ref(i)⁻¹ ⊗ q)``,
those are averaged and mapped back. Multi-turn motions (screwing) are carried
by the reference; component-wise quaternion averaging would collapse to a
near-zero norm when demonstrations start 150° apart, which they do (a part
picked up either way).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numba
import numpy as np
from numpy.typing import ArrayLike

from thirdhand import se3
from thirdhand.arrays import FloatArray, IntArray
from thirdhand.primitives.checks import PrimitiveError, check_trajectory, check_unit_quaternions
from thirdhand.primitives.quaternion_dmp import quat_exp, quat_log


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
    n = int(np.median([t.size for t, _ in data])) if n_samples is None else int(n_samples)
    if n < 2:
        raise PrimitiveError(f"average: need at least 2 output samples, got {n}")
    duration = float(np.mean([t[-1] - t[0] for t, _ in data]))
    resampled = np.stack([phase_resample(t, y, n) for t, y in data])
    cols = np.zeros(0, dtype=np.int64)
    if quaternion_columns is not None:
        cols = np.arange(resampled.shape[2])[quaternion_columns]
        if cols.size != 4:
            raise PrimitiveError(f"average: quaternion columns must be 4, got {cols.size}")
        q_end = resampled[0, -1, cols]
        flip = resampled[:, -1, cols] @ q_end < 0.0
        resampled[np.ix_(flip, np.arange(n), cols)] *= -1.0
    if method == "phase":
        ref = 0
        paths = [np.stack([np.arange(n), np.arange(n)], axis=1) for _ in resampled]
    elif method == "dtw":
        ref, paths = _dtw_paths(resampled)
    else:
        raise PrimitiveError(f"average: method must be 'phase' or 'dtw', got {method!r}")
    return np.linspace(0.0, duration, n), _mean_along(resampled, ref, paths, cols)


def _mean_along(
    resampled: FloatArray, ref: int, paths: list[IntArray], cols: IntArray
) -> FloatArray:
    """Average the samples matched to each reference sample (quaternions in its tangent space)."""
    _, n, d = resampled.shape
    other = np.setdiff1d(np.arange(d), cols)
    total = np.zeros((n, d))
    rot = np.zeros((n, 3))
    count = np.zeros(n)
    q_ref = resampled[ref][:, cols] if cols.size else None
    for traj, path in zip(resampled, paths, strict=True):
        i, j = path[:, 0], path[:, 1]
        np.add.at(total, i, traj[j])
        if q_ref is not None:
            rel = se3.quat_make_continuous(
                se3.quat_multiply(se3.quat_conjugate(q_ref[i]), traj[j][:, cols])
            )
            # demonstrations agree at the end (the constraint pose): take the sign that is
            # the identity there and unwrap backwards, so differences beyond 180° on the way
            # stay continuous instead of jumping to the other side
            if rel[-1, 3] < 0.0:
                rel = -rel
            np.add.at(rot, i, 2.0 * _unwrapped_log(rel))
        np.add.at(count, i, 1.0)
    mean = total / count[:, None]
    if q_ref is not None:
        out = np.empty_like(mean)
        out[:, other] = mean[:, other]
        out[:, cols] = se3.quat_multiply(q_ref, quat_exp(0.5 * rot / count[:, None]))
        mean = out
    return mean


def _continuous(y: FloatArray, cols: slice, i: int) -> FloatArray:
    out = y.copy()
    out[:, cols] = check_unit_quaternions(y[:, cols], name=f"demonstration {i} orientation")
    return out


def _unwrapped_log(q: FloatArray) -> FloatArray:
    """Half rotation vectors (n, 3) of a sign-continuous track, angles beyond π kept."""
    out = quat_log(q)
    # quat_log takes the w ≥ 0 representative, which jumps by π along the axis where
    # the track crosses w = 0; the track's own sign tells which side it is on
    norm = np.linalg.norm(out, axis=-1, keepdims=True)
    axis = np.where(norm > 1e-12, out / np.where(norm > 1e-12, norm, 1.0), 0.0)
    return np.where((q[..., 3] < 0.0)[..., None], out - np.pi * axis, out)


def _dtw_paths(resampled: FloatArray) -> tuple[int, list[IntArray]]:
    """The medoid (by DTW cost) and every trajectory's DTW path against it."""
    k = resampled.shape[0]
    dist = np.zeros((k, k))
    for i in range(k):
        for j in range(i + 1, k):
            dist[i, j] = dist[j, i] = dtw(resampled[i], resampled[j])[1]
    ref = int(np.argmin(dist.sum(axis=1)))
    return ref, [dtw(resampled[ref], traj)[0] for traj in resampled]
