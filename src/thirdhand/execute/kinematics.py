"""Batched forward kinematics, Jacobians and inverse kinematics of a serial revolute chain.

Pinocchio evaluates one configuration per call; sampling goals, checking a
densely interpolated path or running many IK restarts needs the same maths
over hundreds of configurations at once. :class:`Chain` takes the joint
placements and axes of a pinocchio model once and evaluates them in numpy over
a leading batch axis. The tests cross-check every output against pinocchio.

Conventions: transforms are homogeneous ``(..., 4, 4)`` matrices mapping a
child frame's coordinates into the world frame (``T_world_child``); Jacobians
are in the world frame, linear rows first, and give the velocity of the tool
frame's origin and its angular velocity.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from thirdhand import se3
from thirdhand.arrays import BoolArray, FloatArray, IntArray
from thirdhand.errors import ThirdhandError

_AXES = {"JointModelRX": (1.0, 0.0, 0.0), "JointModelRY": (0.0, 1.0, 0.0)}
_AXES["JointModelRZ"] = (0.0, 0.0, 1.0)


@dataclass(frozen=True)
class Chain:
    """A serial chain of revolute joints, copied out of a pinocchio model.

    Attributes
    ----------
    placements : ndarray, shape (dof, 4, 4)
        ``T_parent_joint`` of each joint at zero angle (the parent's joint frame,
        the world for the first joint).
    axes : ndarray, shape (dof, 3)
        Rotation axis of each joint in its own frame, unit.
    parents : ndarray of int, shape (dof,)
        Index of the parent joint, -1 for the world.
    """

    placements: FloatArray
    axes: FloatArray
    parents: NDArray[np.intp]

    @property
    def dof(self) -> int:
        """Number of joints."""
        return int(self.axes.shape[0])

    @classmethod
    def from_model(cls, model: pin.Model) -> Chain:
        """Copy the joints of a pinocchio model whose joints are all 1-DOF revolute.

        Raises
        ------
        ThirdhandError
            If a joint is not revolute (prismatic or multi-DOF joints are not supported).
        """
        placements, axes, parents = [], [], []
        for j in range(1, model.njoints):
            joint = model.joints[j]
            kind = joint.shortname()
            if kind in _AXES:
                axis = np.array(_AXES[kind])
            elif kind == "JointModelRevoluteUnaligned":
                axis = np.asarray(joint.extract().axis, dtype=np.float64)
            else:
                raise ThirdhandError(
                    f"joint {model.names[j]!r}: expected a revolute joint, got {kind}"
                )
            placements.append(model.jointPlacements[j].homogeneous)
            axes.append(axis / np.linalg.norm(axis))
            parents.append(model.parents[j] - 1)
        return cls(
            placements=np.array(placements, dtype=np.float64),
            axes=np.array(axes, dtype=np.float64),
            parents=np.array(parents, dtype=np.intp),
        )

    def joint_transforms(self, q: ArrayLike) -> FloatArray:
        """World transform of every joint frame.

        Parameters
        ----------
        q : array_like, shape (n, dof)
            Joint angles, radians.

        Returns
        -------
        ndarray, shape (n, dof, 4, 4)
            ``T_world_joint`` after the joint's rotation.
        """
        qa = np.ascontiguousarray(q, dtype=np.float64).reshape(-1, self.dof)
        return joint_transforms_nb(qa, self.placements, self.axes, self.parents.astype(np.int64))

    def jacobian(self, t_joints: FloatArray, point: FloatArray, ancestors: BoolArray) -> FloatArray:
        """World-frame Jacobian of a point fixed to a joint's frame.

        Parameters
        ----------
        t_joints : ndarray, shape (n, dof, 4, 4)
            Output of :meth:`joint_transforms`.
        point : ndarray, shape (n, 3)
            The point, world frame, metres.
        ancestors : ndarray of bool, shape (dof,)
            Joints that move the point (the frame's joint and its ancestors).

        Returns
        -------
        ndarray, shape (n, 6, dof)
            Linear velocity rows (metres per radian) then angular velocity rows.
        """
        axes_w = np.einsum("njab,jb->nja", t_joints[:, :, :3, :3], self.axes)
        origins = t_joints[:, :, :3, 3]
        lin = np.cross(axes_w, point[:, None, :] - origins)
        jac = np.concatenate([lin, axes_w], axis=2).transpose(0, 2, 1)
        return jac * ancestors[None, None, :]

    def ancestors(self, joint: int) -> BoolArray:
        """Mask of the joints that move joint ``joint``'s frame (itself included), shape (dof,)."""
        mask = np.zeros(self.dof, dtype=bool)
        j = joint
        while j >= 0:
            mask[j] = True
            j = int(self.parents[j])
        return mask


def rotation_error(r_target: FloatArray, r: FloatArray) -> FloatArray:
    """Rotation vector taking ``r`` to ``r_target`` in the world frame, shape (n, 3), radians.

    ``log(R_target Rᵀ)`` as an axis times an angle in [0, π].
    """
    q = se3.quat_from_matrix(r_target @ np.swapaxes(r, -1, -2))
    q = np.where(q[..., 3:4] < 0.0, -q, q)
    vnorm = np.linalg.norm(q[..., :3], axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(vnorm, q[..., 3:4])
    scale = np.where(vnorm > 1e-12, angle / np.maximum(vnorm, 1e-300), 2.0)
    return np.asarray(q[..., :3] * scale, dtype=np.float64)


# sin and cos of a joint angle in a few multiply-adds (the compiled kernels call them 7 times
# per configuration; libm's calls were 40 % of forward kinematics): the angle less the
# nearest multiple of π/2 (π/2 in two parts, so the remainder is exact to ~1e-17 for joint
# angles), then fdlibm's minimax polynomials on [-π/4, π/4] (errors under 1 ulp there).
_PIO2_HI = 1.57079632673412561417e00
_PIO2_LO = 6.07710050650619224932e-11
_S = (
    -1.66666666666666324348e-01,
    8.33333333332248946124e-03,
    -1.98412698298579493134e-04,
    2.75573137070700676789e-06,
    -2.50507602534068634195e-08,
    1.58969099521155010221e-10,
)
_C = (
    4.16666666666666019037e-02,
    -1.38888888888741095749e-03,
    2.48015872894767294178e-05,
    -2.75573143513906633035e-07,
    2.08757232129817482790e-09,
    -1.13596475577881948265e-11,
)


@numba.njit(cache=True, inline="always")
def sincos(q: float) -> tuple[float, float]:
    """``(sin q, cos q)`` of an angle in radians (for |q| ≤ 100, within 2.3e-16 of libm's)."""
    k = np.floor(q * (2.0 / np.pi) + 0.5)
    r = (q - k * _PIO2_HI) - k * _PIO2_LO
    z = r * r
    s = r + r * z * (_S[0] + z * (_S[1] + z * (_S[2] + z * (_S[3] + z * (_S[4] + z * _S[5])))))
    c = (
        1.0
        - 0.5 * z
        + z * z * (_C[0] + z * (_C[1] + z * (_C[2] + z * (_C[3] + z * (_C[4] + z * _C[5])))))
    )
    n = int(k) & 3
    if n == 0:
        return s, c
    if n == 1:
        return c, -s
    if n == 2:
        return -s, -c
    return -c, s


@numba.njit(cache=True, inline="always")
def joint_local(pl: FloatArray, x: float, y: float, z: float, s: float,
                c: float) -> tuple[float, ...]:  # fmt: skip
    """``T_parent_joint = placement · [R(axis, q) 0; 0 1]``, its top three rows row-major
    (12 values), from the joint's placement ``pl`` (4, 4), unit axis ``(x, y, z)`` and
    ``(sin q, cos q)``."""
    v = 1.0 - c
    r00, r01, r02 = c + x * x * v, x * y * v - z * s, x * z * v + y * s
    r10, r11, r12 = y * x * v + z * s, c + y * y * v, y * z * v - x * s
    r20, r21, r22 = z * x * v - y * s, z * y * v + x * s, c + z * z * v
    return (
        pl[0, 0] * r00 + pl[0, 1] * r10 + pl[0, 2] * r20,
        pl[0, 0] * r01 + pl[0, 1] * r11 + pl[0, 2] * r21,
        pl[0, 0] * r02 + pl[0, 1] * r12 + pl[0, 2] * r22,
        pl[0, 3],
        pl[1, 0] * r00 + pl[1, 1] * r10 + pl[1, 2] * r20,
        pl[1, 0] * r01 + pl[1, 1] * r11 + pl[1, 2] * r21,
        pl[1, 0] * r02 + pl[1, 1] * r12 + pl[1, 2] * r22,
        pl[1, 3],
        pl[2, 0] * r00 + pl[2, 1] * r10 + pl[2, 2] * r20,
        pl[2, 0] * r01 + pl[2, 1] * r11 + pl[2, 2] * r21,
        pl[2, 0] * r02 + pl[2, 1] * r12 + pl[2, 2] * r22,
        pl[2, 3],
    )


@numba.njit(cache=True, nogil=True)
def _fk(q: FloatArray, placements: FloatArray, axes: FloatArray, parents: IntArray,
        out: FloatArray) -> None:  # fmt: skip
    """Joint frames ``out`` (dof, 4, 4) of one configuration ``q`` (dof,).

    Scalars only (no scratch arrays): this runs once per configuration in the
    collision kernels, where an allocation costs as much as the arithmetic.
    """
    for j in range(q.shape[0]):
        s, c = sincos(q[j])
        loc = joint_local(placements[j], axes[j, 0], axes[j, 1], axes[j, 2], s, c)
        o = out[j]
        p = parents[j]
        for a in range(3):
            if p < 0:
                for k in range(4):
                    o[a, k] = loc[4 * a + k]
            else:
                p0, p1, p2 = out[p, a, 0], out[p, a, 1], out[p, a, 2]
                for k in range(4):
                    o[a, k] = p0 * loc[k] + p1 * loc[4 + k] + p2 * loc[8 + k]
                o[a, 3] += out[p, a, 3]
        o[3, 0] = o[3, 1] = o[3, 2] = 0.0
        o[3, 3] = 1.0


@numba.njit(cache=True, nogil=True)
def joint_transforms_nb(qs: FloatArray, placements: FloatArray, axes: FloatArray,
                     parents: IntArray) -> FloatArray:  # fmt: skip
    """Joint frames ``T_world_joint`` of many configurations ``qs`` (n, dof): (n, dof, 4, 4)."""
    n, dof = qs.shape
    out = np.empty((n, dof, 4, 4))
    for i in range(n):
        _fk(qs[i], placements, axes, parents, out[i])
    return out


@numba.njit(cache=True, nogil=True)
def _rotation_log(r: FloatArray, out: FloatArray) -> None:
    """``out[3:6] = log(r)`` (axis times angle in [0, π]) of a rotation matrix r (3, 3).

    Through the quaternion (Shepperd's branch choice, as :func:`rotation_error`).
    """
    tr = r[0, 0] + r[1, 1] + r[2, 2]
    if tr > r[0, 0] and tr > r[1, 1] and tr > r[2, 2]:
        s = 2.0 * np.sqrt(1.0 + tr)
        w = 0.25 * s
        x = (r[2, 1] - r[1, 2]) / s
        y = (r[0, 2] - r[2, 0]) / s
        z = (r[1, 0] - r[0, 1]) / s
    elif r[0, 0] >= r[1, 1] and r[0, 0] >= r[2, 2]:
        s = 2.0 * np.sqrt(max(1.0 + r[0, 0] - r[1, 1] - r[2, 2], 1e-300))
        w = (r[2, 1] - r[1, 2]) / s
        x = 0.25 * s
        y = (r[0, 1] + r[1, 0]) / s
        z = (r[0, 2] + r[2, 0]) / s
    elif r[1, 1] >= r[2, 2]:
        s = 2.0 * np.sqrt(max(1.0 + r[1, 1] - r[0, 0] - r[2, 2], 1e-300))
        w = (r[0, 2] - r[2, 0]) / s
        x = (r[0, 1] + r[1, 0]) / s
        y = 0.25 * s
        z = (r[1, 2] + r[2, 1]) / s
    else:
        s = 2.0 * np.sqrt(max(1.0 + r[2, 2] - r[0, 0] - r[1, 1], 1e-300))
        w = (r[1, 0] - r[0, 1]) / s
        x = (r[0, 2] + r[2, 0]) / s
        y = (r[1, 2] + r[2, 1]) / s
        z = 0.25 * s
    if w < 0.0:
        w, x, y, z = -w, -x, -y, -z
    vn = np.sqrt(x * x + y * y + z * z)
    scale = 2.0 * np.arctan2(vn, w) / vn if vn > 1e-12 else 2.0
    out[3], out[4], out[5] = x * scale, y * scale, z * scale


@numba.njit(cache=True, nogil=True)
def _solve_ik_nb(placements: FloatArray, axes: FloatArray, parents: IntArray, tool_joint: int,
                 t_joint_tool: FloatArray, targets: FloatArray, q0: FloatArray,
                 lower: FloatArray, upper: FloatArray, max_iter: int, tol_pos: float,
                 tol_rot: float, damping: float, max_step: float, anc: BoolArray,
                 q_out: FloatArray, ok_out: BoolArray) -> None:  # fmt: skip
    """:func:`solve_ik` for each start in turn (the same iteration, compiled)."""
    n, dof = q0.shape
    t = np.empty((dof, 4, 4))
    err = np.empty(6)
    jac = np.zeros((6, dof))
    rel = np.empty((3, 3))
    for i in range(n):
        q = q_out[i]
        for j in range(dof):
            q[j] = min(max(q0[i, j], lower[j]), upper[j])
        tgt = targets[i]
        ok_out[i] = False
        for _ in range(max_iter):
            _fk(q, placements, axes, parents, t)
            tool = t[tool_joint] @ t_joint_tool
            for a in range(3):
                err[a] = tgt[a, 3] - tool[a, 3]
            for a in range(3):
                for b in range(3):
                    rel[a, b] = (tgt[a, 0] * tool[b, 0] + tgt[a, 1] * tool[b, 1]
                                 + tgt[a, 2] * tool[b, 2])  # fmt: skip
            _rotation_log(rel, err)
            if (np.sqrt(err[0] ** 2 + err[1] ** 2 + err[2] ** 2) < tol_pos
                    and np.sqrt(err[3] ** 2 + err[4] ** 2 + err[5] ** 2) < tol_rot):  # fmt: skip
                ok_out[i] = True
                break
            for j in range(dof):
                if not anc[j]:
                    for a in range(6):
                        jac[a, j] = 0.0
                    continue
                tj = t[j]
                a0 = tj[0, 0] * axes[j, 0] + tj[0, 1] * axes[j, 1] + tj[0, 2] * axes[j, 2]
                a1 = tj[1, 0] * axes[j, 0] + tj[1, 1] * axes[j, 1] + tj[1, 2] * axes[j, 2]
                a2 = tj[2, 0] * axes[j, 0] + tj[2, 1] * axes[j, 1] + tj[2, 2] * axes[j, 2]
                d0, d1, d2 = tool[0, 3] - tj[0, 3], tool[1, 3] - tj[1, 3], tool[2, 3] - tj[2, 3]
                jac[0, j] = a1 * d2 - a2 * d1
                jac[1, j] = a2 * d0 - a0 * d2
                jac[2, j] = a0 * d1 - a1 * d0
                jac[3, j], jac[4, j], jac[5, j] = a0, a1, a2
            jjt = jac @ jac.T + damping**2 * np.eye(6)
            dq = jac.T @ np.linalg.solve(jjt, err)
            big = np.max(np.abs(dq))
            if big > max_step:
                dq *= max_step / big
            for j in range(dof):
                q[j] = min(max(q[j] + dq[j], lower[j]), upper[j])


@dataclass(frozen=True)
class IkOptions:
    """Settings of the damped least-squares IK.

    Attributes
    ----------
    max_iter : int
        Iterations per start.
    tol_pos : float
        Position tolerance, metres.
    tol_rot : float
        Orientation tolerance, radians.
    damping : float
        Levenberg–Marquardt damping λ (added as λ² to ``J Jᵀ``), in the units of the error.
    max_step : float
        Largest joint change per iteration, radians (keeps far starts stable).
    """

    max_iter: int = 150
    tol_pos: float = 1e-4
    tol_rot: float = 1e-3
    damping: float = 1e-2
    max_step: float = 0.5


def solve_ik(
    chain: Chain,
    tool_joint: int,
    t_joint_tool: FloatArray,
    target: FloatArray,
    q0: ArrayLike,
    lower: FloatArray,
    upper: FloatArray,
    options: IkOptions = IkOptions(),
) -> tuple[FloatArray, BoolArray]:
    """Damped least squares on the SE(3) error from many starts, within joint limits (compiled).

    Each start iterates: the tool's position error and rotation error
    (:func:`rotation_error`) against ``target``; done when both are within tolerance;
    otherwise a step ``Jᵀ (J Jᵀ + λ² I)⁻¹ e`` scaled to at most ``max_step`` per joint and
    clipped into the limits.

    Parameters
    ----------
    chain : Chain
        The kinematic chain.
    tool_joint : int
        Index of the joint the tool frame is fixed to.
    t_joint_tool : ndarray, shape (4, 4)
        Tool frame in that joint's frame.
    target : ndarray, shape (n, 4, 4) or (4, 4)
        Desired ``T_world_tool``; one per start or one for all.
    q0 : array_like, shape (n, dof)
        Starting configurations, radians.
    lower, upper : ndarray, shape (dof,)
        Joint limits, radians; iterates are clipped into them.
    options : IkOptions
        Tolerances and step control.

    Returns
    -------
    q : ndarray, shape (n, dof)
        Final configuration of each start.
    converged : ndarray of bool, shape (n,)
        Whether the start reached both tolerances.
    """
    q_start = np.ascontiguousarray(q0, dtype=np.float64)
    n = q_start.shape[0]
    tgt = np.ascontiguousarray(np.broadcast_to(np.asarray(target, dtype=np.float64), (n, 4, 4)))
    q = np.empty_like(q_start)
    converged = np.zeros(n, dtype=bool)
    _solve_ik_nb(
        chain.placements, chain.axes, chain.parents.astype(np.int64), int(tool_joint),
        np.ascontiguousarray(t_joint_tool, dtype=np.float64), tgt, q_start,
        np.asarray(lower, dtype=np.float64), np.asarray(upper, dtype=np.float64),
        int(options.max_iter), float(options.tol_pos), float(options.tol_rot),
        float(options.damping), float(options.max_step), chain.ancestors(tool_joint), q, converged,
    )  # fmt: skip
    return q, converged
