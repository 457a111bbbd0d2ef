"""Learned primitives in execution: placing along the DMP, and the fallback when it collides."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest

from thirdhand import se3
from thirdhand.execute import Robot
from thirdhand.execute.executor import ExecutionOptions, Executor
from thirdhand.execute.goals import dof_displacement, goal_pose, invert, vary
from thirdhand.execute.layout import make_workcell, start_layout
from thirdhand.execute.primitive_motion import find_primitive, primitive_place_path
from thirdhand.execute.record import write_run
from thirdhand.primitives.quaternion_dmp import PoseDMP
from thirdhand.primitives.serialize import pose_dmp_to_dict
from thirdhand.task.stages import PoseDmpParameters


@pytest.fixture(scope="module")
def learned_chair():
    """The chair task learned from one synthetic demonstration, with its primitives block."""
    from thirdhand.learn.run import learn_task
    from thirdhand.synth import make_scene

    demo = make_scene("chair", seed=0)
    return learn_task([demo], segment=False, reward=False).task


@pytest.fixture
def meshes(shared_data):
    return [str(shared_data / "3rdhand" / "meshes")]


def _line_dmp(
    goal_rel: np.ndarray, direction: np.ndarray, spin_axis=None, spin=0.0, length=0.3
) -> PoseDMP:
    """A pose DMP (parent frame) coming straight in to ``goal_rel`` from ``length × direction``.

    With ``spin_axis`` (child frame), the child also turns by ``spin`` radians about it
    on the way (as a person screwing a leg in), ending at the goal's orientation.
    """
    t = np.linspace(0.0, 2.0, 201)
    s = 10 * (t / 2) ** 3 - 15 * (t / 2) ** 4 + 6 * (t / 2) ** 5  # minimum jerk 0 → 1
    gp, gq = se3.pose_from_matrix(goal_rel)
    pos = gp + (1.0 - s)[:, None] * length * np.asarray(direction)
    if spin_axis is None:
        quat = np.tile(gq, (t.size, 1))
    else:
        from scipy.spatial.transform import Rotation

        turn = Rotation.from_rotvec(((1.0 - s) * spin)[:, None] * np.asarray(spin_axis))
        quat = (Rotation.from_quat(gq) * turn).as_quat()
    return PoseDMP(20).fit(t, pos, quat)


def test_primitive_place_path_ends_on_the_goal_and_drops_the_free_spin() -> None:
    from thirdhand.synth import make_scene
    from thirdhand.synth.task import truth_task

    task = truth_task(make_scene("chair", seed=0))
    c = next(c for c in task.constraints if c.child == "leg1")
    free = c.free_dof_array()
    assert np.ptp(free[3]) > 6.0 and np.ptp(free[4:], axis=1).max() == 0.0  # spins about x
    parent = se3.matrix_from_pose([0.5, 0.1, 0.9], [0.0, 0.0, np.sin(0.3), np.cos(0.3)])
    goal_rel = vary(c, [0, 0, 0, 1.1, 0, 0])  # a goal turned inside the free DOF
    axis_child = c.frame.matrix()[:3, 0]
    dmp = _line_dmp(goal_rel, [0.0, 0.0, 1.0], spin_axis=axis_child, spin=2.5)
    grasp = se3.matrix_from_pose([0.1, 0.0, 0.02], [1.0, 0.0, 0.0, 0.0])
    goal_w = parent @ goal_rel
    kept = primitive_place_path(
        dmp, parent_world=parent, child_goal=goal_w, grasp=grasp, length_m=0.06, constraint=c
    )
    np.testing.assert_allclose(kept[-1], goal_w @ grasp, atol=1e-12)
    child_rel = invert(parent) @ kept @ invert(grasp)
    dist = np.linalg.norm(child_rel[:, :3, 3] - goal_rel[:3, 3], axis=1)
    assert 0.06 <= dist[0] < 0.066 and np.all(np.diff(dist) <= 1e-9)
    d = dof_displacement(child_rel, c)
    np.testing.assert_allclose(d[:, 3], 1.1, atol=1e-6)  # the spin is the goal's throughout
    # the straight-in direction is the demonstrated one: +z of the parent
    lead = child_rel[:-1, :3, 3] - goal_rel[:3, 3]
    lead /= np.linalg.norm(lead, axis=1)[:, None]
    np.testing.assert_allclose(lead, np.tile([0.0, 0.0, 1.0], (len(lead), 1)), atol=1e-3)
    # without the constraint the person's screwing turn is followed as demonstrated
    raw = primitive_place_path(dmp, parent_world=parent, child_goal=goal_w, grasp=grasp)
    d_raw = dof_displacement(invert(parent) @ raw @ invert(grasp), c)
    assert np.ptp(d_raw[:, 3]) > 0.3
    # a primitive that never comes 6 cm from its goal has no final approach to follow
    assert (
        primitive_place_path(dmp, parent_world=parent, child_goal=goal_w, grasp=grasp, length_m=0.5)
        is None
    )


def _executor(task, seed, search, **options):
    cell = make_workcell(task, search=search)
    robot = Robot.load("panda", base_pose=(cell.robot_base[:3, 3], [0.0, 0.0, 0.0, 1.0]))
    start = start_layout(task, cell, seed, search=search)
    return Executor(robot, task, cell, start, ExecutionOptions(**options), search=search)


def _polyline_distance(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    """Distance (n,) of each point (n, 3) from the polyline through ``line`` (m, 3)."""
    a, b = line[:-1], line[1:]
    ab = b - a
    w = np.einsum("nmj,mj->nm", points[:, None] - a[None], ab) / np.maximum(
        np.einsum("mj,mj->m", ab, ab), 1e-18
    )
    foot = a[None] + np.clip(w, 0.0, 1.0)[..., None] * ab[None]
    return np.linalg.norm(points[:, None] - foot, axis=2).min(axis=1)


@pytest.mark.slow
def test_learned_chair_follows_its_primitives_without_collisions(
    learned_chair, meshes, tmp_path
) -> None:
    ex = _executor(learned_chair, 0, meshes)
    result = ex.run_offline(seed=0)
    assert result.success and result.n_collisions == 0
    assert all(r.success and r.n_dense > 0 for r in result.steps)
    kinds = {r.constraint: r.place_motion for r in result.steps}
    assert set(kinds.values()) <= {"primitive", "straight"}
    followed = [cid for cid, k in kinds.items() if k == "primitive"]
    assert followed, kinds
    # the executed insertion is the primitive's final approach, mapped through the grasp
    by_id = {c.id: c for c in learned_chair.constraints}
    for seg in result.trajectory:
        rep = next((r for r in result.steps if r.index == seg["step"]), None)
        if rep is None or seg["segment"] != "insert":
            continue
        assert seg["motion"] == rep.place_motion
        if rep.place_motion != "primitive":
            continue
        c = by_id[rep.constraint]
        dmp = find_primitive(learned_chair.stages.primitives, c.parent, c.child)
        assert dmp is not None
        parent = result.final_poses[c.parent]
        expect = primitive_place_path(
            dmp, parent_world=parent, child_goal=result.final_poses[c.child],
            grasp=invert(seg["t_tool_part"]), constraint=c,
        )  # fmt: skip
        got = ex.robot.tool_transforms(seg["path"])
        # ``final_poses`` is where the part ended, within the arm's IK precision of the
        # goal the executor used (0.1 mm): the resampled path may gain or lose a pose.
        assert abs(len(got) - len(expect)) <= 1
        np.testing.assert_allclose(got[-1, :3, 3], expect[-1, :3, 3], atol=2e-3)
        np.testing.assert_allclose(got[0, :3, 3], expect[0, :3, 3], atol=2e-3)
        assert _polyline_distance(got[:, :3, 3], expect[:, :3, 3]).max() < 2e-3
    # the JSON trajectory says which motion each segment used
    _, traj = write_run(ex.robot, result, tmp_path / "run.parquet")
    doc = json.loads(traj.read_text())
    assert {s["motion"] for s in doc["segments"]} >= {"planner", "straight", "primitive"}
    assert [s["place_motion"] for s in doc["steps"]] == [r.place_motion for r in result.steps]
    spans = [(s["t_start"], s["t_end"]) for s in doc["segments"]]
    assert all(a <= b for a, b in spans)
    assert all(b < a2 for (_, b), (a2, _) in itertools.pairwise(spans))


@pytest.mark.slow
def test_a_primitive_through_the_table_falls_back_to_the_straight_insertion(
    learned_chair, meshes
) -> None:
    task = learned_chair.model_copy(deep=True)
    cell = make_workcell(task, search=meshes)
    by_id = {c.id: c for c in task.constraints}
    # the lowest leg; a primitive coming up to its goal from 50 cm straight below (world down)
    step = min(task.plan, key=lambda s: goal_pose(cell.base_pose, by_id[s.constraint])[2, 3])
    c = by_id[step.constraint]
    height = goal_pose(cell.base_pose, c)[2, 3] - cell.table_z
    down_in_parent = cell.base_pose[:3, :3].T @ np.array([0.0, 0.0, -1.0])
    bad = _line_dmp(c.pose.matrix(), down_in_parent, length=0.5)
    assert task.stages.primitives is not None
    entry = next(e for e in task.stages.primitives.constraints.values() if e.child == c.child)
    entry.dmp = PoseDmpParameters.model_validate(pose_dmp_to_dict(bad))
    task = task.model_copy(update={"plan": [step]})
    # its final approach starts inside the table
    reach = height + 0.06
    kept = primitive_place_path(
        bad, parent_world=cell.base_pose, child_goal=goal_pose(cell.base_pose, c),
        grasp=np.eye(4), length_m=reach,
    )  # fmt: skip
    assert kept[0, 2, 3] < cell.table_z - 0.05
    ex = _executor(task, 0, meshes, primitive_m=reach)
    result = ex.run_offline(seed=0)
    (rep,) = result.steps
    assert rep.success and result.n_collisions == 0
    assert rep.place_motion == "straight" and rep.motions["insert"] == "straight"
    assert rep.tried.primitive_rejected >= 1
