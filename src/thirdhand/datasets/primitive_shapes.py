"""Toy and real data sets for the primitive-library parser.

``sine_tracks``: 1-D trajectories from three skills with known cuts (the
3rdHand report's experiment); ``lasa_shapes`` / ``concatenate_shapes``: LASA
handwriting shapes (``../shared/data/lasa``) joined end to start.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from thirdhand.arrays import FloatArray, IntArray
from thirdhand.errors import FormatError

#: Skill names of :func:`sine_tracks`, in label order.
SINE_SKILLS = ("down", "bump", "up")


def _move(delta: float, n: int) -> FloatArray:
    """Half-cosine move by ``delta`` over ``n`` samples, zero velocity at both ends."""
    s = np.linspace(0.0, 1.0, n)
    return delta * 0.5 * (1.0 - np.cos(np.pi * s))


def sine_tracks(
    n_tracks: int = 10, *, seed: int = 0, rate: float = 100.0, noise: float = 0.0
) -> list[tuple[FloatArray, FloatArray, IntArray, IntArray]]:
    """Sine-like 1-D tracks: start at 0 going down, end at 0 going up.

    Each track is ``down, bump × r, up`` (r = 1…3): ``down`` goes from 0 to −a,
    ``bump`` rises by h and comes back (its zero-velocity top is a candidate cut,
    but the two halves always occur together), ``up`` returns to 0. Amplitudes
    ``a ≈ 1``, ``h ≈ 0.5`` and durations 0.8–1.2 s (per half for ``bump``) vary.

    Returns
    -------
    list of (t, y, bounds, labels)
        ``t (n,)`` seconds, ``y (n, 1)``, true segment boundaries (sample indices,
        ends included) and true skill labels (indices into :data:`SINE_SKILLS`).
    """
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n_tracks):
        a = rng.uniform(0.9, 1.1)
        pieces: list[FloatArray] = []
        labels: list[int] = []
        bounds = [0]

        def add(
            p: FloatArray,
            label: int | None,
            pieces: list[FloatArray] = pieces,
            labels: list[int] = labels,
            bounds: list[int] = bounds,
        ) -> None:
            start = pieces[-1][-1] if pieces else 0.0
            pieces.append(start + p[1:] if pieces else start + p)
            if label is not None:
                labels.append(label)
                bounds.append(sum(len(q) for q in pieces) - 1)

        def n_of(lo: float, hi: float) -> int:
            return int(rng.uniform(lo, hi) * rate) + 1

        add(_move(-a, n_of(0.8, 1.2)), 0)
        for _ in range(int(rng.integers(1, 4))):
            h = rng.uniform(0.4, 0.6)
            add(_move(h, n_of(0.8, 1.2)), None)
            add(_move(-h, n_of(0.8, 1.2)), 1)
        add(_move(a, n_of(0.8, 1.2)), 2)
        y = np.concatenate(pieces)[:, None]
        y = y + noise * rng.standard_normal(y.shape)
        t = np.arange(y.shape[0]) / rate
        out.append((t, y, np.array(bounds, dtype=np.int64), np.array(labels, dtype=np.int64)))
    return out


def lasa_shapes(folder: str | os.PathLike[str], name: str) -> list[tuple[FloatArray, FloatArray]]:
    """All demonstrations of one LASA shape: ``[(t (n,), pos (n, 2)), …]`` (mm, s).

    Raises
    ------
    FormatError
        If the file is missing or has no ``demos`` with ``pos`` and ``t``.
    """
    from scipy.io import loadmat

    path = Path(folder) / f"{name}.mat"
    if not path.is_file():
        raise FormatError(path, "LASA shape file not found")
    try:
        demos = loadmat(path, squeeze_me=True)["demos"]
    except (KeyError, ValueError, OSError) as exc:
        raise FormatError(path, f"expected a MATLAB file with 'demos': {exc}") from None
    out = []
    for i, d in enumerate(np.atleast_1d(demos)):
        try:
            pos = np.asarray(d["pos"].item() if hasattr(d["pos"], "item") else d["pos"], float)
            t = np.asarray(d["t"].item() if hasattr(d["t"], "item") else d["t"], float).ravel()
        except (KeyError, ValueError, IndexError):
            raise FormatError(path, "demo without 'pos' and 't'", where=f"demo {i}") from None
        if pos.ndim != 2 or pos.shape[0] != 2 or pos.shape[1] != t.size:
            raise FormatError(
                path, f"expected pos (2, {t.size}), got {pos.shape}", where=f"demo {i}"
            )
        out.append((t - t[0], pos.T.copy()))
    return out


def concatenate_shapes(
    shapes: Sequence[tuple[FloatArray, FloatArray]], *, rate: float | None = None
) -> tuple[FloatArray, FloatArray, IntArray]:
    """Join trajectories end to start (each translated to start where the previous ended).

    Returns
    -------
    t : ndarray, shape (n,), seconds, uniform
    y : ndarray, shape (n, dims)
    joins : ndarray of int
        Sample indices of the joins.
    """
    pieces, joins, offset = [], [], None
    dt = None
    for t, y in shapes:
        step = float(np.median(np.diff(t))) if rate is None else 1.0 / rate
        dt = step if dt is None else dt
        grid = np.arange(0.0, t[-1] - t[0] + 1e-12, dt)
        yi = np.stack([np.interp(grid, t - t[0], c) for c in y.T], axis=1)
        if offset is not None:
            yi = yi - yi[0] + offset
            yi = yi[1:]
            joins.append(sum(len(p) for p in pieces) - 1)
        pieces.append(yi)
        offset = yi[-1]
    y_all = np.concatenate(pieces)
    assert dt is not None
    t_all = np.arange(y_all.shape[0], dtype=np.float64) * dt
    return t_all, y_all.astype(np.float64), np.array(joins, dtype=np.int64)
