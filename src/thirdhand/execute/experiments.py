"""The free-DOF experiment: success with and without sampling goals inside the free DOFs.

The report's claim: when the planner cannot reach an assembly pose, trying
variations of it inside the constraint's free DOFs (a leg turned about its own
axis) often succeeds where the demonstrated pose alone fails. Each run makes
one goal hard to reach:

- the assembly stands far out on the table (``assembly_xy``), so the slot
  farthest from the robot lies near the arm's reach limit;
- the other legs are already in their slots (turned at random), and posts
  (boxes) stand on the table around the target slot (clutter);
- the demonstrated spin of the target leg is drawn at random, as a person's
  would be (the demonstrated pose is one of many equivalent ones);
- the leg to place lies at a seeded spot on the table.

The executor then places the leg online (the held constraints are detected,
only the target step remains), once with sampling inside the free DOFs and once
with the demonstrated goal only, same seed, same world, same time limits.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from thirdhand import se3
from thirdhand.execute.executor import ExecutionOptions, Executor
from thirdhand.execute.goals import goal_pose, sample_goals, vary
from thirdhand.execute.layout import Workcell, make_workcell, part_vertices, start_layout
from thirdhand.execute.robot import Robot
from thirdhand.task.model import TaskFile

FloatArray = NDArray[np.float64]


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
    """

    seed: int
    constraint: str
    with_sampling: bool
    without_sampling: bool
    time_with_s: float
    time_without_s: float


def hard_setup(
    task: TaskFile,
    seed: int,
    *,
    robot: str = "panda",
    assembly_xy: tuple[float, float] = (0.66, 0.0),
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
    p, q = se3.matrix_to_pose(sample_goals(np.eye(4), far, 2, rng, include_nominal=False)[0][0])
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


def run_once(
    robot: Robot,
    task: TaskFile,
    seed: int,
    *,
    sample_free_dofs: bool,
    step_time_limit: float = 20.0,
    plan_time_limit: float = 3.0,
    search: Sequence[str | os.PathLike[str]] = (),
) -> tuple[bool, float, str]:
    """One condition of one run: (success, planning time of the step, target id)."""
    hard, cell, start, target = hard_setup(task, seed, robot=robot.name, search=search)
    opts = ExecutionOptions(
        sample_free_dofs=sample_free_dofs, step_time_limit=step_time_limit,
        plan_time_limit=plan_time_limit, max_grasps=12,
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
) -> list[RunOutcome]:
    """Run both conditions on every seed.

    Returns
    -------
    list of RunOutcome
    """
    robot = Robot.load(robot_name, base_pose=_base(robot_name))
    out = []
    for s in seeds:
        ok_w, t_w, target = run_once(robot, task, s, sample_free_dofs=True, search=search,
                                     step_time_limit=step_time_limit)  # fmt: skip
        ok_wo, t_wo, _ = run_once(robot, task, s, sample_free_dofs=False, search=search,
                                  step_time_limit=step_time_limit)  # fmt: skip
        out.append(RunOutcome(s, target, ok_w, ok_wo, t_w, t_wo))
    return out


def _base(robot_name: str) -> tuple[FloatArray, FloatArray]:
    from thirdhand.execute.layout import ROBOT_BASES

    return np.asarray(ROBOT_BASES[robot_name], dtype=np.float64), np.array([0.0, 0.0, 0.0, 1.0])


def summary_table(outcomes: Sequence[RunOutcome]) -> str:
    """A plain-text table: success rate and median planning time per condition."""
    n = len(outcomes)
    rows = []
    for label, ok, tm in (
        ("with free-DOF sampling", [o.with_sampling for o in outcomes],
         [o.time_with_s for o in outcomes]),
        ("demonstrated goal only", [o.without_sampling for o in outcomes],
         [o.time_without_s for o in outcomes]),
    ):  # fmt: skip
        k = int(sum(ok))
        rows.append(f"{label:<26} {k:>3}/{n:<3} {100.0 * k / max(n, 1):6.1f} %  "
                    f"{float(np.median(tm)) if tm else float('nan'):7.2f} s")  # fmt: skip
    head = f"{'condition':<26} {'success':>7}  {'rate':>8}  {'median t':>8}"
    return "\n".join([head, *rows])
