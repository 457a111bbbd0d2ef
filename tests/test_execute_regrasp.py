"""A far start spot solved by a regrasp through an intermediate placement."""

from __future__ import annotations

import numpy as np
import pytest

from thirdhand.execute.executor import ExecutionOptions, Executor
from thirdhand.execute.regrasp import NEAR_M


def _far_leg_on_panda(regrasp: bool) -> tuple[Executor, str]:
    # The chair built out at (0.72, 0.2), its first leg laid 0.98 m from the arm at -35°,
    # turned half a turn: the one grasp the arm reaches there reaches none of its goals.
    from thirdhand.synth import make_scene
    from thirdhand.synth.task import truth_task

    task = truth_task(make_scene("chair", seed=0))
    task = task.model_copy(update={"plan": task.plan[:1]})
    c = next(c for c in task.constraints if c.id == task.plan[0].constraint)
    opts = ExecutionOptions(regrasp=regrasp, step_time_limit=40.0, plan_time_limit=3.0)
    ex = Executor.for_task(task, "panda", seed=0, assembly_xy=(0.72, 0.2), options=opts)
    p = ex.start[c.child].copy()
    p[:3, :3] = np.diag([-1.0, -1.0, 1.0]) @ p[:3, :3]
    ang = np.radians(-35.0)
    p[:2, 3] = np.asarray(ex.cell.arm_xy) + 0.98 * np.array([np.cos(ang), np.sin(ang)])
    ex.start[c.child] = p
    return ex, c.child


def _check_regrasped(ex: Executor, result, part: str) -> None:
    assert result.success, [r.status for r in result.steps]
    assert result.n_collisions == 0
    (rep,) = result.steps
    assert rep.n_dense > 0 and rep.n_collisions == 0
    g = rep.regrasp
    assert g is not None
    # put down near the arm, resting on the table, and picked again from there
    assert g.distance_m < NEAR_M  # the centre of the part, as the spots are drawn
    assert g.spot[2] == pytest.approx(ex.start[part][2, 3], abs=0.05)
    assert g.spots[1] >= 1 and g.spots[0] >= g.spots[1]
    names = [seg["segment"] for seg in result.trajectory if seg["step"] == rep.index]
    assert names.index("regrasp put down") < names.index("approach") < names.index("insert")
    # the part was released at the spot between the two picks (to the IK's tolerance: 0.1 mm
    # and 1 mrad at the tool, over a lever under 0.3 m)
    down = next(seg for seg in result.trajectory if seg["segment"] == "regrasp retreat")
    np.testing.assert_allclose(down["static"][part][:3, 3], g.spot, atol=4e-4)
    assert "regrasp put down" in rep.motions


@pytest.mark.slow
def test_far_start_spot_on_the_panda_is_solved_by_a_regrasp() -> None:
    ex, part = _far_leg_on_panda(regrasp=False)
    plain = ex.run_offline(seed=0)
    (rep,) = plain.steps
    # the cause: one grasp reached where the leg lies, no grasp reaches both ends
    assert not plain.success and not rep.success
    assert rep.status.startswith("no reachable goal")
    assert rep.tried.grasps_reachable == 1 and rep.tried.grasps_reach_both == 0
    assert rep.tried.grasp_ik_failed + rep.tried.grasp_in_collision == 23
    assert rep.regrasp is None

    ex, part = _far_leg_on_panda(regrasp=True)
    result = ex.run_offline(seed=0)
    _check_regrasped(ex, result, part)
    assert result.steps[0].regrasp.plain_status.startswith("no reachable goal")


@pytest.mark.slow
def test_a_far_leg_that_baxter_reaches_is_not_regrasped() -> None:
    # The learned bench of seed 4 with leg1 laid 0.78 m from Baxter's right shoulder: one
    # of its grasps reaches there and its goal: the step is done straight, without a regrasp.
    from thirdhand.learn.run import learn_task
    from thirdhand.synth import make_scene

    task = learn_task(
        [make_scene("bench", seed=4)], primitives=False, reward=False, grasps=False
    ).task
    step = next(s for s in task.plan if s.child == "leg1")
    task = task.model_copy(update={"plan": [step.model_copy(update={"after": []})]})
    ex = Executor.for_task(
        task, "baxter", seed=4, options=ExecutionOptions(step_time_limit=30.0, plan_time_limit=3.0)
    )
    d = ex.start["leg1"][:2, 3] - np.asarray(ex.cell.arm_xy)
    ex.start["leg1"][:2, 3] = np.asarray(ex.cell.arm_xy) + 0.78 * d / np.hypot(*d)
    result = ex.run_offline(seed=4)
    assert result.success and result.n_collisions == 0
    (rep,) = result.steps
    assert rep.regrasp is None and rep.tried.grasps_reachable >= 1
    names = [seg["segment"] for seg in result.trajectory if seg["step"] == rep.index]
    assert "regrasp put down" not in names
