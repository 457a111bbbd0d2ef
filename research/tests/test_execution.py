"""The free-DOF experiment: hard instances and both conditions on a few seeds."""

from __future__ import annotations

import numpy as np
import pytest

from research.execution import RunOutcome, hard_setup, summary_table
from thirdhand import se3
from thirdhand.execute.goals import constraint_holds, goal_pose, invert


def _bench():
    from thirdhand.synth import make_scene
    from thirdhand.synth.task import truth_task

    return truth_task(make_scene("bench", seed=0))


def test_hard_setup_targets_the_farthest_slot_with_clutter() -> None:
    task = _bench()
    hard, cell, start, target = hard_setup(task, 3)
    far = {c.id: c for c in hard.constraints}[target]
    dists = {c.id: np.hypot(*goal_pose(cell.base_pose, c)[:2, 3]) for c in hard.constraints}
    assert dists[target] == pytest.approx(max(dists.values()))
    assert any(name.startswith("post") for name, _, _ in cell.fixtures)
    # the other legs are already in (inside their free DOFs); the target lies on the table
    for c in hard.constraints:
        rel = invert(start[c.parent]) @ start[c.child]
        assert constraint_holds(rel, c) == (c.id != target)
    # only the spin of the target changed: same position, free spin about the same axis
    orig = {c.id: c for c in task.constraints}[target]
    np.testing.assert_allclose(far.pos, orig.pos)
    assert constraint_holds(far.pose.matrix(), orig)
    again = hard_setup(task, 3)
    np.testing.assert_array_equal(again[2][far.child], start[far.child])


def test_summary_table_counts() -> None:
    outs = [
        RunOutcome(s, "c2", s % 2 == 0, s % 4 == 0, 1.0, 0.5, 0.25, "clutter") for s in range(8)
    ]
    outs += [RunOutcome(s, "c2", True, False, 2.0, 0.5, 0.5, "reach+clutter") for s in range(4)]
    lines = summary_table(outs).splitlines()
    assert len(lines) == 5
    assert "4/8" in lines[1] and "50.0 %" in lines[1] and "25.0 %" in lines[1]  # feasible 25 %
    assert "2/8" in lines[2] and "25.0 %" in lines[2] and "0.50 s" in lines[2]
    assert lines[3].startswith("reach+clutter") and "4/4" in lines[3] and "2.00 s" in lines[3]
    assert "0/4" in lines[4] and "50.0 %" in lines[4]


@pytest.mark.slow
def test_feasible_spins_agree_with_the_executor(shared_data) -> None:
    from research.execution import feasible_spins
    from thirdhand.execute import Robot
    from thirdhand.execute.executor import ExecutionOptions, Executor
    from thirdhand.execute.goals import vary

    search = [str(shared_data / "3rdhand" / "meshes")]
    robot = Robot.load("panda", base_pose=([0.0, 0.0, 0.75], [0.0, 0.0, 0.0, 1.0]))
    task, cell, start, target = hard_setup(_bench(), 3, search=search)
    feasible = feasible_spins(robot, task, cell, start, target, n_spins=12, seed=3, search=search)
    assert 0 < feasible.sum() < 12  # hard, yet reachable in principle
    c = {c.id: c for c in task.constraints}[target]
    for k in (int(np.argmax(feasible)), int(np.argmin(feasible))):
        # the constraint turned to spin k, planned with that goal only
        dofs = np.zeros(6)
        dofs[3] = -np.pi + 2 * np.pi * k / 12
        p, q = se3.pose_from_matrix(vary(c, dofs))
        new = c.model_copy(update={"pos": tuple(map(float, p)), "quat": tuple(map(float, q))})
        spun = task.model_copy(
            update={"constraints": [new if x.id == target else x for x in task.constraints]}
        )
        opts = ExecutionOptions(sample_free_dofs=False, step_time_limit=10.0, max_grasps=12)
        ex = Executor(robot, spun, cell, start, opts, search=search)
        world = ex.new_world()
        for x in spun.constraints:
            if x.id != target:
                world.scene.allow(x.child, x.parent)
        plan = ex.plan_step(world, 0, new, robot.home, 3)
        assert (plan.report.tried.place_reachable > 0) == bool(feasible[k]), (k, plan.report)


@pytest.mark.slow
def test_sampling_places_the_leg_where_the_demonstrated_goal_fails(shared_data) -> None:
    from research.execution import free_dof_experiment

    skipped: list[int] = []
    (o,) = free_dof_experiment(
        _bench(), [3], search=[str(shared_data / "3rdhand" / "meshes")], step_time_limit=20.0,
        skipped=skipped,
    )  # fmt: skip
    assert not skipped and o.seed == 3 and o.condition == "reach+clutter"
    assert 0.0 < o.feasible_fraction < 0.5  # hard, yet reachable in principle
    # the demonstrated spin is blocked; a spin inside the free DOF is not
    assert o.with_sampling and not o.without_sampling
