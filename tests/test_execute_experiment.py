"""The free-DOF experiment: hard instances and both conditions on a few seeds."""

from __future__ import annotations

import numpy as np
import pytest

from thirdhand.execute.experiments import RunOutcome, hard_setup, summary_table
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
    outs = [RunOutcome(s, "c2", s % 2 == 0, s % 4 == 0, 1.0, 0.5) for s in range(8)]
    table = summary_table(outs)
    assert "4/8" in table and "2/8" in table and "50.0 %" in table and "25.0 %" in table


@pytest.mark.slow
def test_sampling_never_does_worse_than_the_demonstrated_goal(shared_data) -> None:
    from thirdhand.execute.experiments import free_dof_experiment

    outs = free_dof_experiment(
        _bench(), [3, 8], search=[str(shared_data / "3rdhand" / "meshes")], step_time_limit=10.0
    )
    for o in outs:
        assert o.with_sampling or not o.without_sampling
    assert sum(o.with_sampling for o in outs) >= sum(o.without_sampling for o in outs)
