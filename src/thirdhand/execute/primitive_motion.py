"""Motions along a given tool path: straight lines and the learned approach primitive.

The short moves of a pick and place (approach the grasp, lift, insert, retreat)
follow a straight line of the tool; the approach to an assembly pose may follow
the primitive learned from the demonstrations (the task file's
``stages["primitives"]["constraints"]`` block, a pose DMP of the child in the
parent's frame, see :mod:`thirdhand.primitives.stage`). Both become joint paths
the same way: inverse kinematics at each pose along the path, every solve
started from the previous solution, so the arm follows the path continuously;
a jump between consecutive solutions (a branch switch) rejects the path.
The caller checks the joint path for collisions.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from thirdhand import se3
from thirdhand.execute.goals import invert
from thirdhand.execute.robot import Robot
from thirdhand.primitives.serialize import pose_dmp_from_dict
from thirdhand.primitives.stage import rollout_in_world

FloatArray = NDArray[np.float64]

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


def find_primitive(block: Mapping[str, Any] | None, parent: str, child: str) -> Any | None:
    """The learned pose DMP of ``child`` in ``parent``'s frame from a primitives block, or None."""
    if not block:
        return None
    for entry in (block.get("constraints") or {}).values():
        if entry.get("parent") == parent and entry.get("child") == child and "dmp" in entry:
            return pose_dmp_from_dict(entry["dmp"])
    return None


def primitive_tool_path(
    dmp: Any,
    *,
    parent_world: ArrayLike,
    child_start: ArrayLike,
    child_goal: ArrayLike,
    grasp: ArrayLike,
    n: int = 40,
) -> FloatArray:
    """Tool poses (n, 4, 4) that carry the child along the primitive to its goal.

    Parameters
    ----------
    dmp : PoseDMP
        Learned in the parent's frame.
    parent_world : array_like, shape (4, 4)
        ``T_world_parent``.
    child_start, child_goal : array_like, shape (4, 4)
        ``T_world_child`` where the motion starts and where it must end.
    grasp : array_like, shape (4, 4)
        ``T_child_tool``.
    n : int
        Poses kept along the rollout (evenly spaced in time).
    """
    tp = np.asarray(parent_world, dtype=np.float64)
    goal_rel = invert(tp) @ np.asarray(child_goal, dtype=np.float64)
    sp, sq = se3.matrix_to_pose(np.asarray(child_start, dtype=np.float64))
    gp, gq = se3.matrix_to_pose(goal_rel)
    pp, pq = se3.matrix_to_pose(tp)
    _, pw, qw = rollout_in_world(
        dmp,
        parent_pos=pp,
        parent_quat=pq,
        start_pos=sp,
        start_quat=sq,
        goal_pos=gp,
        goal_quat=gq,
    )
    idx = np.unique(np.linspace(0, len(pw) - 1, n).round().astype(int))
    child = se3.pose_to_matrix(pw[idx], qw[idx])
    # land exactly on the goal (the rollout converges to it asymptotically)
    child[-1] = np.asarray(child_goal, dtype=np.float64)
    return np.asarray(child @ np.asarray(grasp, dtype=np.float64), dtype=np.float64)
