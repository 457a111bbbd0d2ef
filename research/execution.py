"""The free-DOF experiment: success with and without sampling goals inside the free DOFs.

The report's claim: when the planner cannot reach an assembly pose, trying
variations of it inside the constraint's free DOFs (a leg turned about its own
axis) often succeeds where the demonstrated pose alone fails. Each run makes
one bench leg's goal hard to reach (:func:`hard_setup`):

- the other legs are already in their slots (turned at random) and posts
  (4 cm boxes, 20–35 cm high) stand on the table 12–20 cm around the target
  slot (clutter); in the ``reach+clutter`` condition the assembly also stands
  farther out (``assembly_xy``) so that the target slot (the farthest) lies
  near the arm's reach limit;
- the demonstrated spin of the target leg is drawn at random, as a person's
  would be (the demonstrated pose is one of many equivalent ones);
- the leg to place lies at a seeded spot on the table.

Only instances that are *reachable in principle* are kept
(:func:`feasible_spins`): of 24 spins of the leg evenly spread over its free
turn, at least one has a collision-free place configuration for one of the
grasps the executor would try. A seed whose instance is not is skipped (and
counted). The fraction of feasible spins is the chance that a random
demonstrated spin is reachable at all.

The executor then places the leg online (the held constraints are detected,
only the target step remains), once with sampling inside the free DOFs and once
with the demonstrated goal only, same seed, same world, same time limits.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.execute.executor import ExecutionOptions, Executor
from thirdhand.execute.goals import goal_pose, sample_goals, vary
from thirdhand.execute.layout import Workcell, make_workcell, part_vertices, start_layout
from thirdhand.execute.robot import Robot
from thirdhand.task.model import TaskFile

#: Experiment conditions: keyword arguments of :func:`hard_setup`.
CONDITIONS: dict[str, dict[str, Any]] = {
    "reach+clutter": {"assembly_xy": (0.58, 0.0), "n_posts": 3},
    "clutter": {"assembly_xy": (0.5, 0.0), "n_posts": 3},
}


@dataclass
class RunOutcome:
    """One run of the experiment, both conditions.

    Attributes
    ----------
    seed : int
    constraint : str
        The target constraint.
    with_sampling, without_sampling : bool
        Whether the step succeeded.
    time_with_s, time_without_s : float
        Planning time of the step, seconds.
    feasible_fraction : float
        Fraction of evenly spread spins with a collision-free place configuration
        (:func:`feasible_spins`); nan when not computed.
    condition : str
        Name of the condition (:data:`CONDITIONS`).
    """

    seed: int
    constraint: str
    with_sampling: bool
    without_sampling: bool
    time_with_s: float
    time_without_s: float
    feasible_fraction: float = float("nan")
    condition: str = ""


def hard_setup(
    task: TaskFile,
    seed: int,
    *,
    robot: str = "panda",
    assembly_xy: tuple[float, float] = (0.58, 0.0),
    n_posts: int = 3,
    task_path: str | os.PathLike[str] | None = None,
    search: Sequence[str | os.PathLike[str]] = (),
) -> tuple[TaskFile, Workcell, dict[str, FloatArray], str]:
    """A hard instance: work cell with clutter, start poses, and the target constraint id.

    Returns
    -------
    task : TaskFile
        A copy whose target constraint has a random demonstrated spin (inside
        its free DOFs).
    cell : Workcell
        With the clutter posts among its fixtures.
    start : dict of str to ndarray (4, 4)
        The other children at goals inside their free DOFs, the target on the table.
    target : str
        The target constraint's id.
    """
    rng = np.random.default_rng(seed)
    cell = make_workcell(task, robot, assembly_xy=assembly_xy, task_path=task_path, search=search)
    rx, ry = cell.robot_base[0, 3], cell.robot_base[1, 3]
    far = max(
        (c for c in task.constraints if c.parent == cell.base),
        key=lambda c: float(np.hypot(*(goal_pose(cell.base_pose, c)[:2, 3] - (rx, ry)))),
    )
    # the demonstrated pose: the nominal one turned at random inside the free DOFs
    p, q = se3.pose_from_matrix(sample_goals(np.eye(4), far, 2, rng, include_nominal=False)[0][0])
    new_far = far.model_copy(update={"pos": tuple(float(v) for v in p),
                                     "quat": tuple(float(v) for v in q)})  # fmt: skip
    hard = task.model_copy(
        update={"constraints": [new_far if c.id == far.id else c for c in task.constraints]}
    )
    start = start_layout(hard, cell, rng, task_path=task_path, search=search)
    for c in hard.constraints:
        if c.id != far.id and c.parent == cell.base:
            dofs = sample_goals(np.eye(4), c, 2, rng, include_nominal=False)[1][0]
            start[c.child] = cell.base_pose @ vary(c, dofs)
    slot = goal_pose(cell.base_pose, new_far)[:3, 3]
    fixtures = list(cell.fixtures)
    for k in range(n_posts):
        ang = rng.uniform(-np.pi, np.pi)
        r = rng.uniform(0.12, 0.2)
        centre = np.eye(4)
        height = float(rng.uniform(0.2, 0.35))
        centre[:3, 3] = [
            slot[0] + r * np.cos(ang),
            slot[1] + r * np.sin(ang),
            cell.table_z + height / 2,
        ]
        fixtures.append((f"post{k + 1}", centre, np.array([0.04, 0.04, height])))
    cell.fixtures = _clear_posts(fixtures, cell, start, hard)
    return hard, cell, start, far.id


Fixture = tuple[str, FloatArray, FloatArray]


def _clear_posts(
    fixtures: list[Fixture], cell: Workcell, start: dict[str, FloatArray], task: TaskFile
) -> list[Fixture]:
    """Drop posts that would overlap a part (at its start or goal) or the fixture."""
    objs = {o.name: o for o in task.objects}
    keep: list[Fixture] = []
    boxes: list[tuple[FloatArray, FloatArray]] = []
    for name, pose in start.items():
        v = part_vertices(objs[name]) @ pose[:3, :3].T + pose[:3, 3]
        boxes.append((v.min(axis=0) - 0.03, v.max(axis=0) + 0.03))
    for c in task.constraints:
        if c.parent == cell.base:
            g = goal_pose(cell.base_pose, c)
            v = part_vertices(objs[c.child]) @ g[:3, :3].T + g[:3, 3]
            boxes.append((v.min(axis=0) - 0.03, v.max(axis=0) + 0.03))
    for f in fixtures:
        name, pose, size = f
        if not name.startswith("post"):
            keep.append(f)
            continue
        lo, hi = pose[:3, 3] - size / 2, pose[:3, 3] + size / 2
        if not any(np.all(lo < b[1]) and np.all(b[0] < hi) for b in boxes):
            keep.append(f)
            boxes.append((lo - 0.03, hi + 0.03))
    return keep


def feasible_spins(
    robot: Robot,
    task: TaskFile,
    cell: Workcell,
    start: dict[str, FloatArray],
    target: str,
    *,
    n_spins: int = 24,
    max_grasps: int = 12,
    seed: int = 0,
    search: Sequence[str | os.PathLike[str]] = (),
) -> NDArray[np.bool_]:
    """Which of ``n_spins`` evenly spread spins of the target can be placed at all.

    A spin is feasible when, for one of the first ``max_grasps`` grasps the
    executor would try that reaches the part where it lies, inverse kinematics
    finds a collision-free configuration holding the part at that goal (the
    part touching its parent allowed). Motions are not planned: this says
    whether a goal is reachable in principle.

    Returns
    -------
    ndarray of bool, shape (n_spins,)
        Spin ``k`` turns the nominal goal by ``-π + 2πk / n_spins`` about the
        first free rotation of the constraint.
    """
    from thirdhand.execute.scene import GRIPPER
    from thirdhand.execute.step_search import candidate_grasps
    from thirdhand.execute.world import SimWorld

    c = next(c for c in task.constraints if c.id == target)
    free = np.flatnonzero(np.ptp(c.free_dof_array(), axis=1)[3:] > 0.0)
    if free.size == 0:
        raise ValueError(f"constraint {target!r} has no free rotation to spin about")
    world = SimWorld(robot, task, cell, start, search=search)
    scene = world.scene
    for other in task.constraints:
        if other.id != target:
            scene.allow(other.child, other.parent)
    part, parent = world.pose(c.child), world.pose(c.parent)
    spins = np.linspace(-np.pi, np.pi, n_spins, endpoint=False)
    goals = np.zeros((n_spins, 6))
    goals[:, 3 + free[0]] = spins
    feasible = np.zeros(n_spins, dtype=bool)
    for k, g in enumerate(candidate_grasps(task, c, {}, part, max_grasps)):
        scene.allow(GRIPPER, c.child)
        q_grasp = robot.ik(se3.pose_from_matrix(part @ g.pose), seed=seed + k, n_restarts=16,
                           accept=scene.is_valid)  # fmt: skip
        scene.disallow(GRIPPER, c.child)
        if q_grasp is None:
            continue
        scene.attach(c.child, q_grasp)
        scene.allow(c.child, c.parent)
        for j in np.flatnonzero(~feasible):
            t_place = parent @ vary(c, goals[j]) @ g.pose
            q = robot.ik(se3.pose_from_matrix(t_place), q_grasp, seed=seed + int(j), n_restarts=16,
                         accept=scene.is_valid)  # fmt: skip
            feasible[j] = q is not None
        scene.disallow(c.child, c.parent)
        scene.detach(c.child, q_grasp)
        if feasible.all():
            break
    return feasible


def run_once(
    robot: Robot,
    task: TaskFile,
    seed: int,
    *,
    sample_free_dofs: bool,
    step_time_limit: float = 20.0,
    plan_time_limit: float = 3.0,
    search: Sequence[str | os.PathLike[str]] = (),
    setup: tuple[TaskFile, Workcell, dict[str, FloatArray], str] | None = None,
    **condition: Any,
) -> tuple[bool, float, str]:
    """One condition of one run: (success, planning time of the step, target id).

    ``setup`` is the instance (:func:`hard_setup`), made from ``seed`` and
    ``condition`` when not given.
    """
    if setup is None:
        setup = hard_setup(task, seed, robot=robot.name, search=search, **condition)
    hard, cell, start, target = setup
    opts = ExecutionOptions(
        sample_free_dofs=sample_free_dofs, step_time_limit=step_time_limit,
        plan_time_limit=plan_time_limit, max_grasps=12, regrasp=False,
    )  # fmt: skip
    ex = Executor(robot, hard, cell, start, opts, search=search)
    res = ex.run_online(seed=seed)
    rep = next(r for r in res.steps if r.constraint == target)
    return rep.success and rep.status == "done", rep.planning_time_s, target


def free_dof_experiment(
    task: TaskFile,
    seeds: Sequence[int],
    *,
    robot_name: str = "panda",
    search: Sequence[str | os.PathLike[str]] = (),
    step_time_limit: float = 20.0,
    condition: str = "reach+clutter",
    skipped: list[int] | None = None,
) -> list[RunOutcome]:
    """Run both conditions on every seed whose instance is reachable in principle.

    Parameters
    ----------
    task : TaskFile
        The bench task (ground truth).
    seeds : sequence of int
    robot_name : str
    search : sequence of path
        Where to find the part meshes.
    step_time_limit : float
        Bound of the step's search, seconds.
    condition : str
        A key of :data:`CONDITIONS`.
    skipped : list of int, optional
        Receives the seeds whose instance had no feasible spin.

    Returns
    -------
    list of RunOutcome
    """
    if condition not in CONDITIONS:
        raise ValueError(f"condition {condition!r}: expected one of {sorted(CONDITIONS)}")
    kwargs = CONDITIONS[condition]
    robot = Robot.load(robot_name, base_pose=_base(robot_name))
    out = []
    for s in seeds:
        setup = hard_setup(task, s, robot=robot_name, search=search, **kwargs)
        feasible = feasible_spins(robot, *setup, seed=s, search=search)
        if not feasible.any():
            if skipped is not None:
                skipped.append(s)
            continue
        ok_w, t_w, target = run_once(robot, task, s, sample_free_dofs=True, search=search,
                                     step_time_limit=step_time_limit, setup=setup)  # fmt: skip
        ok_wo, t_wo, _ = run_once(robot, task, s, sample_free_dofs=False, search=search,
                                  step_time_limit=step_time_limit, setup=setup)  # fmt: skip
        out.append(RunOutcome(s, target, ok_w, ok_wo, t_w, t_wo, float(feasible.mean()), condition))
    return out


def _base(robot_name: str) -> tuple[FloatArray, FloatArray]:
    from thirdhand.execute.layout import ROBOT_BASES

    return np.asarray(ROBOT_BASES[robot_name], dtype=np.float64), np.array([0.0, 0.0, 0.0, 1.0])


def summary_table(outcomes: Sequence[RunOutcome]) -> str:
    """A plain-text table: per condition, success rate and median planning time per step.

    Outcomes are grouped by their ``condition`` (in order of appearance); each
    group gives a row with and a row without sampling, and the mean fraction of
    feasible spins (the chance that a random demonstrated spin is reachable at all).
    """
    groups: dict[str, list[RunOutcome]] = {}
    for o in outcomes:
        groups.setdefault(o.condition, []).append(o)
    head = (f"{'condition':<16} {'goals tried':<24} {'success':>7}  {'rate':>7}  "
            f"{'median t':>8}  {'feasible spins':>14}")  # fmt: skip
    rows = [head]
    for cond, outs in groups.items():
        n = len(outs)
        fr = [o.feasible_fraction for o in outs if np.isfinite(o.feasible_fraction)]
        feas = float(np.mean(fr)) if fr else float("nan")
        for label, ok, tm in (
            ("free-DOF sampling", [o.with_sampling for o in outs],
             [o.time_with_s for o in outs]),
            ("demonstrated goal only", [o.without_sampling for o in outs],
             [o.time_without_s for o in outs]),
        ):  # fmt: skip
            k = int(sum(ok))
            med = float(np.median(tm)) if tm else float("nan")
            rate = 100.0 * k / max(n, 1)
            rows.append(f"{cond or '-':<16} {label:<24} {k:>3}/{n:<3} {rate:6.1f} %"
                        f"  {med:7.2f} s  {100.0 * feas:12.1f} %")  # fmt: skip
    return "\n".join(rows)
