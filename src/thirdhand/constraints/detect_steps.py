"""Latent steps of constraint detection: step edges, mean poses per step, runs, motion."""

from __future__ import annotations

import math

import numpy as np

from thirdhand import se3
from thirdhand.arrays import BoolArray, FloatArray
from thirdhand.demonstration import Demonstration


def step_edges(t: FloatArray, step: float) -> FloatArray:
    """Edges of latent steps of ``step`` seconds covering ``t``, shape (n_steps + 1,)."""
    n = max(1, math.ceil((t[-1] - t[0]) / step - 1e-9))
    return np.asarray(t[0] + step * np.arange(n + 1), dtype=np.float64)


def step_poses(
    demo: Demonstration, body: str, edges: FloatArray, *, min_fraction: float = 0.5
) -> tuple[FloatArray, FloatArray]:
    """Mean pose of a body per latent step, world frame.

    Returns
    -------
    pos : ndarray, shape (n_steps, 3), metres; NaN where fewer than ``min_fraction``
        of the step's frames are valid (a mean of a few samples is too noisy to
        compare with the others).
    quat : ndarray, shape (n_steps, 4), x y z w, sign-continuous; NaN likewise.
    """
    n = edges.size - 1
    idx = np.clip(np.searchsorted(edges, demo.t, side="right") - 1, 0, n - 1)
    valid = demo.valid(body)
    frames = np.bincount(idx, minlength=n).astype(np.float64)
    min_samples = np.maximum(1.0, np.ceil(min_fraction * frames))
    counts = np.bincount(idx[valid], minlength=n).astype(np.float64)
    pos = np.zeros((n, 3))
    quat = np.zeros((n, 4))
    q = se3.quat_make_continuous(demo.quat(body), valid)
    for k in range(3):
        pos[:, k] = np.bincount(idx[valid], weights=demo.pos(body)[valid, k], minlength=n)
    for k in range(4):
        quat[:, k] = np.bincount(idx[valid], weights=q[valid, k], minlength=n)
    ok = counts >= min_samples
    pos = np.where(ok[:, None], pos / np.maximum(counts, 1)[:, None], np.nan)
    norm = np.linalg.norm(quat, axis=1)
    quat = np.where((ok & (norm > 1e-12))[:, None], quat / np.maximum(norm, 1e-12)[:, None], np.nan)
    return pos, quat


def _runs(mask: BoolArray) -> list[tuple[int, int]]:
    """Half-open index runs ``[lo, hi)`` where ``mask`` is true."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist(), strict=True))


def _last_valid_pose(pos: FloatArray, quat: FloatArray) -> tuple[FloatArray, FloatArray]:
    ok = np.flatnonzero(np.all(np.isfinite(pos), axis=1) & np.all(np.isfinite(quat), axis=1))
    if ok.size == 0:
        return np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0])
    tail = ok[-5:]
    qm = quat[tail].sum(axis=0)
    return pos[tail].mean(axis=0), qm / np.linalg.norm(qm)


def _motion(pos: FloatArray, quat: FloatArray, lo: int, hi: int) -> tuple[float, float]:
    """Largest displacement (m) and rotation (rad) from the first valid pose in ``[lo, hi)``."""
    p, q = pos[lo:hi], quat[lo:hi]
    ok = np.all(np.isfinite(p), axis=1) & np.all(np.isfinite(q), axis=1)
    if ok.sum() < 2:
        return 0.0, 0.0
    p, q = p[ok], q[ok]
    dp = float(np.max(np.linalg.norm(p - p[0], axis=1)))
    dr = float(np.max(se3.quat_angle(q, q[0])))
    return dp, dr


def _path_length(pos: FloatArray, quat: FloatArray) -> float:
    """Distance a body travels in the world, metres (over valid consecutive steps)."""
    d = np.linalg.norm(np.diff(pos, axis=0), axis=1)
    return float(np.nansum(d))
