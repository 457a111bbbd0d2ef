"""The executor on the synthetic chair and bench: offline, online with a person, failure reports."""

from __future__ import annotations

import json

import numpy as np
import pytest

from thirdhand.execute import Robot
from thirdhand.execute.executor import (
    ExecutionOptions,
    Executor,
    detect_done,
    insertion_axis,
    person_does,
    slip,
)
from thirdhand.execute.goals import constraint_holds, invert
from thirdhand.execute.layout import (
    assembled_vertices,
    base_part,
    make_workcell,
    part_vertices,
    start_layout,
)
from thirdhand.execute.record import TOOL_BODY, read_trajectory, write_run


@pytest.fixture
def meshes(shared_data):
    return [str(shared_data / "3rdhand" / "meshes")]


def _task(scene: str):
    from thirdhand.synth import make_scene
    from thirdhand.synth.task import truth_task

    return truth_task(make_scene(scene, seed=0))


def _executor(task, seed, search, **options):
    cell = make_workcell(task, search=search)
    robot = Robot.load("panda", base_pose=(cell.robot_base[:3, 3], [0.0, 0.0, 0.0, 1.0]))
    start = start_layout(task, cell, seed, search=search)
    return Executor(robot, task, cell, start, ExecutionOptions(**options), search=search)


def _check_assembled(ex, result):
    assert result.success, [r.status for r in result.steps]
    assert result.n_collisions == 0
    assert all(r.success for r in result.steps)
    planned = {s.constraint for s in ex.task.plan}
    for c in ex.bound_task().constraints:  # each slot with the part put into it
        if c.id not in planned:
            continue
        rel = invert(result.final_poses[c.parent]) @ result.final_poses[c.child]
        assert constraint_holds(rel, c)


def test_insertion_axes_of_the_chair() -> None:
    task = _task("chair")
    by_child = {c.child: c for c in task.constraints}
    np.testing.assert_array_equal(insertion_axis(task, by_child["leg1"]), [1.0, 0.0, 0.0])
    np.testing.assert_array_equal(insertion_axis(task, by_child["back"]), [0.0, -1.0, 0.0])


@pytest.mark.slow
@pytest.mark.parametrize("scene", ["bench", "chair"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_offline_every_step_succeeds_without_collisions(scene, seed, meshes) -> None:
    task = _task(scene)
    ex = _executor(task, seed, meshes)
    result = ex.run_offline(seed=seed)
    _check_assembled(ex, result)
    # the executor chooses the order: every slot once, each with its own part here
    assert {r.constraint: r.child for r in result.steps} == {
        s.constraint: s.child for s in task.plan
    }
    assert all(r.n_dense > 0 for r in result.steps)


@pytest.mark.parametrize("robot", ["panda", "baxter"])
@pytest.mark.parametrize("scene", ["bench", "chair"])
def test_assembly_keeps_out_of_the_arms_inner_radius(scene, robot, monkeypatch) -> None:
    # with boxes for parts the chair's back used to point at the Panda, its far end 8 cm
    # from the first joint (inside panda_link1): no place configuration was valid
    monkeypatch.delenv("THIRDHAND_MESH_PATH", raising=False)
    task = _task(scene)
    cell = make_workcell(task, robot)
    objs = {o.name: o for o in task.objects}
    base = base_part(task)
    verts = {n: part_vertices(objs[n]) for n in {base} | {c.child for c in task.constraints}}
    placed = assembled_vertices(task, base, verts)
    every = np.vstack(list(placed.values())) @ cell.base_pose[:3, :3].T + cell.base_pose[:3, 3]
    dist = np.linalg.norm(every[:, :2] - np.asarray(cell.arm_xy), axis=1)
    assert dist.min() >= cell.reach[0]


@pytest.mark.slow
def test_chair_with_bounding_boxes_only_every_step_succeeds(monkeypatch) -> None:
    # regression: without meshes the back's last step found no valid place configuration
    monkeypatch.delenv("THIRDHAND_MESH_PATH", raising=False)
    task = _task("chair")
    ex = _executor(task, 0, [])
    result = ex.run_offline(seed=0)
    _check_assembled(ex, result)
    # the executor chooses the order: every slot once, each with its own part here
    assert {r.constraint: r.child for r in result.steps} == {
        s.constraint: s.child for s in task.plan
    }


@pytest.mark.slow
def test_online_person_does_two_steps_and_the_robot_the_rest(meshes, tmp_path) -> None:
    task = _task("bench")
    ex = _executor(task, 0, meshes)
    ids = [s.constraint for s in task.plan]
    # after the robot's first step the person puts in two legs (the 2nd and 4th of the plan)
    events = {1: [person_does(task, ids[1], 5), person_does(task, ids[3], 6)]}
    result = ex.run_online(seed=0, events=events)
    _check_assembled(ex, result)
    status = {r.constraint: r.status for r in result.steps}
    assert status[ids[1]] == status[ids[3]] == "done by person"
    assert status[ids[0]] == status[ids[2]] == "done"
    assert len(result.events) == 2
    # the replay: parts and the tool frame; the trajectory round-trips
    replay, traj = write_run(ex.robot, result, tmp_path / "replay.parquet")
    from thirdhand import io

    demo = io.load(replay)
    assert TOOL_BODY in demo.body_names and demo.info(TOOL_BODY).kind == "tool"
    assert {"seating", "leg1", "leg2", "leg3", "leg4"} <= set(demo.body_names)
    t, q, names = read_trajectory(traj)
    assert q.shape == (t.size, ex.robot.dof) and names == ex.robot.joint_names
    doc = json.loads(traj.read_text())
    assert doc["n_collisions"] == 0 and len(doc["steps"]) == 4
    # the tool's recorded path is the forward kinematics of the joint trajectory
    pos, _ = ex.robot.fk_batch(q)
    np.testing.assert_allclose(demo.pos(TOOL_BODY), pos, atol=1e-6)


@pytest.mark.slow
def test_online_puts_back_a_leg_that_slipped(meshes) -> None:
    task = _task("bench")
    task = task.model_copy(update={"plan": task.plan[:2]})
    ex = _executor(task, 1, meshes)
    ids = [s.constraint for s in task.plan]
    result = ex.run_online(seed=1, events={1: [slip(task, ids[0], 0.04)]})
    _check_assembled(ex, result)
    assert result.events and result.events[0].startswith("slip")


def test_unreachable_constraint_ends_with_a_failure_report(meshes) -> None:
    task = _task("bench")
    c0 = task.plan[0].constraint
    far = [
        c.model_copy(update={"pos": (c.pos[0] + 2.0, c.pos[1], c.pos[2])}) if c.id == c0 else c
        for c in task.constraints
    ]
    task = task.model_copy(update={"constraints": far, "plan": task.plan[:2]})
    # The step budget is wall-clock: generous, so a loaded machine does not fail the good step.
    ex = _executor(task, 0, meshes, step_time_limit=40.0, max_grasps=6, n_goal_samples=6)
    result = ex.run_offline(seed=0)
    assert not result.success
    first, second = result.steps
    assert not first.success and first.constraint == c0
    assert "no reachable goal" in first.status or "time limit" in first.status
    assert first.tried.grasps > 0 and first.tried.place_reachable == 0
    # 2 m out: the place IK never converges (not a collision), and the status says so
    assert first.tried.place_ik_failed > 0 and first.tried.place_in_collision == 0
    assert f"place IK: {first.tried.place_ik_failed} unreachable" in first.status
    assert second.success and result.n_collisions == 0


def test_detect_done_at_the_start_and_after_a_person(meshes) -> None:
    task = _task("bench")
    ex = _executor(task, 2, meshes)
    world = ex.new_world()
    assert not any(detect_done(world, task).values())
    cid = task.plan[2].constraint
    person_does(task, cid, 0)(world)
    done = detect_done(world, task)
    assert done[cid] and sum(done.values()) == 1
