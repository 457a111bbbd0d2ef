"""Bridge the tracking gaps of a body that stayed where it was.

An AR tag on a table is hidden whenever the arm passes in front of the camera
(the IKEA bags: the table's tag is seen in 0–45 % of each second); a magnetic
sensor drops packets. A body seen at rest just before a gap and at rest, at the
same pose, just after it most likely did not move in between: the gap is
filled with the mean of the two poses, so that the pairs it forms keep their
evidence (a leg resting in the table's hole is only an interaction if the table
is seen).

A gap is filled when it lasts at most ``max_gap_s`` and the ``side`` valid
frames on each side are at rest (their position and orientation variances
within :data:`~thirdhand.segment.noise.REST_FACTOR` × the track's noise floor)
and the two side means agree: ``|Δmean|² ≤ 9 τ (1/n_before + 1/n_after)``, a
3-σ test for two means of white noise of trace covariance ``τ``, for
positions and for quaternion components. Anything else stays a gap. The filled
pose is the sample-weighted mean of the two sides.
"""

from __future__ import annotations

import numba
import numpy as np

from thirdhand.arrays import BoolArray, FloatArray, IntArray
from thirdhand.segment.noise import REST_FACTOR, NoiseFloor


@numba.njit(cache=True, nogil=True)
def _side_stats(  # pragma: no cover - compiled
    x: FloatArray, rows: IntArray
) -> tuple[FloatArray, float]:
    """Mean (d,) and trace of the covariance of ``x[rows]``."""
    d = x.shape[1]
    mean = np.zeros(d)
    for r in rows:
        for j in range(d):
            mean[j] += x[r, j]
    mean /= rows.size
    var = 0.0
    for r in rows:
        for j in range(d):
            dv = x[r, j] - mean[j]
            var += dv * dv
    return mean, var / rows.size


@numba.njit(cache=True, nogil=True)
def _fill(  # pragma: no cover - compiled
    t: FloatArray,
    pos: FloatArray,
    quat: FloatArray,
    valid: BoolArray,
    floor_pos: float,
    floor_rot: float,
    max_gap_s: float,
    side: int,
    rest: float,
) -> tuple[FloatArray, FloatArray, BoolArray, int]:
    n = valid.size
    idx = np.flatnonzero(valid)
    p_out = pos.copy()
    q_out = quat.copy()
    v_out = valid.copy()
    filled = 0
    k = 0  # index into idx of the first valid frame after the current gap
    i = 0
    while i < n:
        if valid[i]:
            i += 1
            continue
        lo = i
        while i < n and not valid[i]:
            i += 1
        hi = i
        while k < idx.size and idx[k] < lo:
            k += 1
        if lo == 0 or hi >= n or t[hi] - t[lo - 1] > max_gap_s:
            continue
        before = idx[max(k - side, 0) : k]
        after = idx[k : k + side]
        if before.size < 2 or after.size < 2:
            continue
        pb, vpb = _side_stats(pos, before)
        pa, vpa = _side_stats(pos, after)
        qb, vqb = _side_stats(quat, before)
        qa, vqa = _side_stats(quat, after)
        if vpb > rest * floor_pos or vpa > rest * floor_pos:
            continue
        if vqb > rest * floor_rot or vqa > rest * floor_rot:
            continue
        sign = 1.0 if np.dot(qb, qa) >= 0 else -1.0
        scale = 1.0 / before.size + 1.0 / after.size
        dp = pb - pa
        dq = qb - sign * qa
        if np.dot(dp, dp) > 9.0 * floor_pos * scale or np.dot(dq, dq) > 9.0 * floor_rot * scale:
            continue
        wb = before.size / (before.size + after.size)
        p = wb * pb + (1.0 - wb) * pa
        q = wb * qb + (1.0 - wb) * sign * qa
        q /= np.sqrt(np.dot(q, q))
        for r in range(lo, hi):
            p_out[r] = p
            q_out[r] = q
            v_out[r] = True
        filled += hi - lo
    return p_out, q_out, v_out, filled


def fill_static_gaps(
    t: FloatArray,
    pos: FloatArray,
    quat: FloatArray,
    valid: BoolArray,
    floor: NoiseFloor,
    *,
    max_gap_s: float,
    side: int = 5,
) -> tuple[FloatArray, FloatArray, BoolArray, int]:
    """Fill the gaps of a track across which the body stayed still.

    Parameters
    ----------
    t : ndarray, shape (n,), seconds
    pos : ndarray, shape (n, 3), metres
    quat : ndarray, shape (n, 4), x y z w, sign-continuous over valid frames
    valid : ndarray of bool, shape (n,)
    floor : NoiseFloor
        The track's noise floor (:func:`~thirdhand.segment.noise.noise_floor`).
    max_gap_s : float
        Longest gap filled, seconds.
    side : int
        Valid frames looked at on each side of a gap.

    Returns
    -------
    pos, quat, valid : ndarrays as given, with the filled frames (copies)
    filled : int
        Number of frames filled.
    """
    v = np.ascontiguousarray(valid, dtype=np.bool_)
    if max_gap_s <= 0 or floor.n == 0 or v.all() or not v.any():
        return pos, quat, v, 0
    p = np.where(v[:, None], np.asarray(pos, np.float64), 0.0)
    q = np.where(v[:, None], np.asarray(quat, np.float64), 0.0)
    p_out, q_out, v_out, filled = _fill(
        np.ascontiguousarray(t, dtype=np.float64),
        np.ascontiguousarray(p),
        np.ascontiguousarray(q),
        v,
        float(floor.pos),
        float(floor.rot),
        float(max_gap_s),
        int(side),
        float(REST_FACTOR),
    )
    keep = ~v_out
    p_out[keep] = np.asarray(pos, np.float64)[keep]
    q_out[keep] = np.asarray(quat, np.float64)[keep]
    return p_out, q_out, v_out, int(filled)


__all__ = ["fill_static_gaps"]
