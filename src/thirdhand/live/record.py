"""``thirdhand live … --record OUT``: the live run as a replay, beside the person.

Two files, the same pair ``thirdhand execute --record`` writes, so the same
viewers read them:

- ``OUT.parquet``: a :class:`~thirdhand.demonstration.Demonstration` of the
  streamed frames (every body of the recording, the person included, as it
  arrived) and, when the assist ran, the robot's tool frame
  (:data:`~thirdhand.execute.record.TOOL_BODY`, kind ``"tool"``) at every frame;
  its ``meta["live_steps"]`` holds the recognised steps (as ``recognised`` below).
  ``thirdhand review TASK --demo OUT.parquet`` plays it back and lists the steps
  beside the playback.
- ``OUT.json`` (``thirdhand.trajectory/1``, ``"source": "thirdhand.live"``): the
  arm's joint configuration at every frame time (``t`` on the stream's clock,
  ``q`` radians), its base pose (where it stood first) and joint names, ``base_pos``
  (the base's position at every frame time, world metres) when the base moved, and
  the timeline of the run:
  ``recognised`` (each step formed or undone, with its time), ``assists``.
  ``thirdhand convert OUT.parquet out.rrd --with OUT.json --with TASK.json``
  shows the person, the parts, the arm's shapes and the steps in Rerun.

The arm between assists stands at home; during an assist its base first drives
along its route (:class:`~thirdhand.live.assist.Assist` ``base_route``, the arm at
home), then the arm follows the
planned path at the times the assist scheduled (:class:`~thirdhand.live.assist.Assist`
``times``), holds the hand-over pose, and is back at home once the person took
the part (the simulation does not plan the way back). Without ``--assist``
there is no arm: ``t`` and ``q`` are empty.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from thirdhand import jsontext, se3
from thirdhand.arrays import FloatArray
from thirdhand.demonstration import BodyInfo, Demonstration
from thirdhand.execute.record import TOOL_BODY, record_paths, robot_joints_document
from thirdhand.fileops import atomic_write_bytes
from thirdhand.live.assist import RobotAssist
from thirdhand.live.loop import LiveReport


def arm_configurations(assist: RobotAssist, t: FloatArray) -> FloatArray:
    """The arm's joint configuration at each time, shape (n, dof), radians.

    Home outside the assists; along each assist's path (linear between its
    waypoints) from its first waypoint until the person took the part or the
    next assist started, holding the last waypoint in between.
    """
    robot = assist.robot
    if robot is None:
        raise ValueError("the assist never set up its arm (the root was never tracked)")
    q = np.repeat(robot.home[None], t.size, axis=0)
    runs = [a for a in assist.assists if a.path.shape[0] > 0]
    for i, a in enumerate(runs):
        stop = min(
            a.end_s if a.end_s is not None else np.inf,
            runs[i + 1].start_s if i + 1 < len(runs) else np.inf,
        )
        sel = (t >= a.times[0]) & (t < stop)
        if not sel.any():
            continue
        ts = np.clip(t[sel], a.times[0], a.times[-1])
        q[sel] = np.stack([np.interp(ts, a.times, a.path[:, j]) for j in range(robot.dof)], 1)
    return q


def base_positions(assist: RobotAssist, t: FloatArray) -> FloatArray:
    """The base's position at each time ``t`` (n,), shape (n, 3), world metres.

    Where it stood first until the first drive; along each assist's route (linear
    between its points, at the times the assist scheduled), then at its end until
    the next drive.
    """
    out = np.repeat(assist.initial_base[None], t.size, axis=0)
    for a in assist.assists:
        if len(a.base_route) == 0:
            continue
        sel = t >= a.base_times[0]
        ts = np.clip(t[sel], a.base_times[0], a.base_times[-1])
        out[sel] = np.stack([np.interp(ts, a.base_times, a.base_route[:, j]) for j in range(3)], 1)
    return out


def live_replay(
    demo: Demonstration, report: LiveReport, assist: RobotAssist | None
) -> tuple[Demonstration, dict[str, Any]]:
    """The replay demonstration and the trajectory document of a live run.

    Parameters
    ----------
    demo : Demonstration
        The recording that was streamed.
    report : LiveReport
        What the loop saw and did.
    assist : RobotAssist or None
        The loop's assist, when it ran.
    """
    keep = (demo.t >= report.t0 - 1e-9) & (demo.t <= report.t1 + 1e-9)
    t = demo.t[keep]
    bodies = list(demo.bodies)
    pos = {b.name: demo.pos(b.name)[keep] for b in bodies}
    quat = {b.name: demo.quat(b.name)[keep] for b in bodies}
    doc: dict[str, Any] = {
        "schema": "thirdhand.trajectory/1",
        "source": "thirdhand.live",
        "robot": None,
        "joint_names": [],
        "t": [],
        "q": [],
    }
    if assist is not None and assist.robot is not None:
        robot = assist.robot
        q = arm_configurations(assist, t)
        base = base_positions(assist, t)
        tool = robot.tool_transforms(q)  # the base where it stands last; it keeps its turn
        bodies.append(BodyInfo(TOOL_BODY, kind="tool"))
        pos[TOOL_BODY] = tool[:, :3, 3] + (base - robot.base_pose[0])
        quat[TOOL_BODY] = se3.quat_from_matrix(tool[:, :3, :3])
        doc |= robot_joints_document(robot, t, q)
        doc["base_pose"]["pos"] = [float(v) for v in assist.initial_base]
        if np.any(base != assist.initial_base):
            doc["base_pos"] = [[round(float(v), 6) for v in row] for row in base]
    doc["recognised"] = [
        {
            "t": round(float(e.time), 6),
            "kind": e.kind,
            "step": e.step + 1,
            "constraint": e.constraint,
            "parent": e.parent,
            "child": e.child,
        }
        for e in report.events
    ]
    doc["assists"] = list(report.assists)
    meta = dict(demo.meta) | {
        "source": "thirdhand.live",
        "recording": demo.meta.get("source"),
        "live_steps": doc["recognised"],
    }
    replay = Demonstration(t, bodies, pos, quat, labels=demo.labels, meta=meta)
    return replay, doc


def write_live_record(
    demo: Demonstration,
    report: LiveReport,
    assist: RobotAssist | None,
    out: str | os.PathLike[str],
) -> tuple[Path, Path]:
    """Write ``OUT.parquet`` and ``OUT.json`` (see the module docstring), each atomically.

    Returns
    -------
    replay, trajectory : pathlib.Path
    """
    from thirdhand import io

    replay_path, traj_path = record_paths(out)
    replay, doc = live_replay(demo, report, assist)
    io.save(replay, replay_path)
    atomic_write_bytes(
        traj_path, (jsontext.dumps(doc, what=str(traj_path), indent=1) + "\n").encode()
    )
    return replay_path, traj_path


__all__ = ["arm_configurations", "base_positions", "live_replay", "write_live_record"]
