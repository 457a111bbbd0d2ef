"""Online execution with pointing: the part a person points at is left to them, then re-checked."""

from __future__ import annotations

import pytest

from thirdhand.execute import Robot
from thirdhand.execute.executor import ExecutionOptions, Executor, person_does
from thirdhand.execute.layout import make_workcell, start_layout


def _bench_pointing_at_first(t1: float):
    """The bench task whose perception block says the person points at the plan's first leg."""
    from thirdhand.synth import make_scene
    from thirdhand.synth.task import truth_task

    task = truth_task(make_scene("bench", seed=0))
    first = task.plan[0].child
    from thirdhand.task.stages import PerceptionBlock, PointingRecord

    out = task.model_copy(deep=True)
    out.stages.perception = PerceptionBlock(
        pointing=[PointingRecord(hand="rh", object=first, t0=0.0, t1=t1)]
    )
    return out, first


def _executor(task, search, **options):
    cell = make_workcell(task, search=search)
    robot = Robot.load("panda", base_pose=(cell.robot_base[:3, 3], [0.0, 0.0, 0.0, 1.0]))
    start = start_layout(task, cell, 0, search=search)
    return Executor(robot, task, cell, start, ExecutionOptions(**options), search=search)


@pytest.fixture
def meshes(shared_data):
    return [str(shared_data / "3rdhand" / "meshes")]


@pytest.mark.slow
def test_the_robot_leaves_the_pointed_part_to_the_person(meshes) -> None:
    task, first = _bench_pointing_at_first(0.5)
    task = task.model_copy(update={"plan": task.plan[:3]})
    ex = _executor(task, meshes)
    ids = [s.constraint for s in task.plan]
    # the person puts the leg they pointed at in while the robot does its first step
    result = ex.run_online(seed=0, events={1: [person_does(task, ids[0], 3)]})
    assert result.success and result.n_collisions == 0
    status = {r.constraint: r.status for r in result.steps}
    assert status[ids[0]] == "done by person"
    assert status[ids[1]] == status[ids[2]] == "done"
    robot_order = [seg["step"] for seg in result.trajectory if seg["segment"] == "grasp"]
    assert robot_order == [1, 2]  # the plan's first step was skipped, not done first
    assert result.events[0].startswith(f"pointing: the person points at {first}")
    # without the perception hook the robot takes the plan's first step itself
    plain = _executor(task, meshes, use_perception=False).run_online(seed=0)
    assert [seg["step"] for seg in plain.trajectory if seg["segment"] == "grasp"] == [0, 1, 2]


@pytest.mark.slow
def test_a_pointed_part_nobody_places_is_the_robots_again_once_the_claim_lapses(meshes) -> None:
    task, first = _bench_pointing_at_first(2.0)
    task = task.model_copy(update={"plan": task.plan[:1]})
    ex = _executor(task, meshes, pointing_lookback_s=3.0, wait_s=1.0)
    result = ex.run_online(seed=0)
    assert result.success and result.n_collisions == 0
    (rep,) = result.steps
    assert rep.child == first and rep.status == "done"
    waits = [e for e in result.events if e.startswith("wait:")]
    assert len(waits) == 6  # the claim lasts to t = 2 + 3 s: the robot waits 1 s six times
