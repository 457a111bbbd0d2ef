"""Closed-form, weighted geometric fits behind the constraint models.

Every function takes per-sample weights ``w (n,)`` (non-negative, not all zero)
so that the robust loop of :mod:`thirdhand.constraints.models` can reweight
samples without changing the maths. Quaternions are x y z w; nothing here needs
sign continuity (the fits work on ``q qᵀ`` or on a plane through the origin of
R⁴, both blind to the sign of ``q``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def weighted_mean(x: FloatArray, w: FloatArray) -> FloatArray:
    """Weighted mean of rows ``x (n, k)`` with weights ``w (n,)``, shape (k,)."""
    return np.asarray(w @ x / w.sum(), dtype=np.float64)


def weighted_cov(x: FloatArray, w: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Weighted mean (k,) and scatter matrix (k, k) of rows ``x (n, k)``."""
    m = weighted_mean(x, w)
    d = x - m
    return m, np.asarray((d * w[:, None]).T @ d / w.sum(), dtype=np.float64)


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
    m = (q * w[:, None]).T @ q
    _, vec = np.linalg.eigh(m)
    out = vec[:, -1]
    return np.asarray(out if out[3] >= 0 else -out, dtype=np.float64)


def cross3(a: FloatArray, b: FloatArray) -> FloatArray:
    """Cross product of 3-vectors, broadcasting, shape (..., 3) (cheaper than ``np.cross``)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def quat_mul(a: FloatArray, b: FloatArray) -> FloatArray:
    """Hamilton product ``a ⊗ b`` of x y z w quaternions, broadcasting, shape (..., 4)."""
    av, aw = a[..., :3], a[..., 3:]
    bv, bw = b[..., :3], b[..., 3:]
    vec = aw * bv + bw * av + cross3(av, bv)
    sc = aw * bw - np.sum(av * bv, axis=-1, keepdims=True)
    return np.concatenate([vec, sc], axis=-1)


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


def quat_conj(q: FloatArray) -> FloatArray:
    """Conjugate of x y z w quaternions, shape (..., 4)."""
    return q * np.array([-1.0, -1.0, -1.0, 1.0])


def quat_log(q: FloatArray) -> FloatArray:
    """Rotation vectors (n, 3), radians, of unit quaternions (n, 4), angle in [0, π]."""
    v = q[:, :3]
    s = np.abs(q[:, 3])
    norm = np.sqrt(np.einsum("ij,ij->i", v, v))
    # angle / sin(angle / 2) -> 2 as the angle goes to 0; the sign of w picks the
    # shorter of the two rotations q and -q describe.
    small = norm < 1e-12
    scale = 2.0 * np.arctan2(norm, s) / np.where(small, 1.0, norm)
    scale[small] = 2.0
    scale *= np.where(q[:, 3] < 0.0, -1.0, 1.0)
    return np.asarray(v * scale[:, None], dtype=np.float64)


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
    idx = np.flatnonzero(mask)
    if idx.size == 0 or idx.size == theta.shape[0]:
        return np.asarray(np.unwrap(theta), dtype=np.float64)
    ref_in = np.unwrap(theta[idx])
    nearest = np.clip(np.searchsorted(idx, np.arange(theta.shape[0]), side="right") - 1, 0, None)
    ref = ref_in[nearest]
    out = ref + wrap_angle(theta - ref)
    out[idx] = ref_in
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
    m = (q * w[:, None]).T @ q
    _, vec = np.linalg.eigh(m)
    u: FloatArray = np.asarray(vec[:, 3], dtype=np.float64)
    v: FloatArray = np.asarray(vec[:, 2], dtype=np.float64)
    axis = quat_mul(v, quat_conj(u))[:3]
    axis = axis / np.linalg.norm(axis)
    v_exact = quat_mul(np.append(axis, 0.0), u)
    # q = cos α u + sin α v_exact = q(a, 2α) ⊗ u; the sign of q only shifts θ by 2π.
    theta = unwrap_masked(2.0 * np.arctan2(q @ v_exact, q @ u), w > 0)
    return axis, np.asarray(theta, dtype=np.float64), u


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
    m, cov = weighted_cov(p, w)
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
    x, y = xy[:, 0], xy[:, 1]
    a = np.stack([x, y, np.ones_like(x)], axis=1)
    b = -(x * x + y * y)
    aw = a * w[:, None]
    ata = aw.T @ a
    atb = aw.T @ b
    if np.linalg.cond(ata) > 1e14:
        return np.full(2, np.nan), float("inf")
    d, e, f = np.linalg.solve(ata, atb)
    c = np.array([-0.5 * d, -0.5 * e])
    r2 = c @ c - f
    if not np.isfinite(r2) or r2 <= 0.0:
        return np.full(2, np.nan), float("inf")
    r = float(np.sqrt(r2))
    for _ in range(iterations):
        diff = xy - c
        dist = np.linalg.norm(diff, axis=1)
        dist = np.where(dist > 1e-15, dist, 1e-15)
        res = dist - r
        jac = np.empty((xy.shape[0], 3))
        jac[:, :2] = -diff / dist[:, None]
        jac[:, 2] = -1.0
        jw = jac * w[:, None]
        jtj = jw.T @ jac
        if np.linalg.cond(jtj) > 1e14:
            break
        step = np.linalg.solve(jtj, -(jw.T @ res))
        c = c + step[:2]
        r = r + float(step[2])
        if np.max(np.abs(step)) < 1e-15 * max(1.0, abs(r)):
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
    c_t = np.cos(theta)
    s_t = np.sin(theta)
    ax = np.outer(axis, axis)
    skew = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    eye = np.eye(3)
    sw = w.sum()
    sc = w @ c_t
    ss = w @ s_t
    # Σ w R_i, with R_i = cos I + sin K + (1 - cos) a aᵀ.
    sum_r = sc * eye + ss * skew + (sw - sc) * ax
    proj = eye - ax if planar else eye
    # Normal equations of min Σ w |P (c + R_i u - p_i)|², P the projection.
    n = np.zeros((6, 6))
    n[:3, :3] = sw * proj
    n[:3, 3:] = proj @ sum_r
    n[3:, :3] = sum_r.T @ proj
    # Σ w R_iᵀ P R_i = P Σ w (R commutes with P); for P = I it is Σ w I.
    n[3:, 3:] = sw * proj
    wp = p * w[:, None]
    rhs = np.empty(6)
    rhs[:3] = proj @ wp.sum(axis=0)
    # Σ w R_iᵀ p_i; as rows, Kᵀ p is p @ K.
    rtp = c_t @ wp + s_t @ (wp @ skew) + ((1.0 - c_t) @ (wp @ axis)) * axis
    rhs[3:] = proj @ rtp
    sol = np.linalg.lstsq(n, rhs, rcond=1e-12)[0]
    centre, lever = sol[:3], sol[3:]
    mean = wp.sum(axis=0) / sw
    shift = axis @ (mean - centre)
    centre = centre + shift * axis
    lever = lever - shift * axis
    if planar:
        lever = lever - (lever @ axis) * axis
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
    _, cov = weighted_cov(p, w)
    sw = w.sum()
    t_mean = (w @ theta) / sw
    info_rot = ratio * ratio * (w @ (theta - t_mean) ** 2) / sw
    proj = np.eye(3) - np.outer(axis, axis)
    lhs = proj @ cov @ proj + info_rot * proj + np.outer(axis, axis)
    # Minimum-norm solution: a direction neither the plane nor the rotations
    # determine (a straight track, no rotation) keeps the rotation axis.
    delta = np.linalg.lstsq(lhs, -(proj @ cov @ axis), rcond=1e-9)[0]
    out = axis + proj @ delta
    return np.asarray(out / np.linalg.norm(out), dtype=np.float64)
