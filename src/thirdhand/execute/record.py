"""Write an executed run: a replay demonstration and a JSON joint trajectory.

The replay is a :class:`~thirdhand.demonstration.Demonstration` whose bodies
are the task's parts (kind ``"part"``) and the robot's tool frame (kind
``"tool"``, named ``"robot_tool"``), sampled at ``rate_hz`` along the
time-parametrised motions, saved in the native parquet format so that
``thirdhand review TASK --demo replay.parquet`` and ``thirdhand info`` show it.
The JSON file holds the joint trajectory (``t``, ``q``), the joint names and
the per-step reports.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from thirdhand import jsontext, se3
from thirdhand.arrays import FloatArray
from thirdhand.demonstration import BodyInfo, Demonstration
from thirdhand.execute.executor import ExecutionResult
from thirdhand.execute.robot import Robot
from thirdhand.execute.timing import time_parametrize
from thirdhand.fileops import atomic_write_bytes, check_path_shape

#: Body name of the robot's tool frame in a replay.
TOOL_BODY = "robot_tool"


def sample_run(
    robot: Robot,
    result: ExecutionResult,
    *,
    rate_hz: float = 50.0,
    spans: list[dict[str, Any]] | None = None,
) -> tuple[FloatArray, FloatArray, dict[str, FloatArray]]:
    """Time-parametrise every executed segment and sample the world along them.

    Parameters
    ----------
    robot : Robot
    result : ExecutionResult
    rate_hz : float
        Samples per second.
    spans : list, optional
        Filled with one dict per executed segment: ``step``, ``segment``,
        ``motion`` (``"planner"``, ``"straight"`` or ``"primitive"``), its
        ``t_start``, ``t_end`` (s) on the returned clock and ``attached`` (the
        part the gripper holds during it, or None).

    Returns
    -------
    t : ndarray, shape (n,)
        Seconds from the start, strictly increasing.
    q : ndarray, shape (n, dof)
        Joint positions, radians.
    poses : dict of str to ndarray, shape (n, 4, 4)
        ``T_world_body`` of every part and of :data:`TOOL_BODY`.
    """
    ts: list[FloatArray] = []
    qs: list[FloatArray] = []
    poses: dict[str, list[FloatArray]] = {}
    names: list[str] = sorted({n for seg in result.trajectory for n in seg["static"]} | {
        seg["attached"] for seg in result.trajectory if seg["attached"] is not None
    })  # fmt: skip
    offset = 0.0
    for seg in result.trajectory:
        traj = time_parametrize(
            seg["path"], robot.velocity_limits, robot.acceleration_limits, rate_hz=rate_hz
        )
        t = traj.t + offset
        if ts:
            keep = t > ts[-1][-1] + 1e-9
            t, q = t[keep], traj.q[keep]
        else:
            q = traj.q
        if len(t) == 0:
            continue
        offset = float(t[-1]) + 1.0 / rate_hz
        if spans is not None:
            spans.append(
                {
                    "step": seg["step"],
                    "segment": seg["segment"],
                    "motion": seg.get("motion", "planner"),
                    "t_start": round(float(t[0]), 6),
                    "t_end": round(float(t[-1]), 6),
                    "attached": seg["attached"],
                }
            )
        tool = robot.tool_transforms(q)
        ts.append(t)
        qs.append(q)
        poses.setdefault(TOOL_BODY, []).append(tool)
        for name in names:
            if name == seg["attached"]:
                poses.setdefault(name, []).append(tool @ seg["t_tool_part"])
            elif name in seg["static"]:
                poses.setdefault(name, []).append(np.repeat(seg["static"][name][None], len(t), 0))
            else:
                poses.setdefault(name, []).append(np.full((len(t), 4, 4), np.nan))
    if not ts:
        static = result.final_poses
        return (
            np.zeros(1),
            robot.home[None],
            {TOOL_BODY: robot.tool_transforms(robot.home[None])}
            | {n: p[None] for n, p in static.items()},
        )
    return np.concatenate(ts), np.vstack(qs), {k: np.vstack(v) for k, v in poses.items()}


def replay_demonstration(
    robot: Robot, result: ExecutionResult, *, rate_hz: float = 50.0, task_name: str = "task"
) -> Demonstration:
    """The run as a demonstration: the parts and the robot's tool frame over time."""
    t, _, poses = sample_run(robot, result, rate_hz=rate_hz)
    bodies = [BodyInfo(n, kind="tool" if n == TOOL_BODY else "part") for n in poses]
    pos = {n: p[:, :3, 3] for n, p in poses.items()}
    quat = {}
    for n, p in poses.items():
        ok = np.all(np.isfinite(p[:, :3, :3]), axis=(1, 2))
        q = np.full((len(p), 4), np.nan)
        if ok.any():
            q[ok] = se3.quat_from_matrix(p[ok, :3, :3])
        quat[n] = q
    meta = {
        "source": "thirdhand.execute",
        "task": task_name,
        "robot": robot.name,
        "units": "m",
        "up_axis": "z",
        "table_z_m": 0.75,
    }
    return Demonstration(t, bodies, pos, quat, meta=meta)


def robot_joints_document(robot: Robot, t: FloatArray, q: FloatArray) -> dict[str, Any]:
    """The arm part of a ``thirdhand.trajectory/1`` document: robot, base pose, joints.

    ``base_pose`` is the robot root's pose in the world (``pos`` metres, ``quat``
    x y z w); ``t`` (n,) seconds and ``q`` (n, dof) radians, rounded to 1e-6.
    """
    return {
        "schema": "thirdhand.trajectory/1",
        "robot": robot.name,
        "base_pose": {
            "pos": [float(v) for v in robot.base_pose[0]],
            "quat": [float(v) for v in robot.base_pose[1]],
        },
        "joint_names": list(robot.joint_names),
        "t": [round(float(v), 6) for v in t],
        "q": [[round(float(v), 6) for v in row] for row in q],
    }


def trajectory_document(
    robot: Robot, result: ExecutionResult, *, rate_hz: float = 50.0
) -> dict[str, Any]:
    """The JSON trajectory: robot, base pose, joints, ``t`` (s), ``q`` (rad), steps, events.

    ``base_pose`` is the robot root's pose in the world (``pos`` metres, ``quat``
    x y z w), so a viewer can place the arm (:mod:`thirdhand.export.robot_model`).

    ``segments`` says which motion each executed segment used (``"planner"``,
    ``"straight"``, ``"primitive"``) and when it ran; ``steps`` are the step
    reports (with ``place_motion``, ``motions``, ``grasp_source``).
    """
    spans: list[dict[str, Any]] = []
    t, q, _ = sample_run(robot, result, rate_hz=rate_hz, spans=spans)
    return {
        **robot_joints_document(robot, t, q),
        "rate_hz": rate_hz,
        "success": result.success,
        "n_collisions": result.n_collisions,
        "segments": spans,
        "steps": [asdict(s) for s in result.steps],
        "events": list(result.events),
    }


def record_paths(out: str | os.PathLike[str]) -> tuple[Path, Path]:
    """The replay (``.parquet``) and trajectory (``.json``) files ``--record out`` writes."""
    replay = check_path_shape(out, what="--record stem")
    if replay.suffix.lower() != ".parquet":
        replay = replay.with_suffix(".parquet")
    return replay, replay.with_suffix(".json")


def write_run(
    robot: Robot,
    result: ExecutionResult,
    out: str | os.PathLike[str],
    *,
    rate_hz: float = 50.0,
    task_name: str = "task",
) -> tuple[Path, Path]:
    """Write the replay (``out``, parquet) and the trajectory (``out`` with ``.json``).

    Both are written atomically; an existing file is kept as its next numbered
    backup (:func:`thirdhand.fileops.atomic_output`).

    Returns
    -------
    replay, trajectory : pathlib.Path
    """
    from thirdhand import io

    replay, traj_path = record_paths(out)
    io.save(replay_demonstration(robot, result, rate_hz=rate_hz, task_name=task_name), replay)
    doc = trajectory_document(robot, result, rate_hz=rate_hz)
    atomic_write_bytes(
        traj_path, (jsontext.dumps(doc, what=str(traj_path), indent=1) + "\n").encode()
    )
    return replay, traj_path


def read_trajectory(path: str | os.PathLike[str]) -> tuple[FloatArray, FloatArray, Sequence[str]]:
    """Read a trajectory file back: ``t`` (n,), ``q`` (n, dof), joint names."""
    from thirdhand.readlimits import MAX_RUN_BYTES, read_json

    doc = read_json(path, what="run (execute --record)", limit=MAX_RUN_BYTES)
    return (
        np.asarray(doc["t"], dtype=np.float64),
        np.asarray(doc["q"], dtype=np.float64),
        list(doc["joint_names"]),
    )
