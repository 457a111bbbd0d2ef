"""Compiled (numba) companions of :mod:`thirdhand.se3` for per-frame loops.

Same conventions (x y z w quaternions, "pose of B in A"); each kernel is tested
against its numpy original in ``tests/test_se3.py``.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from thirdhand.arrays import BoolArray, FloatArray


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


# Small per-sample rotation kernels, called from other compiled loops (the
# constraint fits); floating-point errors follow numpy (``error_model``).


@numba.njit(cache=True, error_model="numpy")
def cross_one(a: FloatArray, b: FloatArray) -> FloatArray:  # pragma: no cover - compiled
    """Cross product of two 3-vectors, compiled."""
    return np.array(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )


@numba.njit(cache=True, error_model="numpy")
def qmul(
    ax: float, ay: float, az: float, aw: float, bx: float, by: float, bz: float, bw: float
) -> tuple[float, float, float, float]:  # pragma: no cover - compiled
    """Hamilton product ``a ⊗ b`` of x y z w quaternions given by components."""
    return (
        aw * bx + bw * ax + (ay * bz - az * by),
        aw * by + bw * ay + (az * bx - ax * bz),
        aw * bz + bw * az + (ax * by - ay * bx),
        aw * bw - (ax * bx + ay * by + az * bz),
    )


@numba.njit(cache=True, error_model="numpy")
def quat_from_frame(m: FloatArray) -> FloatArray:  # pragma: no cover - compiled
    """Unit quaternion x y z w of a rotation matrix ``m (3, 3)`` (Shepperd's method)."""
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    choice = 3
    best = tr
    for i in range(3):
        if m[i, i] > best:
            best = m[i, i]
            choice = i
    q = np.empty(4)
    if choice == 3:
        q[0] = m[2, 1] - m[1, 2]
        q[1] = m[0, 2] - m[2, 0]
        q[2] = m[1, 0] - m[0, 1]
        q[3] = 1.0 + tr
    else:
        i = choice
        j = (i + 1) % 3
        k = (j + 1) % 3
        q[i] = 1.0 - tr + 2.0 * m[i, i]
        q[j] = m[j, i] + m[i, j]
        q[k] = m[k, i] + m[i, k]
        q[3] = m[k, j] - m[j, k]
    return q / math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])


@numba.njit(cache=True, error_model="numpy")
def frame_from_axes(x: FloatArray, y_hint: FloatArray) -> FloatArray:  # pragma: no cover
    """Quaternion (4,) of a frame whose x axis is unit ``x (3,)`` and whose y axis is
    nearest ``y_hint (3,)`` (any perpendicular when ``y_hint`` is along ``x``)."""
    y = y_hint - (y_hint[0] * x[0] + y_hint[1] * x[1] + y_hint[2] * x[2]) * x
    if math.sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2]) < 1e-9:
        # Any perpendicular: the parent axis least aligned with x.
        k = int(np.argmin(np.abs(x)))
        y = -x[k] * x
        y[k] += 1.0
    y = y / math.sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2])
    z = cross_one(x, y)
    m = np.empty((3, 3))
    m[:, 0] = x
    m[:, 1] = y
    m[:, 2] = z
    return quat_from_frame(m)


@numba.njit(cache=True, error_model="numpy")
def rotate_one(q: FloatArray, v: FloatArray) -> FloatArray:  # pragma: no cover - compiled
    """Rotate ``v (3,)`` by unit quaternion ``q (4,)``."""
    u = q[:3].copy()
    t = 2.0 * cross_one(u, v)
    return v + q[3] * t + cross_one(u, t)


@numba.njit(cache=True, error_model="numpy")
def align_x(q: FloatArray, axis: FloatArray) -> FloatArray:  # pragma: no cover - compiled
    """Turn orientation ``q (4,)`` by the smallest rotation taking its x axis to unit
    ``axis (3,)``; shape (4,)."""
    x = rotate_one(q, np.array([1.0, 0.0, 0.0]))
    cos = x[0] * axis[0] + x[1] * axis[1] + x[2] * axis[2]
    turn = np.empty(4)
    if cos < -1.0 + 1e-12:
        turn[:3] = rotate_one(q, np.array([0.0, 1.0, 0.0]))
        turn[3] = 0.0
    else:
        turn[:3] = cross_one(x, axis)
        turn[3] = 1.0 + cos
    turn /= math.sqrt(turn[0] ** 2 + turn[1] ** 2 + turn[2] ** 2 + turn[3] ** 2)
    return np.array(qmul(turn[0], turn[1], turn[2], turn[3], q[0], q[1], q[2], q[3]))


@numba.njit(cache=True, error_model="numpy")
def rotvec_scale(x: float, y: float, z: float, w: float) -> float:
    """Factor taking the vector part of a unit quaternion to its rotation vector.

    ``(x, y, z) * rotvec_scale(x, y, z, w)`` is :func:`thirdhand.se3.rotvec_from_quat`
    of ``(x, y, z, w)``: angle in [0, π], the shorter of ``q`` and ``-q``.
    """
    norm = math.sqrt(x * x + y * y + z * z)
    # angle / sin(angle / 2) -> 2 as the angle goes to 0; the sign of w picks the
    # shorter of the two rotations q and -q describe.
    scale = 2.0 if norm < 1e-12 else 2.0 * math.atan2(norm, abs(w)) / norm
    return -scale if w < 0.0 else scale
