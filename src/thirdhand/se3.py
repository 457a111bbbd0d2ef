"""Pose helpers: unit quaternions in x, y, z, w order and rigid transforms.

Conventions
-----------
- Quaternions are stored scalar-last, ``(x, y, z, w)``, as scipy, ROS and Motive do.
- A pose "of B in A", ``(p_AB, q_AB)``, maps B's coordinates into A's:
  ``x_A = R(q_AB) x_B + p_AB``.
- Every function broadcasts over leading axes: ``q`` may be ``(4,)`` or ``(..., 4)``.

The algebra is written directly in numpy (Hamilton product, rotation of
vectors) because it runs over millions of frames; ``scipy.spatial.transform.Rotation``
is the reference these functions are tested against.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from thirdhand.arrays import FloatArray
from thirdhand.errors import ThirdhandError

_UNIT_TOL = 1e-6


def check_quat(q: ArrayLike, *, normalize: bool = True) -> FloatArray:
    """Validate quaternions and return them as float64, normalised.

    Parameters
    ----------
    q : array_like, shape (..., 4)
        Quaternions, x y z w.
    normalize : bool
        Divide by the norm (the default). Without it, a non-unit input is an error.

    Returns
    -------
    ndarray, shape (..., 4)
        Unit quaternions.

    Raises
    ------
    ThirdhandError
        If the last axis is not 4, a value is not finite, or a norm is zero.
    """
    arr = np.asarray(q, dtype=np.float64)
    if arr.shape[-1:] != (4,):
        raise ThirdhandError(f"expected quaternions of shape (..., 4), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ThirdhandError("quaternion contains a non-finite value")
    norm = np.linalg.norm(arr, axis=-1, keepdims=True)
    if np.any(norm < 1e-12):
        raise ThirdhandError("quaternion of zero norm")
    if not normalize:
        if np.any(np.abs(norm - 1.0) > _UNIT_TOL):
            raise ThirdhandError("quaternion is not of unit norm")
        return arr
    return arr / norm


def quat_identity(shape: tuple[int, ...] = ()) -> FloatArray:
    """Identity quaternions of the given leading shape, shape ``shape + (4,)``."""
    out = np.zeros((*shape, 4))
    out[..., 3] = 1.0
    return out


def quat_conjugate(q: ArrayLike) -> FloatArray:
    """Conjugate (the inverse of a unit quaternion), shape (..., 4)."""
    out = np.array(q, dtype=np.float64, copy=True)
    out[..., :3] *= -1.0
    return out


def quat_multiply(q1: ArrayLike, q2: ArrayLike) -> FloatArray:
    """Hamilton product ``q1 ⊗ q2`` (rotate by q2 first, then by q1), x y z w."""
    a = np.asarray(q1, dtype=np.float64)
    b = np.asarray(q2, dtype=np.float64)
    x1, y1, z1, w1 = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    x2, y2, z2, w2 = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return np.stack(
        [
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        ],
        axis=-1,
    )


def quat_rotate(q: ArrayLike, v: ArrayLike) -> FloatArray:
    """Rotate vectors ``v`` (..., 3) by unit quaternions ``q`` (..., 4)."""
    qa = np.asarray(q, dtype=np.float64)
    va = np.asarray(v, dtype=np.float64)
    u = qa[..., :3]
    w = qa[..., 3:4]
    t = 2.0 * np.cross(u, va)
    return va + w * t + np.cross(u, t)


def quat_angle(q1: ArrayLike, q2: ArrayLike) -> FloatArray:
    """Rotation angle between two orientations, radians in [0, π], shape (...).

    Computed as ``2 atan2(|v|, |w|)`` of ``q1⁻¹ ⊗ q2``, accurate near 0 and near π
    (``arccos`` of a dot product loses half the digits near 0).
    """
    d = quat_multiply(quat_conjugate(q1), q2)
    return 2.0 * np.arctan2(np.linalg.norm(d[..., :3], axis=-1), np.abs(d[..., 3]))


def quat_make_continuous(q: ArrayLike, valid: ArrayLike | None = None) -> FloatArray:
    """Flip signs so that consecutive quaternions have a non-negative dot product.

    ``q`` and ``-q`` are the same rotation; statistics (means, variances, splines)
    over a track need one sign chosen consistently.

    Parameters
    ----------
    q : array_like, shape (n, 4)
        Quaternion track, x y z w.
    valid : array_like of bool, shape (n,), optional
        Frames to consider. Invalid frames are skipped: the sign of the next valid
        frame is chosen against the previous valid one, and invalid rows are
        returned unchanged.

    Returns
    -------
    ndarray, shape (n, 4)
    """
    arr = np.array(q, dtype=np.float64, copy=True)
    if arr.ndim != 2 or arr.shape[1] != 4:
        raise ThirdhandError(f"expected a quaternion track of shape (n, 4), got {arr.shape}")
    if valid is None:
        idx = np.flatnonzero(np.all(np.isfinite(arr), axis=1))
    else:
        idx = np.flatnonzero(np.asarray(valid, dtype=bool))
    if idx.size < 2:
        return arr
    sub = arr[idx]
    dots = np.sum(sub[1:] * sub[:-1], axis=1)
    # A flip at step i flips every later sample too: cumulative parity.
    flips = np.concatenate([[False], np.logical_xor.accumulate(dots < 0.0)])
    sub[flips] *= -1.0
    arr[idx] = sub
    return arr


def quat_slerp(q0: ArrayLike, q1: ArrayLike, w: ArrayLike) -> FloatArray:
    """Spherical linear interpolation between unit quaternions, shortest path.

    Parameters
    ----------
    q0, q1 : array_like, shape (..., 4)
    w : array_like, shape (...)
        Interpolation weight, 0 gives ``q0`` and 1 gives ``q1``.
    """
    a = np.asarray(q0, dtype=np.float64)
    b = np.asarray(q1, dtype=np.float64)
    s = np.asarray(w, dtype=np.float64)[..., None]
    dot = np.sum(a * b, axis=-1, keepdims=True)
    b = np.where(dot < 0.0, -b, b)
    dot = np.abs(dot)
    theta = np.arccos(np.clip(dot, -1.0, 1.0))
    sin_theta = np.sin(theta)
    small = sin_theta < 1e-9
    safe = np.where(small, 1.0, sin_theta)
    wa = np.where(small, 1.0 - s, np.sin((1.0 - s) * theta) / safe)
    wb = np.where(small, s, np.sin(s * theta) / safe)
    out = wa * a + wb * b
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


def quat_from_rotvec(rotvec: ArrayLike) -> FloatArray:
    """Unit quaternions (..., 4) x y z w of rotation vectors (..., 3), radians."""
    rv = np.asarray(rotvec, dtype=np.float64)
    angle = np.linalg.norm(rv, axis=-1, keepdims=True)
    half = 0.5 * angle
    # sin(θ/2)/θ, with its limit 1/2 at θ = 0.
    k = np.where(angle > 1e-12, np.sin(half) / np.where(angle > 1e-12, angle, 1.0), 0.5)
    return np.concatenate([rv * k, np.cos(half)], axis=-1)


def rotvec_from_quat(q: ArrayLike) -> FloatArray:
    """Rotation vectors (..., 3), radians, of unit quaternions (..., 4) x y z w.

    The shorter of the rotations ``q`` and ``−q`` describe: angle in [0, π].
    """
    qa = np.asarray(q, dtype=np.float64)
    qa = np.where(qa[..., 3:4] < 0.0, -qa, qa)
    s = np.linalg.norm(qa[..., :3], axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(s, qa[..., 3:4])
    k = np.where(s > 1e-12, angle / np.where(s > 1e-12, s, 1.0), 2.0)
    return qa[..., :3] * k


def quat_log(q: ArrayLike) -> FloatArray:
    """Logarithm of unit quaternions (..., 4): half the rotation vector, (..., 3), norm ≤ π/2."""
    return 0.5 * rotvec_from_quat(q)


def quat_exp(r: ArrayLike) -> FloatArray:
    """Exponential of pure quaternions (..., 3) into unit quaternions (..., 4) x y z w."""
    return quat_from_rotvec(2.0 * np.asarray(r, dtype=np.float64))


def quat_from_matrix(m: ArrayLike) -> FloatArray:
    """Quaternions (..., 4) x y z w from rotation matrices (..., 3, 3)."""
    from scipy.spatial.transform import Rotation

    arr = np.asarray(m, dtype=np.float64)
    flat = arr.reshape(-1, 3, 3)
    return Rotation.from_matrix(flat).as_quat().reshape(*arr.shape[:-2], 4)


def matrix_from_quat(q: ArrayLike) -> FloatArray:
    """Rotation matrices (..., 3, 3) from unit quaternions (..., 4) x y z w."""
    qa = np.asarray(q, dtype=np.float64)
    x, y, z, w = qa[..., 0], qa[..., 1], qa[..., 2], qa[..., 3]
    m = np.empty((*qa.shape[:-1], 3, 3))
    m[..., 0, 0] = 1 - 2 * (y * y + z * z)
    m[..., 0, 1] = 2 * (x * y - z * w)
    m[..., 0, 2] = 2 * (x * z + y * w)
    m[..., 1, 0] = 2 * (x * y + z * w)
    m[..., 1, 1] = 1 - 2 * (x * x + z * z)
    m[..., 1, 2] = 2 * (y * z - x * w)
    m[..., 2, 0] = 2 * (x * z - y * w)
    m[..., 2, 1] = 2 * (y * z + x * w)
    m[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return m


def matrix_from_rotvec(rotvec: ArrayLike) -> FloatArray:
    """Rotation matrices (..., 3, 3) of rotation vectors (..., 3), radians."""
    return matrix_from_quat(quat_from_rotvec(rotvec))


def rotvec_from_matrix(m: ArrayLike) -> FloatArray:
    """Rotation vectors (..., 3), radians (angle in [0, π]), of rotation matrices (..., 3, 3)."""
    return rotvec_from_quat(quat_from_matrix(m))


def quat_from_euler(angles: ArrayLike, seq: str = "xyz", *, degrees: bool = False) -> FloatArray:
    """Unit quaternions (..., 4) x y z w of Euler angles (..., 3).

    ``seq`` as in :meth:`scipy.spatial.transform.Rotation.from_euler`: lower case
    for extrinsic (fixed-axis) rotations, upper case for intrinsic ones.
    """
    from scipy.spatial.transform import Rotation

    a = np.asarray(angles, dtype=np.float64)
    flat = Rotation.from_euler(seq, a.reshape(-1, 3), degrees=degrees).as_quat()
    return flat.reshape(*a.shape[:-1], 4)


def euler_from_quat(q: ArrayLike, seq: str = "xyz", *, degrees: bool = False) -> FloatArray:
    """Euler angles (..., 3) of unit quaternions (..., 4) x y z w (``seq`` as in scipy)."""
    from scipy.spatial.transform import Rotation

    qa = np.asarray(q, dtype=np.float64)
    flat = Rotation.from_quat(qa.reshape(-1, 4)).as_euler(seq, degrees=degrees)
    return flat.reshape(*qa.shape[:-1], 3)


def matrix_from_euler(angles: ArrayLike, seq: str = "xyz", *, degrees: bool = False) -> FloatArray:
    """Rotation matrices (..., 3, 3) of Euler angles (..., 3) (``seq`` as in scipy)."""
    return matrix_from_quat(quat_from_euler(angles, seq, degrees=degrees))


def euler_from_matrix(m: ArrayLike, seq: str = "xyz", *, degrees: bool = False) -> FloatArray:
    """Euler angles (..., 3) of rotation matrices (..., 3, 3) (``seq`` as in scipy)."""
    return euler_from_quat(quat_from_matrix(m), seq, degrees=degrees)


def quat_mean(q: ArrayLike, weights: ArrayLike | None = None) -> FloatArray:
    """The (weighted) mean rotation of unit quaternions (n, 4) x y z w, shape (4,).

    The top eigenvector of ``Σ wᵢ qᵢ qᵢᵀ`` (Markley et al. 2007): the rotation
    minimising the weighted sum of squared chordal distances, blind to the sign
    of each ``qᵢ``. Returned with ``w >= 0``.
    """
    qa = np.asarray(q, dtype=np.float64).reshape(-1, 4)
    w = np.ones(len(qa)) if weights is None else np.asarray(weights, dtype=np.float64)
    _, vec = np.linalg.eigh((qa * w[:, None]).T @ qa)
    top = vec[:, 3]
    return np.asarray(top if top[3] >= 0 else -top, dtype=np.float64)


def transform_invert(t: ArrayLike) -> FloatArray:
    """Inverses of rigid transforms (..., 4, 4): ``[Rᵀ, −Rᵀ p; 0, 1]``."""
    ta = np.asarray(t, dtype=np.float64)
    out = np.zeros_like(ta)
    rt = np.swapaxes(ta[..., :3, :3], -1, -2)
    out[..., :3, :3] = rt
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", rt, ta[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out


def pose_invert(p: ArrayLike, q: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Inverse of pose ``(p_AB, q_AB)``: the pose ``(p_BA, q_BA)`` of A in B."""
    qi = quat_conjugate(q)
    return -quat_rotate(qi, p), qi


def pose_compose(
    p_ab: ArrayLike, q_ab: ArrayLike, p_bc: ArrayLike, q_bc: ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Compose pose of B in A with pose of C in B into the pose of C in A."""
    return quat_rotate(q_ab, p_bc) + np.asarray(p_ab, dtype=np.float64), quat_multiply(q_ab, q_bc)


def relative_pose(
    p_wa: ArrayLike, q_wa: ArrayLike, p_wb: ArrayLike, q_wb: ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Pose of B in A from both poses in the world frame.

    ``p_AB = R_A⁻¹ (p_B − p_A)`` and ``q_AB = q_A⁻¹ ⊗ q_B``.

    Parameters
    ----------
    p_wa, p_wb : array_like, shape (..., 3), metres, world frame
    q_wa, q_wb : array_like, shape (..., 4), x y z w

    Returns
    -------
    p_ab : ndarray, shape (..., 3), metres, A's frame
    q_ab : ndarray, shape (..., 4)
    """
    qa_inv = quat_conjugate(q_wa)
    diff = np.asarray(p_wb, dtype=np.float64) - np.asarray(p_wa, dtype=np.float64)
    return quat_rotate(qa_inv, diff), quat_multiply(qa_inv, q_wb)


def matrix_from_pose(p: ArrayLike, q: ArrayLike) -> FloatArray:
    """Homogeneous transforms (..., 4, 4) from positions (..., 3) and quaternions (..., 4)."""
    pa = np.asarray(p, dtype=np.float64)
    r = matrix_from_quat(q)
    out = np.zeros((*r.shape[:-2], 4, 4))
    out[..., :3, :3] = r
    out[..., :3, 3] = pa
    out[..., 3, 3] = 1.0
    return out


def pose_from_matrix(t: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Positions (..., 3) and quaternions (..., 4) from homogeneous transforms (..., 4, 4)."""
    arr = np.asarray(t, dtype=np.float64)
    return arr[..., :3, 3].copy(), quat_from_matrix(arr[..., :3, :3])


def kabsch(
    reference: ArrayLike, observed: ArrayLike, weights: ArrayLike | None = None
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Least-squares rigid fit of a point cluster, batched over frames (Kabsch).

    Finds ``R, p`` minimising ``Σ_i w_i ||R r_i + p − o_i||²`` for each frame.

    Parameters
    ----------
    reference : array_like, shape (m, 3)
        Cluster points in the body frame, metres.
    observed : array_like, shape (n, m, 3)
        Observed points per frame, metres, world frame. NaN rows are ignored.
    weights : array_like, shape (n, m) or (m,), optional
        Non-negative weights; missing (NaN) observations get weight 0.

    Returns
    -------
    p : ndarray, shape (n, 3)
        Body origin in the world frame; NaN where fewer than 3 points were seen.
    q : ndarray, shape (n, 4)
        Body orientation, x y z w; NaN where fewer than 3 points were seen.
    rms : ndarray, shape (n,)
        Root-mean-square residual of the fit, metres.
    """
    ref = np.asarray(reference, dtype=np.float64)
    obs = np.asarray(observed, dtype=np.float64)
    if obs.ndim == 2:
        obs = obs[None]
    n, m, _ = obs.shape
    seen = np.all(np.isfinite(obs), axis=2)
    w = np.ones((n, m)) if weights is None else np.broadcast_to(np.asarray(weights, float), (n, m))
    w = np.where(seen, w, 0.0)
    obs0 = np.where(seen[..., None], obs, 0.0)
    wsum = w.sum(axis=1)
    ok = (seen.sum(axis=1) >= 3) & (wsum > 0)
    wsafe = np.where(wsum > 0, wsum, 1.0)
    c_ref = (w[..., None] * ref[None]).sum(axis=1) / wsafe[:, None]
    c_obs = (w[..., None] * obs0).sum(axis=1) / wsafe[:, None]
    a = ref[None] - c_ref[:, None]
    b = obs0 - c_obs[:, None]
    h = np.einsum("nm,nmi,nmj->nij", w, a, b)
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(np.einsum("nji,nkj->nik", vt, u)))
    d = np.where(d == 0, 1.0, d)
    diag = np.ones((n, 3))
    diag[:, 2] = d
    r = np.einsum("nji,nj,nkj->nik", vt, diag, u)
    p = c_obs - np.einsum("nij,nj->ni", r, c_ref)
    q = quat_from_matrix(r)
    resid = np.einsum("nij,mj->nmi", r, ref) + p[:, None] - obs0
    rms = np.sqrt((w * np.sum(resid**2, axis=2)).sum(axis=1) / wsafe)
    p[~ok] = np.nan
    q[~ok] = np.nan
    rms[~ok] = np.nan
    return p, q, rms


def random_quat(rng: np.random.Generator, n: int | None = None) -> FloatArray:
    """Uniformly distributed unit quaternions, shape (4,) or (n, 4)."""
    shape = (4,) if n is None else (n, 4)
    q = rng.standard_normal(shape)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)
