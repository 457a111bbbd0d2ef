"""Compiled (numba) companions of :mod:`thirdhand.se3` for per-frame loops.

Same conventions (x y z w quaternions, "pose of B in A"); each kernel is tested
against its numpy original in ``tests/test_se3.py``.
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


@numba.njit(cache=True, nogil=True)
def continuous_quat_rows(q: FloatArray, valid: BoolArray) -> FloatArray:  # pragma: no cover
    """Sign-continuous copy of a quaternion track, shape (n, 4); invalid rows skipped.

    The compiled twin of :func:`thirdhand.se3.quat_make_continuous`.
    """
    out = q.copy()
    have = False
    prev = np.zeros(4)
    for i in range(q.shape[0]):
        if not valid[i]:
            continue
        if have:
            dot = 0.0
            for j in range(4):
                dot += out[i, j] * prev[j]
            if dot < 0.0:
                for j in range(4):
                    out[i, j] = -out[i, j]
        for j in range(4):
            prev[j] = out[i, j]
        have = True
    return out


@numba.njit(cache=True, nogil=True)
def relative_pose_rows(  # pragma: no cover - compiled
    pa: FloatArray, qa: FloatArray, pb: FloatArray, qb: FloatArray, valid: BoolArray
) -> tuple[FloatArray, FloatArray]:
    """B's pose in A's frame per frame, ``(p (n, 3), q (n, 4))``; zeros where invalid.

    The compiled twin of :func:`thirdhand.se3.relative_pose` followed by
    :func:`thirdhand.se3.quat_make_continuous` over the valid frames.
    """
    n = pa.shape[0]
    dp = np.zeros((n, 3))
    dq = np.zeros((n, 4))
    have = False
    p0 = 0.0
    p1 = 0.0
    p2 = 0.0
    p3 = 0.0
    for i in range(n):
        if not valid[i]:
            continue
        # conj(qa) = (-x, -y, -z, w)
        x1 = -qa[i, 0]
        y1 = -qa[i, 1]
        z1 = -qa[i, 2]
        w1 = qa[i, 3]
        vx = pb[i, 0] - pa[i, 0]
        vy = pb[i, 1] - pa[i, 1]
        vz = pb[i, 2] - pa[i, 2]
        # v + w t + u x t with t = 2 u x v
        tx = 2.0 * (y1 * vz - z1 * vy)
        ty = 2.0 * (z1 * vx - x1 * vz)
        tz = 2.0 * (x1 * vy - y1 * vx)
        dp[i, 0] = vx + w1 * tx + (y1 * tz - z1 * ty)
        dp[i, 1] = vy + w1 * ty + (z1 * tx - x1 * tz)
        dp[i, 2] = vz + w1 * tz + (x1 * ty - y1 * tx)
        x2 = qb[i, 0]
        y2 = qb[i, 1]
        z2 = qb[i, 2]
        w2 = qb[i, 3]
        rx = w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2
        ry = w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2
        rz = w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2
        rw = w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2
        if have and rx * p0 + ry * p1 + rz * p2 + rw * p3 < 0.0:
            rx = -rx
            ry = -ry
            rz = -rz
            rw = -rw
        dq[i, 0] = rx
        dq[i, 1] = ry
        dq[i, 2] = rz
        dq[i, 3] = rw
        p0, p1, p2, p3 = rx, ry, rz, rw
        have = True
    return dp, dq
