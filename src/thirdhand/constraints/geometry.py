"""Closed-form, weighted geometric fits behind the constraint models.

Every function takes per-sample weights ``w (n,)`` (non-negative, not all zero)
so that the robust loop of :mod:`thirdhand.constraints.models` can reweight
samples without changing the maths. Quaternions are x y z w; nothing here needs
sign continuity (the fits work on ``q qᵀ`` or on a plane through the origin of
R⁴, both blind to the sign of ``q``).

The per-sample loops (and the small eigen- and least-squares problems they feed)
are compiled with numba (``cache=True``); each compiled function is called with
C-contiguous float64 arrays only, so that it has a single cached signature.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from thirdhand.arrays import FloatArray
from thirdhand.se3_compiled import qmul

_TWO_PI = 2.0 * math.pi


def weighted_mean(x: FloatArray, w: FloatArray) -> FloatArray:
    """Weighted mean of rows ``x (n, k)`` with weights ``w (n,)``, shape (k,)."""
    return np.asarray(w @ x / w.sum(), dtype=np.float64)


def weighted_cov(x: FloatArray, w: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Weighted mean (k,) and scatter matrix (k, k) of rows ``x (n, k)``."""
    return _moments(np.ascontiguousarray(x, dtype=np.float64), np.ascontiguousarray(w))


@njit(cache=True, error_model="numpy")
def _moments(x: FloatArray, w: FloatArray) -> tuple[FloatArray, FloatArray]:  # pragma: no cover
    n, k = x.shape
    sw = 0.0
    m = np.zeros(k)
    for i in range(n):
        sw += w[i]
        for a in range(k):
            m[a] += w[i] * x[i, a]
    m /= sw
    cov = np.zeros((k, k))
    d = np.empty(k)
    for i in range(n):
        if w[i] == 0.0:
            continue
        for a in range(k):
            d[a] = x[i, a] - m[a]
        for a in range(k):
            wa = w[i] * d[a]
            for b in range(a, k):
                cov[a, b] += wa * d[b]
    for a in range(k):
        for b in range(a, k):
            cov[a, b] /= sw
            cov[b, a] = cov[a, b]
    return m, cov


@njit(cache=True, error_model="numpy")
def col_ptp(x: FloatArray) -> FloatArray:  # pragma: no cover - compiled
    """Range (max - min) of each column of finite ``x (n, k)``, shape (k,)."""
    out = np.empty(x.shape[1])
    for a in range(x.shape[1]):
        lo = x[0, a]
        hi = x[0, a]
        for i in range(1, x.shape[0]):
            lo = min(lo, x[i, a])
            hi = max(hi, x[i, a])
        out[a] = hi - lo
    return out


@njit(cache=True, error_model="numpy")
def col_median(x: FloatArray) -> FloatArray:  # pragma: no cover - compiled
    """Median of each column of ``x (n, k)``, shape (k,)."""
    out = np.empty(x.shape[1])
    for a in range(x.shape[1]):
        out[a] = np.median(x[:, a])
    return out


@njit(cache=True, error_model="numpy")
def masked_median(x: FloatArray, w: FloatArray) -> float:  # pragma: no cover - compiled
    """Median of the entries of ``x (n,)`` whose weight ``w (n,)`` is positive."""
    return float(np.median(x[w > 0.0]))


@njit(cache=True, error_model="numpy")
def quat_scatter(q: FloatArray, w: FloatArray) -> FloatArray:  # pragma: no cover - compiled
    """``Σ w q qᵀ`` of quaternion rows ``q (n, 4)`` and weights ``w (n,)``, shape (4, 4)."""
    m = np.zeros((4, 4))
    for i in range(q.shape[0]):
        if w[i] == 0.0:
            continue
        for a in range(4):
            wa = w[i] * q[i, a]
            for b in range(a, 4):
                m[a, b] += wa * q[i, b]
    for a in range(4):
        for b in range(a + 1, 4):
            m[b, a] = m[a, b]
    return m


def quat_average(q: FloatArray, w: FloatArray) -> FloatArray:
    """Weighted average orientation: the top eigenvector of ``Σ w q qᵀ`` (Markley).

    Parameters
    ----------
    q : ndarray, shape (n, 4)
        Unit quaternions x y z w, any signs.
    w : ndarray, shape (n,)

    Returns
    -------
    ndarray, shape (4,)
        Unit quaternion with ``w >= 0``.
    """
    return _quat_top(q, w)


@njit(cache=True, error_model="numpy")
def _quat_top(q: FloatArray, w: FloatArray) -> FloatArray:  # pragma: no cover - compiled
    """Top eigenvector (4,) of ``Σ w q qᵀ``, sign ``w >= 0``."""
    _, vec = np.linalg.eigh(quat_scatter(q, w))
    out = vec[:, 3].copy()
    return out if out[3] >= 0 else -out


def cross3(a: FloatArray, b: FloatArray) -> FloatArray:
    """Cross product of 3-vectors, broadcasting, shape (..., 3) (cheaper than ``np.cross``)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def quat_right_matrix(p: FloatArray) -> FloatArray:
    """Matrix (4, 4) with ``q @ M = q ⊗ p`` for quaternion rows ``q``: one matmul per track."""
    x, y, z, w = (float(c) for c in p)
    return np.array(
        [
            [w, -z, y, -x],
            [z, w, -x, -y],
            [-y, x, w, -z],
            [x, y, z, w],
        ]
    )


def quat_axis_angle(axis: FloatArray, angle: FloatArray) -> FloatArray:
    """Quaternions (n, 4) of rotations by ``angle (n,)`` radians about unit ``axis (3,)``."""
    half = 0.5 * angle
    out = np.empty((angle.shape[0], 4))
    out[:, :3] = np.sin(half)[:, None] * axis
    out[:, 3] = np.cos(half)
    return out


def rotate_about(axis: FloatArray, angle: FloatArray, v: FloatArray) -> FloatArray:
    """Rotate one vector ``v (3,)`` by each of ``angle (n,)`` about unit ``axis (3,)``.

    Rodrigues' formula, vectorised; shape (n, 3).
    """
    par = (v @ axis) * axis
    return np.asarray(
        np.outer(np.cos(angle), v - par) + np.outer(np.sin(angle), cross3(axis, v)) + par,
        dtype=np.float64,
    )


def wrap_angle(a: FloatArray) -> FloatArray:
    """Angles wrapped to [-π, π), radians."""
    return np.asarray((a + np.pi) % (2.0 * np.pi) - np.pi, dtype=np.float64)


def unwrap_masked(theta: FloatArray, mask: NDArray[np.bool_]) -> FloatArray:
    """Unwrap angles in time along the ``mask`` samples only; others join their neighbour.

    ``np.unwrap`` over every sample lets two consecutive outliers shift the rest of
    the track by 2π (the positions and rotations are the same, but the range is
    not). Unwrapping the inliers alone and putting each outlier on the branch of the
    last inlier before it (the first inlier, for leading outliers) avoids that.

    Parameters
    ----------
    theta : ndarray, shape (n,)
        Angles, radians, any branch.
    mask : ndarray of bool, shape (n,)

    Returns
    -------
    ndarray, shape (n,)
    """
    return _unwrap_masked(np.ascontiguousarray(theta, dtype=np.float64), np.ascontiguousarray(mask))


@njit(cache=True, error_model="numpy")
def _wrap(a: float) -> float:
    """Angle ``a`` wrapped to [-π, π), radians (as :func:`wrap_angle`)."""
    return (a + math.pi) % _TWO_PI - math.pi


@njit(cache=True, error_model="numpy")
def _unwrap(p: FloatArray) -> FloatArray:  # pragma: no cover - compiled
    """``np.unwrap`` of a 1-D array (same arithmetic, sequential cumulative sum)."""
    out = p.copy()
    acc = 0.0
    for i in range(1, p.shape[0]):
        dd = p[i] - p[i - 1]
        ddmod = (dd + math.pi) % _TWO_PI - math.pi
        if ddmod == -math.pi and dd > 0.0:
            ddmod = math.pi
        if abs(dd) >= math.pi:
            acc += ddmod - dd
        out[i] = p[i] + acc
    return out


@njit(cache=True, error_model="numpy")
def _unwrap_masked(theta: FloatArray, mask: NDArray[np.bool_]) -> FloatArray:  # pragma: no cover
    """Compiled :func:`unwrap_masked`."""
    n = theta.shape[0]
    idx = np.flatnonzero(mask)
    if idx.size == 0 or idx.size == n:
        return _unwrap(theta)
    ref_in = _unwrap(theta[idx])
    out = np.empty(n)
    k = -1
    for i in range(n):
        while k + 1 < idx.size and idx[k + 1] <= i:
            k += 1
        ref = ref_in[max(k, 0)]
        out[i] = ref + _wrap(theta[i] - ref)
    for j in range(idx.size):
        out[idx[j]] = ref_in[j]
    return out


def rotation_plane_axis(q: FloatArray, w: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Axis of a one-parameter rotation family ``q_i = q(a, θ_i) ⊗ q_0``, and its angles.

    All such quaternions lie in the plane of R⁴ spanned by ``q_0`` and
    ``(a, 0) ⊗ q_0``. The plane is the span of the top two eigenvectors ``u, v``
    of ``Σ w q qᵀ`` and, ``u`` and ``v`` being orthogonal, ``v ⊗ u⁻¹ = (±a, 0)``.

    Parameters
    ----------
    q : ndarray, shape (n, 4)
        Unit quaternions x y z w, any signs.
    w : ndarray, shape (n,)

    Returns
    -------
    axis : ndarray, shape (3,)
        Unit rotation axis, in the frame the quaternions are expressed in.
    theta : ndarray, shape (n,)
        Rotation angles about ``axis`` relative to ``q0``, radians, unwrapped in time
        over the samples of positive weight (see :func:`unwrap_masked`).
    q0 : ndarray, shape (4,)
        The orientation at ``theta = 0``, unit quaternion.
    """
    return _rotation_plane(q, w)


@njit(cache=True, error_model="numpy")
def _rotation_plane(
    q: FloatArray, w: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:  # pragma: no cover - compiled
    """Compiled :func:`rotation_plane_axis`: axis (3,), angles (n,), ``q0`` (4,)."""
    _, vec = np.linalg.eigh(quat_scatter(q, w))
    u = vec[:, 3].copy()
    axis, theta = _plane_angles(q, u, vec[:, 2].copy(), w > 0)
    return axis, theta, u


@njit(cache=True, error_model="numpy")
def _plane_angles(
    q: FloatArray, u: FloatArray, v: FloatArray, mask: NDArray[np.bool_]
) -> tuple[FloatArray, FloatArray]:  # pragma: no cover - compiled
    """Axis ``v ⊗ u⁻¹`` (3,) and the unwrapped angles (n,) of :func:`rotation_plane_axis`."""
    x, y, z, _ = qmul(v[0], v[1], v[2], v[3], -u[0], -u[1], -u[2], u[3])
    norm = math.sqrt(x * x + y * y + z * z)
    axis = np.array([x / norm, y / norm, z / norm])
    # q = cos α u + sin α v_exact = q(a, 2α) ⊗ u; the sign of q only shifts θ by 2π.
    ve = qmul(axis[0], axis[1], axis[2], 0.0, u[0], u[1], u[2], u[3])
    theta = np.empty(q.shape[0])
    for i in range(q.shape[0]):
        cu = q[i, 0] * u[0] + q[i, 1] * u[1] + q[i, 2] * u[2] + q[i, 3] * u[3]
        cv = q[i, 0] * ve[0] + q[i, 1] * ve[1] + q[i, 2] * ve[2] + q[i, 3] * ve[3]
        theta[i] = 2.0 * math.atan2(cv, cu)
    return axis, _unwrap_masked(theta, mask)


def plane_fit(p: FloatArray, w: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Weighted principal axes of points.

    Parameters
    ----------
    p : ndarray, shape (n, 3)
    w : ndarray, shape (n,)

    Returns
    -------
    centroid : ndarray, shape (3,)
    axes : ndarray, shape (3, 3)
        Rows are unit principal directions, largest spread first (row 0 is the
        best line direction, row 2 the plane normal).
    variances : ndarray, shape (3,)
        Weighted variance along each row of ``axes``, decreasing.
    """
    return _plane_fit(np.ascontiguousarray(p, dtype=np.float64), w)


@njit(cache=True, error_model="numpy")
def _plane_fit(
    p: FloatArray, w: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:  # pragma: no cover - compiled
    """Compiled :func:`plane_fit`."""
    m, cov = _moments(p, w)
    val, vec = np.linalg.eigh(cov)
    return m, vec[:, ::-1].T.copy(), val[::-1].copy()


def circle_fit_2d(
    xy: FloatArray, w: FloatArray, *, iterations: int = 5
) -> tuple[FloatArray, float]:
    """Weighted circle fit in the plane: algebraic (Kåsa) start, geometric refinement.

    Parameters
    ----------
    xy : ndarray, shape (n, 2)
        Points, metres.
    w : ndarray, shape (n,)
    iterations : int
        Gauss-Newton steps on the geometric distance ``| |x - c| - r |``.

    Returns
    -------
    centre : ndarray, shape (2,)
    radius : float
        ``inf`` when the points are collinear (no finite circle).
    """
    return _circle_fit(np.ascontiguousarray(xy, dtype=np.float64), w, iterations)


@njit(cache=True, error_model="numpy")
def _circle_fit(
    xy: FloatArray, w: FloatArray, iterations: int
) -> tuple[FloatArray, float]:  # pragma: no cover - compiled
    n = xy.shape[0]
    ata = np.zeros((3, 3))
    atb = np.zeros(3)
    row = np.empty(3)
    for i in range(n):
        x = xy[i, 0]
        y = xy[i, 1]
        row[0], row[1], row[2] = x, y, 1.0
        b = -(x * x + y * y)
        for a in range(3):
            wa = row[a] * w[i]
            atb[a] += wa * b
            for k in range(3):
                ata[a, k] += wa * row[k]
    nan2 = np.full(2, np.nan)
    if np.linalg.cond(ata) > 1e14:
        return nan2, math.inf
    sol = np.linalg.solve(ata, atb)
    c = np.array([-0.5 * sol[0], -0.5 * sol[1]])
    r2 = c[0] * c[0] + c[1] * c[1] - sol[2]
    if not np.isfinite(r2) or r2 <= 0.0:
        return nan2, math.inf
    r = math.sqrt(r2)
    jtj = np.zeros((3, 3))
    jtr = np.zeros(3)
    for _ in range(iterations):
        jtj[:] = 0.0
        jtr[:] = 0.0
        for i in range(n):
            d0 = xy[i, 0] - c[0]
            d1 = xy[i, 1] - c[1]
            dist = math.sqrt(d0 * d0 + d1 * d1)
            if not dist > 1e-15:
                dist = 1e-15
            res = dist - r
            row[0], row[1], row[2] = -d0 / dist, -d1 / dist, -1.0
            for a in range(3):
                wa = row[a] * w[i]
                jtr[a] += wa * res
                for b in range(3):
                    jtj[a, b] += wa * row[b]
        if np.linalg.cond(jtj) > 1e14:
            break
        step = np.linalg.solve(jtj, -jtr)
        c[0] += step[0]
        c[1] += step[1]
        r = r + step[2]
        if max(abs(step[0]), abs(step[1]), abs(step[2])) < 1e-15 * max(1.0, abs(r)):
            break
    return c, abs(r)


def revolute_centre(
    p: FloatArray, axis: FloatArray, theta: FloatArray, w: FloatArray, *, planar: bool = False
) -> tuple[FloatArray, FloatArray]:
    """Least-squares centre of rotation given the axis and the angles.

    Solves ``p_i ≈ c + R(a, θ_i) u`` for the centre ``c`` and lever ``u``. The
    component of ``c`` along the axis is not observable; it is chosen so that
    ``c`` is the point of the axis nearest the weighted centroid of ``p``.

    Parameters
    ----------
    p : ndarray, shape (n, 3)
        Positions, metres, parent frame.
    axis : ndarray, shape (3,)
        Unit axis, parent frame.
    theta : ndarray, shape (n,)
        Rotation angles, radians.
    w : ndarray, shape (n,)
    planar : bool
        Fit only the components orthogonal to the axis (a cylindrical joint, whose
        translation along the axis is free).

    Returns
    -------
    centre : ndarray, shape (3,)
        A point of the axis, metres, parent frame.
    lever : ndarray, shape (3,)
        ``u``: the child's position relative to ``centre`` at ``θ = 0``.
    """
    return _revolute_centre(p, axis, np.ascontiguousarray(theta), w, planar)


@njit(cache=True, error_model="numpy")
def _revolute_centre(
    p: FloatArray, axis: FloatArray, theta: FloatArray, w: FloatArray, planar: bool
) -> tuple[FloatArray, FloatArray]:  # pragma: no cover - compiled
    """Compiled :func:`revolute_centre`: centre (3,) and lever (3,), metres."""
    n, rhs, mean = _centre_system(p, axis, theta, w, planar)
    sol = np.linalg.lstsq(n, rhs, rcond=1e-12)[0].astype(np.float64)
    return _centre_shift(sol, axis, mean, planar)


@njit(cache=True, error_model="numpy")
def _centre_system(
    p: FloatArray, axis: FloatArray, theta: FloatArray, w: FloatArray, planar: bool
) -> tuple[FloatArray, FloatArray, FloatArray]:  # pragma: no cover - compiled
    """Normal equations of min Σ w |P (c + R_i u - p_i)|², P the projection (6, 6), (6,),
    and the weighted centroid of ``p`` (3,)."""
    sw = 0.0
    sc = 0.0
    ss = 0.0
    wps = np.zeros(3)
    rtp = np.zeros(3)
    a0, a1, a2 = axis[0], axis[1], axis[2]
    for i in range(p.shape[0]):
        wi = w[i]
        if wi == 0.0:
            continue
        c = math.cos(theta[i])
        s = math.sin(theta[i])
        sw += wi
        sc += wi * c
        ss += wi * s
        x0 = wi * p[i, 0]
        x1 = wi * p[i, 1]
        x2 = wi * p[i, 2]
        wps[0] += x0
        wps[1] += x1
        wps[2] += x2
        # R_iᵀ p_i = cos p + sin (p × a) + (1 - cos) (p · a) a.
        pa = (1.0 - c) * (x0 * a0 + x1 * a1 + x2 * a2)
        rtp[0] += c * x0 + s * (x1 * a2 - x2 * a1) + pa * a0
        rtp[1] += c * x1 + s * (x2 * a0 - x0 * a2) + pa * a1
        rtp[2] += c * x2 + s * (x0 * a1 - x1 * a0) + pa * a2
    ax = np.outer(axis, axis)
    skew = np.array([[0.0, -a2, a1], [a2, 0.0, -a0], [-a1, a0, 0.0]])
    eye = np.eye(3)
    # Σ w R_i, with R_i = cos I + sin K + (1 - cos) a aᵀ.
    sum_r = sc * eye + ss * skew + (sw - sc) * ax
    proj = eye - ax if planar else eye
    n = np.zeros((6, 6))
    n[:3, :3] = sw * proj
    n[:3, 3:] = proj @ sum_r
    n[3:, :3] = sum_r.T @ proj
    # Σ w R_iᵀ P R_i = P Σ w (R commutes with P); for P = I it is Σ w I.
    n[3:, 3:] = sw * proj
    rhs = np.empty(6)
    rhs[:3] = proj @ wps
    rhs[3:] = proj @ rtp
    return n, rhs, wps / sw


@njit(cache=True, error_model="numpy")
def _centre_shift(
    sol: FloatArray, axis: FloatArray, mean: FloatArray, planar: bool
) -> tuple[FloatArray, FloatArray]:  # pragma: no cover - compiled
    """Slide the centre along the axis to the point nearest ``mean``."""
    centre = sol[:3].copy()
    lever = sol[3:].copy()
    shift = axis[0] * (mean[0] - centre[0])
    shift += axis[1] * (mean[1] - centre[1])
    shift += axis[2] * (mean[2] - centre[2])
    centre += shift * axis
    lever -= shift * axis
    if planar:
        lever -= (lever[0] * axis[0] + lever[1] * axis[1] + lever[2] * axis[2]) * axis
    return centre, lever


def refine_axis_with_plane(
    axis: FloatArray, p: FloatArray, theta: FloatArray, w: FloatArray, ratio: float
) -> FloatArray:
    """Combine a rotation axis with the normal of the plane the positions turn in.

    The axis from the rotations alone is off by the rotation noise; a revolute
    joint's positions lie in a plane normal to the axis, which tilts it back.
    Linearised about ``axis``, with the tilt ``δ ⊥ axis``: the positions give
    ``S δ = -P C a`` (``C`` their weighted scatter, ``P = I - a aᵀ``,
    ``S = P C P``), in units of ``1/σ_pos²``; the rotations pin ``δ = 0`` with
    information ``Σ w (θ - θ̄)² / σ_rot²``. The two are added.

    Parameters
    ----------
    axis : ndarray, shape (3,)
        Unit axis from the rotations.
    p : ndarray, shape (n, 3)
        Positions, metres.
    theta : ndarray, shape (n,)
        Angles about ``axis``, radians.
    w : ndarray, shape (n,)
    ratio : float
        ``σ_pos / σ_rot``, metres per radian.

    Returns
    -------
    ndarray, shape (3,)
        Unit axis, same sign as ``axis``.
    """
    return _refine_axis(axis, p, np.ascontiguousarray(theta), w, float(ratio))


@njit(cache=True, error_model="numpy")
def _refine_axis(
    axis: FloatArray, p: FloatArray, theta: FloatArray, w: FloatArray, ratio: float
) -> FloatArray:  # pragma: no cover - compiled
    """Compiled :func:`refine_axis_with_plane`: unit axis (3,)."""
    _, cov = _moments(p, w)
    sw = 0.0
    st = 0.0
    for i in range(w.shape[0]):
        sw += w[i]
        st += w[i] * theta[i]
    t_mean = st / sw
    var = 0.0
    for i in range(w.shape[0]):
        var += w[i] * (theta[i] - t_mean) ** 2
    info_rot = ratio * ratio * var / sw
    aa = np.outer(axis, axis)
    proj = np.eye(3) - aa
    lhs = proj @ cov @ proj + info_rot * proj + aa
    # Minimum-norm solution: a direction neither the plane nor the rotations
    # determine (a straight track, no rotation) keeps the rotation axis.
    delta = np.linalg.lstsq(lhs, -(proj @ cov @ axis), rcond=1e-9)[0]
    out = axis + proj @ delta
    return out / math.sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2])
