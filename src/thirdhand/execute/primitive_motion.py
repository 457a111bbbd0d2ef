"""Motions along a given tool path: straight lines and the learned approach primitive.

The short moves of a pick and place (approach the grasp, lift, insert, retreat)
follow a straight line of the tool; the final approach onto an assembly pose
may follow the primitive learned from the demonstrations (a
:class:`~thirdhand.task.stages.PrimitiveRecord` of the task file's
``stages.primitives``, a pose DMP of the child in the parent's frame, see
:mod:`thirdhand.primitives.stage`): the DMP is rolled out
from its demonstrated start to the chosen goal and its last few centimetres
(:func:`primitive_place_path`) are followed — the way the person pushed the
part home, e.g. the chair's back slid into its groove. Both become joint paths
the same way: inverse kinematics at each pose along the path, every solve
started from the previous solution, so the arm follows the path continuously;
a jump between consecutive solutions (a branch switch) rejects the path.
The caller checks the joint path for collisions.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.execute.goals import dof_displacement, invert, vary
from thirdhand.execute.robot import Robot
from thirdhand.primitives.serialize import pose_dmp_from_record
from thirdhand.task.constraint import Constraint
from thirdhand.task.stages import PrimitivesBlock

if TYPE_CHECKING:
    from thirdhand.primitives.quaternion_dmp import PoseDMP


#: Largest joint change between consecutive path poses before the path counts as broken, rad.
MAX_JUMP_RAD = 0.35


def follow_tool_path(
    robot: Robot, q_seed: ArrayLike, tool_poses: ArrayLike, *, max_jump: float = MAX_JUMP_RAD
) -> FloatArray | None:
    """Joint path whose tool passes through ``tool_poses``, or None.

    Parameters
    ----------
    robot : Robot
    q_seed : array_like, shape (dof,)
        Start of the first solve (normally a solution at the first pose), radians.
    tool_poses : array_like, shape (n, 4, 4)
        ``T_world_tool`` along the path.
    max_jump : float
        Largest joint change between consecutive solutions, radians.

    Returns
    -------
    ndarray, shape (n, dof) or None
        None if a solve fails or the arm would jump.
    """
    poses = np.asarray(tool_poses, dtype=np.float64)
    q = robot.check_q(q_seed)
    out = np.empty((poses.shape[0], robot.dof))
    for i, t in enumerate(poses):
        sol, ok = robot.ik_batch(t[None], q[None])
        if not ok[0] or (np.max(np.abs(sol[0] - q)) > max_jump and i > 0):
            return None
        q = sol[0]
        out[i] = q
    return out


def straight_line(t_a: ArrayLike, t_b: ArrayLike, n: int) -> FloatArray:
    """``n`` poses (n, 4, 4) from ``t_a`` to ``t_b``: points on the segment, slerped rotations."""
    a = np.asarray(t_a, dtype=np.float64)
    b = np.asarray(t_b, dtype=np.float64)
    w = np.linspace(0.0, 1.0, n)
    qa = se3.quat_from_matrix(a[:3, :3])
    qb = se3.quat_from_matrix(b[:3, :3])
    out = np.tile(np.eye(4), (n, 1, 1))
    out[:, :3, :3] = se3.matrix_from_quat(se3.quat_slerp(qa, qb, w))
    out[:, :3, 3] = a[:3, 3] + w[:, None] * (b[:3, 3] - a[:3, 3])
    return out


def linear_motion(
    robot: Robot, q_a: ArrayLike, t_b: ArrayLike, *, step_m: float = 0.01
) -> FloatArray | None:
    """Move the tool in a straight line from where it is at ``q_a`` to ``t_b``.

    Parameters
    ----------
    robot : Robot
    q_a : array_like, shape (dof,)
        Start configuration, radians.
    t_b : array_like, shape (4, 4)
        Target ``T_world_tool``.
    step_m : float
        Spacing of the poses solved along the line, metres.

    Returns
    -------
    ndarray, shape (n, dof) or None
        Starts with ``q_a``; None if the line cannot be followed.
    """
    qa = robot.check_q(q_a)
    t_a = robot.tool_transforms(qa[None])[0]
    dist = float(np.linalg.norm(np.asarray(t_b)[:3, 3] - t_a[:3, 3]))
    n = max(int(np.ceil(dist / step_m)) + 1, 2)
    path = follow_tool_path(robot, qa, straight_line(t_a, t_b, n)[1:])
    if path is None:
        return None
    return np.vstack([qa[None], path])


def find_primitive(block: PrimitivesBlock | None, parent: str, child: str) -> PoseDMP | None:
    """The learned pose DMP of ``child`` in ``parent``'s frame from a primitives block, or None."""
    found = None if block is None else block.find(parent, child)
    return None if found is None else pose_dmp_from_record(found[1])


def primitive_place_path(
    dmp: PoseDMP,
    *,
    parent_world: ArrayLike,
    child_goal: ArrayLike,
    grasp: ArrayLike,
    length_m: float = 0.06,
    step_m: float = 0.005,
    constraint: Constraint | None = None,
    straight_m: float = 0.0,
    axis: ArrayLike | None = None,
) -> FloatArray | None:
    """Tool poses that bring the child to its goal along the end of the learned primitive.

    The primitive (learned in the parent's frame) is rolled out from its
    demonstrated start to ``child_goal``; the part of the rollout after the
    child last came within ``length_m`` of the goal (the person's final approach,
    e.g. a leg pushed into its slot or the back slid into its groove) is kept and
    resampled about every ``step_m`` of the child's motion, ending exactly on the goal.
    With ``constraint``, turns inside its free rotational DOFs are dropped from
    the motion (held at the goal's): a person screws a leg into its slot, the
    goal already fixes the leg's spin, and the arm's wrist could not turn that far.

    Parameters
    ----------
    dmp : PoseDMP
        Learned in the parent's frame.
    parent_world : array_like, shape (4, 4)
        ``T_world_parent``.
    child_goal : array_like, shape (4, 4)
        ``T_world_child`` at the goal (any pose inside the free DOFs).
    grasp : array_like, shape (4, 4)
        ``T_child_tool``.
    length_m : float
        Distance from the goal where the kept motion starts, metres.
    step_m : float
        Spacing of the kept poses, metres (rotation counts 5 cm per radian).
    constraint : Constraint, optional
        The constraint whose free rotations are held at the goal's.
    straight_m : float
        The last ``straight_m`` metres run straight in along ``axis`` at the goal's
        orientation, and the ``straight_m`` before them blend into that line: a
        person wiggles a leg into its slot, a stiff arm with a millimetre of
        clearance jams unless the part comes in square. 0 keeps the primitive as is.
    axis : array_like, shape (3,), optional
        The direction the child backs out of its parent, child frame
        (:func:`~thirdhand.execute.world.insertion_axis`); needed with ``straight_m``.

    Returns
    -------
    ndarray, shape (n, 4, 4) or None
        ``T_world_tool`` along the motion, the last one the goal's; None when
        the rollout never comes farther than ``length_m`` from the goal.
    """
    tp = np.asarray(parent_world, dtype=np.float64)
    goal_w = np.asarray(child_goal, dtype=np.float64)
    gp, gq = se3.pose_from_matrix(invert(tp) @ goal_w)
    _, pos, quat = dmp.rollout(goal_pos=gp, goal_quat=gq, at_rest=True)
    dist = np.linalg.norm(pos - gp, axis=1)
    far = np.flatnonzero(dist >= length_m)
    if far.size == 0:
        return None
    tail_p, tail_q = pos[far[-1] :], quat[far[-1] :]
    if constraint is not None:
        free_rot = np.ptp(constraint.free_dof_array(), axis=1)[3:] > 0.0
        if free_rot.any():
            d = dof_displacement(se3.matrix_from_pose(tail_p, tail_q), constraint)
            d[:, 3:][:, free_rot] = dof_displacement(invert(tp) @ goal_w, constraint)[3:][free_rot]
            tail_p, tail_q = se3.pose_from_matrix(vary(constraint, d))
    # arc length of the child's motion (5 cm per radian of turning) to resample evenly
    dot = np.abs(np.sum(tail_q[1:] * tail_q[:-1], axis=1))
    ang = 2.0 * np.arccos(np.clip(dot, 0.0, 1.0))
    arc = np.concatenate(
        [[0.0], np.cumsum(np.linalg.norm(np.diff(tail_p, axis=0), axis=1) + 0.05 * ang)]
    )
    n = max(int(np.ceil(arc[-1] / step_m)) + 1, 2)
    idx = np.unique(np.searchsorted(arc, np.linspace(0.0, arc[-1], n)).clip(0, len(arc) - 1))
    child = tp @ se3.matrix_from_pose(tail_p[idx], tail_q[idx])
    child[-1] = goal_w  # land exactly on the goal (the rollout converges to it asymptotically)
    if straight_m > 0.0 and axis is not None:
        child = straight_entry(child, goal_w, np.asarray(axis, dtype=np.float64), straight_m)
    return np.asarray(child @ np.asarray(grasp, dtype=np.float64), dtype=np.float64)


def straight_entry(
    child: FloatArray, goal: FloatArray, axis: FloatArray, straight_m: float
) -> FloatArray:
    """Child poses (n, 4, 4) whose last ``straight_m`` run straight in to ``goal``.

    A pose whose distance from the goal is ``d`` becomes the goal backed out by ``d``
    along ``axis`` (child frame) when ``d ≤ straight_m``; between ``straight_m`` and
    ``2 · straight_m`` it is blended linearly (position, and rotation vector from the
    goal's orientation) from the given pose to that line. World frame, metres.
    """
    out = np.array(child, dtype=np.float64)
    out_dir = goal[:3, :3] @ (axis / np.linalg.norm(axis))
    for i, pose in enumerate(out):
        d = float(np.linalg.norm(pose[:3, 3] - goal[:3, 3]))
        w = float(np.clip((2.0 * straight_m - d) / straight_m, 0.0, 1.0))
        if w <= 0.0:
            continue
        line_p = goal[:3, 3] + d * out_dir
        rv = se3.rotvec_from_matrix(pose[:3, :3] @ goal[:3, :3].T)
        out[i, :3, :3] = se3.matrix_from_rotvec((1.0 - w) * rv) @ goal[:3, :3]
        out[i, :3, 3] = (1.0 - w) * pose[:3, 3] + w * line_p
    return out
