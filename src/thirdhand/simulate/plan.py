"""The run to simulate: the arm's planned joint trajectory, its segments, steps and start poses.

Either planned now (:func:`from_execution`, the plan ``thirdhand execute`` makes)
or read back from a run recorded with ``thirdhand execute --record OUT``
(:func:`from_record`: ``OUT.json`` holds the trajectory and the steps,
``OUT.parquet`` the parts' poses, of which the first frame is the start).
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.readlimits import read_input
from thirdhand.simulate.parts import SimulateError
from thirdhand.task.model import TaskFile

#: The last metres of a learned insertion run straight in along the insertion axis: a
#: leg with a millimetre of clearance in its pocket jams when it comes in at an angle.
STRAIGHT_ENTRY_M = 0.02


@dataclass(frozen=True)
class Span:
    """One planned motion segment on the run's clock.

    Attributes
    ----------
    step : int
        Index of the step in the plan (-1: the final motion home).
    segment : str
        ``approach``, ``grasp``, ``lift``, ``transport``, ``insert``, ``retreat`` or ``home``.
    t_start, t_end : float
        Seconds on the planned clock.
    attached : str or None
        The part the planner had attached to the hand during it.
    """

    step: int
    segment: str
    t_start: float
    t_end: float
    attached: str | None


@dataclass(frozen=True)
class PlannedStep:
    """One step of the plan as the planner left it.

    Attributes
    ----------
    index : int
    constraint, parent, child : str
        The slot and the part put into it.
    planned : bool
        Whether the planner found motions for it.
    status : str
        The planner's status (its reason when not planned).
    grasp : str or None
        The grasp's name.
    """

    index: int
    constraint: str
    parent: str
    child: str
    planned: bool
    status: str
    grasp: str | None = None


@dataclass(frozen=True)
class RunPlan:
    """Everything the simulation replays.

    Attributes
    ----------
    robot : str
    robot_base : ndarray, shape (4, 4)
        Robot root pose, world frame.
    t : ndarray, shape (n,)
        Seconds, strictly increasing.
    q : ndarray, shape (n, dof)
        Planned joint positions, radians.
    spans : list of Span
    steps : list of PlannedStep
    start : dict of str to ndarray (4, 4)
        Every part's start pose, world frame.
    """

    robot: str
    robot_base: FloatArray
    t: FloatArray
    q: FloatArray
    spans: Sequence[Span]
    steps: Sequence[PlannedStep]
    start: Mapping[str, FloatArray]


def _spans(rows: Sequence[Mapping[str, Any]]) -> list[Span]:
    return [
        Span(int(s["step"]), str(s["segment"]), float(s["t_start"]), float(s["t_end"]),
             s.get("attached"))
        for s in rows
    ]  # fmt: skip


def _steps(rows: Sequence[Mapping[str, Any]]) -> list[PlannedStep]:
    return [
        PlannedStep(int(r["index"]), str(r["constraint"]), str(r["parent"]), str(r["child"]),
                    bool(r["success"]), str(r["status"]), r.get("grasp"))
        for r in rows
    ]  # fmt: skip


def from_execution(executor: Any, result: Any, *, rate_hz: float = 100.0) -> RunPlan:
    """The run of an :class:`~thirdhand.execute.executor.Executor`'s offline result."""
    from dataclasses import asdict

    from thirdhand.execute.record import sample_run

    spans: list[dict[str, Any]] = []
    t, q, _ = sample_run(executor.robot, result, rate_hz=rate_hz, spans=spans)
    start = result.trajectory[0]["static"] if result.trajectory else executor.start
    return RunPlan(
        robot=executor.robot.name,
        robot_base=se3.matrix_from_pose(*executor.robot.base_pose),
        t=np.asarray(t, dtype=np.float64),
        q=np.asarray(q, dtype=np.float64),
        spans=_spans(spans),
        steps=_steps([asdict(s) for s in result.steps]),
        start={k: np.asarray(v, dtype=np.float64) for k, v in start.items()},
    )


def sim_robot(task: TaskFile, robot: str | None) -> str:
    """The robot simulated: ``robot``, else the task's, else panda.

    Raises
    ------
    ThirdhandError
        An unknown robot, or one the physics simulation does not build.
    """
    from thirdhand.errors import ThirdhandError
    from thirdhand.execute.executor import task_defaults
    from thirdhand.execute.robot import ROBOTS
    from thirdhand.simulate.model import SIM_ROBOTS

    if robot is not None and robot not in ROBOTS:
        raise ThirdhandError(
            f"[simulate] robot {robot}: unknown (expected one of {', '.join(ROBOTS)})"
        )
    name, _ = task_defaults(task, robot)
    if name not in SIM_ROBOTS:
        raise SimulateError(
            f"robot {name!r}: the physics simulation builds {', '.join(SIM_ROBOTS)} only"
        )
    return name


def plan_offline(
    task: TaskFile,
    *,
    task_path: str | os.PathLike[str] | None,
    robot: str | None,
    seed: int,
    search: Sequence[str | os.PathLike[str]] = (),
    rate: float = 100.0,
) -> RunPlan:
    """Plan ``task`` offline as ``thirdhand execute`` does, with its settings' defaults.

    Parameters
    ----------
    task : TaskFile
    task_path : path-like or None
        Where the task file lies (its meshes are found beside it).
    robot : str or None
        The robot to plan for (None: the task's, else panda).
    seed : int
        Seed of the start layout and of the planner.
    search : sequence of path-like
        Folders searched for part meshes the task file does not find.
    rate : float
        Samples per second of the planned motion, Hz.

    Raises
    ------
    ThirdhandError
        An unknown robot, or one the physics simulation does not build.
    """
    from thirdhand.execute.executor import ExecutionOptions, Executor, task_defaults
    from thirdhand.execute.settings import ExecuteSettings

    ecfg = ExecuteSettings.model_validate({})
    opts = ExecutionOptions(
        sample_free_dofs=ecfg.free_dofs, step_time_limit=ecfg.step_time,
        plan_time_limit=ecfg.plan_time, order=ecfg.order, max_grasps=ecfg.max_grasps,
        n_goal_samples=ecfg.goals, placement=ecfg.placement, start_grasps=ecfg.start_grasps,
        regrasp=ecfg.regrasp, fit_grasps_to_fingers=True, straight_entry_m=STRAIGHT_ENTRY_M,
        straight_carry=True,
    )  # fmt: skip
    name = sim_robot(task, robot)
    _, assembly_xy = task_defaults(task, name, ecfg.assembly_at)
    if assembly_xy is None:
        assembly_xy = centred_assembly_xy(task, name, task_path=task_path, search=search)
    ex = Executor.for_task(
        task, name, seed=seed, options=opts, task_path=task_path, search=list(search),
        assembly_xy=assembly_xy,
    )  # fmt: skip
    result = ex.run_offline(seed=seed)
    return from_execution(ex, result, rate_hz=rate)


def centred_assembly_xy(
    task: TaskFile,
    robot: str,
    *,
    task_path: str | os.PathLike[str] | None = None,
    search: Sequence[str | os.PathLike[str]] = (),
) -> tuple[float, float]:
    """The robot's assembly spot moved sideways so the finished assembly is centred on the arm.

    The robot's own spot (``thirdhand.execute.layout``) puts the base part's origin
    in front of the arm; a chair built there has its back off to the arm's side,
    where the arm reaches it only folded. Moved along world ``y`` until the finished
    assembly's footprint is centred on the arm's first joint, every part is placed
    from in front. World x, y in metres.
    """
    from thirdhand.execute.layout import assembled_vertices, make_workcell, part_vertices

    cell = make_workcell(task, robot, task_path=task_path, search=search)
    objs = {o.name: o for o in task.objects}
    names = {cell.base} | {c.child for c in task.constraints}
    verts = {n: part_vertices(objs[n], task_path, search) for n in names if n in objs}
    placed = assembled_vertices(task, cell.base, verts)
    rot, at = cell.base_pose[:3, :3], cell.base_pose[:3, 3]
    ys = np.concatenate([(v @ rot.T + at)[:, 1] for v in placed.values()])
    shift = float(cell.arm_xy[1] - (ys.min() + ys.max()) / 2.0)
    return float(at[0]), float(at[1] + shift)


def from_record(path: Path, task: TaskFile) -> RunPlan:
    """A run recorded by ``thirdhand execute --record``: ``path`` (.json) and its .parquet.

    Raises
    ------
    SimulateError
        When a file is missing or malformed, or the run was recorded for another task.
    """
    from thirdhand import io

    def bad(msg: str) -> SimulateError:
        return SimulateError(f"--run {path}: {msg}")

    text = read_input(path, what="recorded run", error=bad)
    try:
        doc = json.loads(text)
        t = np.asarray(doc["t"], dtype=np.float64)
        q = np.asarray(doc["q"], dtype=np.float64)
        base = doc["base_pose"]
        robot = str(doc["robot"])
        spans = _spans(doc["segments"])
        steps = _steps(doc["steps"])
    except (ValueError, KeyError, TypeError) as exc:
        raise bad(f"not a run recorded by 'thirdhand execute --record' ({exc})") from None
    if q.ndim != 2 or q.shape[0] != t.shape[0] or t.shape[0] < 2:
        raise bad(f"'q' has shape {q.shape}, expected ({t.shape[0]}, dof)")
    objects = {o.name for o in task.objects}
    constraints = {c.id for c in task.constraints}
    for s in steps:
        if s.constraint not in constraints or s.child not in objects or s.parent not in objects:
            raise bad(
                f"recorded for another task: step {s.index} puts {s.child!r} into "
                f"{s.constraint!r} of {s.parent!r}, which this task does not have"
            )
    replay_path = path.with_suffix(".parquet")
    if not replay_path.is_file():
        raise bad(f"no replay {replay_path} beside it (the start poses of the parts)")
    replay = io.load(replay_path)
    start: dict[str, FloatArray] = {}
    for name in replay.body_names:
        if name not in objects:
            continue
        pos = np.asarray(replay.pos(name)[0], dtype=np.float64)
        quat = np.asarray(replay.quat(name)[0], dtype=np.float64)
        if np.all(np.isfinite(pos)) and np.all(np.isfinite(quat)):
            start[name] = se3.matrix_from_pose(pos, quat)
    missing = sorted({s.child for s in steps if s.planned} - set(start))
    if missing:
        raise bad(f"the replay {replay_path} has no start pose of {', '.join(missing)}")
    return RunPlan(
        robot=robot,
        robot_base=se3.matrix_from_pose(np.asarray(base["pos"]), np.asarray(base["quat"])),
        t=t,
        q=q,
        spans=spans,
        steps=steps,
        start=start,
    )
