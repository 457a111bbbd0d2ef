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

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from thirdhand import se3
from thirdhand.errors import ThirdhandError

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

_AXES = {"JointModelRX": (1.0, 0.0, 0.0), "JointModelRY": (0.0, 1.0, 0.0)}
_AXES["JointModelRZ"] = (0.0, 0.0, 1.0)


def _axis_rotation(axis: FloatArray, angle: FloatArray) -> FloatArray:
    """Rotation matrices about a unit ``axis`` (3,) by ``angle`` (n,), shape (n, 3, 3)."""
    x, y, z = axis
    c = np.cos(angle)[:, None, None]
    s = np.sin(angle)[:, None, None]
    k = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return np.eye(3) + s * k + (1.0 - c) * (k @ k)


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
        qa = np.asarray(q, dtype=np.float64)
        n = qa.shape[0]
        out = np.empty((n, self.dof, 4, 4))
        local = np.zeros((n, 4, 4))
        local[:, 3, 3] = 1.0
        for j in range(self.dof):
            local[:, :3, :3] = _axis_rotation(self.axes[j], qa[:, j])
            t_local = self.placements[j] @ local
            p = self.parents[j]
            out[:, j] = t_local if p < 0 else out[:, p] @ t_local
        return out

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
    """Damped least squares on the SE(3) error from many starts at once, within joint limits.

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
    q = np.clip(np.array(q0, dtype=np.float64), lower, upper)
    n = q.shape[0]
    tgt = np.broadcast_to(np.asarray(target, dtype=np.float64), (n, 4, 4))
    anc = chain.ancestors(tool_joint)
    active = np.ones(n, dtype=bool)
    converged = np.zeros(n, dtype=bool)
    eye6 = np.eye(6)
    for _ in range(options.max_iter):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        tj = chain.joint_transforms(q[idx])
        tool = tj[:, tool_joint] @ t_joint_tool
        e_pos = tgt[idx, :3, 3] - tool[:, :3, 3]
        e_rot = rotation_error(tgt[idx, :3, :3], tool[:, :3, :3])
        done = (np.linalg.norm(e_pos, axis=1) < options.tol_pos) & (
            np.linalg.norm(e_rot, axis=1) < options.tol_rot
        )
        converged[idx[done]] = True
        active[idx[done]] = False
        keep = ~done
        if not np.any(keep):
            break
        idx = idx[keep]
        jac = chain.jacobian(tj[keep], tool[keep, :3, 3], anc)
        err = np.concatenate([e_pos[keep], e_rot[keep]], axis=1)
        jjt = jac @ jac.transpose(0, 2, 1) + options.damping**2 * eye6
        dq = np.einsum("nij,ni->nj", jac, np.linalg.solve(jjt, err[..., None])[..., 0])
        big = np.max(np.abs(dq), axis=1, keepdims=True)
        dq *= np.minimum(1.0, options.max_step / np.maximum(big, 1e-300))
        q[idx] = np.clip(q[idx] + dq, lower, upper)
    return q, converged
