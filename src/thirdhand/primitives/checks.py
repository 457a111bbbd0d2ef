"""Input checks shared by the motor-primitive modules."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from thirdhand.arrays import FloatArray
from thirdhand.errors import ThirdhandError


class PrimitiveError(ThirdhandError, ValueError):
    """A trajectory given to a motor primitive cannot be used (too short, NaN, bad shape)."""


def check_trajectory(
    t: ArrayLike, y: ArrayLike, *, name: str = "trajectory", min_samples: int = 3
) -> tuple[FloatArray, FloatArray]:
    """Validate a sampled trajectory once, at the public boundary.

    Parameters
    ----------
    t : array_like, shape (n,)
        Strictly increasing times, seconds.
    y : array_like, shape (n,) or (n, d)
        Samples; a 1-D array is one dimension.
    name : str
        Used in error messages ("segment 3 of demo.parquet").
    min_samples : int
        Fewest samples accepted.

    Returns
    -------
    t : ndarray, shape (n,)
    y : ndarray, shape (n, d)

    Raises
    ------
    PrimitiveError
        Naming the trajectory, the sample and what was expected.
    """
    ta = np.asarray(t, dtype=np.float64)
    ya = np.asarray(y, dtype=np.float64)
    if ya.ndim == 1:
        ya = ya[:, None]
    if ta.ndim != 1 or ya.ndim != 2 or ya.shape[0] != ta.size:
        raise PrimitiveError(
            f"{name}: expected times (n,) and samples (n, d), got {ta.shape} and {ya.shape}"
        )
    if ta.size < min_samples:
        raise PrimitiveError(f"{name}: expected at least {min_samples} samples, got {ta.size}")
    if ya.shape[1] == 0:
        raise PrimitiveError(f"{name}: samples have no dimension")
    bad = ~np.isfinite(ya).all(axis=1) | ~np.isfinite(ta)
    if bad.any():
        raise PrimitiveError(
            f"{name}: sample {int(np.argmax(bad))} is not finite (NaN or inf); "
            f"{int(bad.sum())} of {ta.size} samples are bad — fill or cut the gaps first"
        )
    dt = np.diff(ta)
    if not (dt > 0).all():
        k = int(np.argmax(dt <= 0))
        raise PrimitiveError(
            f"{name}: times must increase strictly, sample {k + 1} at {ta[k + 1]:.6g} s "
            f"follows {ta[k]:.6g} s"
        )
    return ta, ya


def check_unit_quaternions(q: FloatArray, *, name: str = "orientation track") -> FloatArray:
    """Normalise a quaternion track (n, 4) x y z w and make its signs continuous.

    Raises
    ------
    PrimitiveError
        If a row is (near) zero or the shape is not (n, 4).
    """
    if q.ndim != 2 or q.shape[1] != 4:
        raise PrimitiveError(f"{name}: expected quaternions of shape (n, 4), got {q.shape}")
    norms = np.linalg.norm(q, axis=1)
    if (norms < 1e-6).any():
        k = int(np.argmax(norms < 1e-6))
        raise PrimitiveError(f"{name}: quaternion at sample {k} has zero norm")
    qn = q / norms[:, None]
    dots = np.sum(qn[1:] * qn[:-1], axis=1)
    flips = np.concatenate([[False], np.logical_xor.accumulate(dots < 0.0)])
    qn[flips] *= -1.0
    return qn
