"""Goals inside the free DOFs, constraint detection, grasps and start layouts."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from thirdhand.execute.goals import (
    constraint_holds,
    displacement_matrix,
    dof_displacement,
    goal_pose,
    invert,
    sample_dofs,
    sample_goals,
    vary,
)
from thirdhand.execute.grasps import demo_grasps, rank_grasps, shape_grasps, tool_frame
from thirdhand.execute.layout import (
    assembled_vertices,
    base_part,
    make_workcell,
    part_vertices,
    start_layout,
)
from thirdhand.task.constraint import Constraint


def _random_pose(rng: np.random.Generator) -> np.ndarray:
    t = np.eye(4)
    t[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    t[:3, 3] = rng.normal(size=3)
    return t


def _revolute(frame_pos=(0.0, 0.0, 0.0), frame_quat=(0.0, 0.0, 0.0, 1.0)) -> Constraint:
    return Constraint.model_validate(
        {
            "id": "c1",
            "parent": "seat",
            "child": "leg",
            "type": "revolute",
            "pos": [0.1, 0.02, -0.1],
            "quat": [0.0, 0.0, 0.7071067811865476, 0.7071067811865476],
            "frame": {"pos": list(frame_pos), "quat": list(frame_quat)},
            "free_dofs": {"rx": [-np.pi, np.pi]},
        }
    )


def test_goal_pose_composes_parent_and_constraint() -> None:
    rng = np.random.default_rng(0)
    parent = _random_pose(rng)
    c = _revolute()
    g = goal_pose(parent, c)
    np.testing.assert_allclose(invert(parent) @ g, c.pose.matrix(), atol=1e-12)


def test_vary_turns_about_the_constraint_axis_only() -> None:
    # constraint frame 0.2 m along the child's x, turned: the axis passes through it
    c = _revolute(
        frame_pos=(0.2, 0.0, 0.0), frame_quat=(0.0, 0.0, np.sin(np.pi / 8), np.cos(np.pi / 8))
    )
    f = c.frame.matrix()
    t = vary(c, [0.0, 0.0, 0.0, 1.1, 0.0, 0.0])
    # the constraint frame's origin and x axis stay where they were (parent frame)
    before = c.pose.matrix() @ f
    after = t @ f
    np.testing.assert_allclose(after[:3, 3], before[:3, 3], atol=1e-12)
    np.testing.assert_allclose(after[:3, 0], before[:3, 0], atol=1e-12)
    angle = np.arccos(np.clip(after[:3, 1] @ before[:3, 1], -1, 1))
    assert angle == pytest.approx(1.1, abs=1e-9)


def test_dof_displacement_inverts_vary() -> None:
    rng = np.random.default_rng(1)
    c = _revolute(
        frame_pos=(0.05, 0.01, 0.0),
        frame_quat=tuple(np.array([0.1, 0.2, 0.3, 0.927]) / np.linalg.norm([0.1, 0.2, 0.3, 0.927])),
    )
    dofs = np.column_stack([rng.uniform(-0.1, 0.1, (20, 3)), rng.uniform(-1.0, 1.0, (20, 3))])
    back = dof_displacement(vary(c, dofs), c)
    np.testing.assert_allclose(back, dofs, atol=1e-9)
    np.testing.assert_allclose(displacement_matrix(np.zeros(6)), np.eye(4))


def test_samples_stay_inside_the_ranges_and_are_seeded() -> None:
    c = _revolute()
    a = sample_dofs(c, 50, 3)
    np.testing.assert_array_equal(a, sample_dofs(c, 50, 3))
    assert np.all(a[:, [0, 1, 2, 4, 5]] == 0.0)
    assert np.all(np.abs(a[:, 3]) <= np.pi)
    np.testing.assert_array_equal(a[0], np.zeros(6))  # the demonstrated pose first
    goals, _ = sample_goals(np.eye(4), c, 10, 4)
    assert all(constraint_holds(g, c) for g in goals)


def test_constraint_holds_detects_locked_violations() -> None:
    c = _revolute()
    t = c.pose.matrix()
    assert constraint_holds(t, c)
    assert constraint_holds(vary(c, [0, 0, 0, 2.5, 0, 0]), c)  # free spin
    assert constraint_holds(vary(c, [0.004, 0, 0, 0, 0, 0]), c)  # within 5 mm
    assert not constraint_holds(vary(c, [0.02, 0, 0, 0, 0, 0]), c)  # slipped out
    assert not constraint_holds(vary(c, [0, 0, 0, 0, 0.2, 0]), c)  # tilted
    fixed = c.model_copy(update={"free_dofs": type(c.free_dofs)()})
    assert not constraint_holds(vary(c, [0, 0, 0, 0.5, 0, 0]), fixed)


def test_tool_frame_is_right_handed() -> None:
    t = tool_frame([0.1, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.2])
    np.testing.assert_allclose(t[:3, :3].T @ t[:3, :3], np.eye(3), atol=1e-12)
    assert np.linalg.det(t[:3, :3]) == pytest.approx(1.0)
    np.testing.assert_allclose(t[:3, 2], [0.0, 0.0, -1.0])


def test_shape_grasps_of_a_rod_close_across_its_axis() -> None:
    gs = shape_grasps([0.0, -0.04, -0.04], [0.28, 0.04, 0.04])
    side = [g for g in gs if g.label == "side"]
    end = [g for g in gs if g.label == "end"]
    assert len(side) == 5 * 12 * 2 and len(end) == 8
    for g in side:
        assert abs(g.pose[0, 2]) < 1e-12 and abs(g.pose[0, 1]) < 1e-12  # ⊥ axis
        np.testing.assert_allclose(g.pose[1:3, 3], 0.0, atol=1e-12)  # on the axis
    for g in end:
        assert abs(abs(g.pose[0, 2]) - 1.0) < 1e-12
    ranked = rank_grasps(gs, avoid=[0.0, 0.0, 0.0])
    assert ranked[0].pose[0, 3] > 0.2  # held far from the end that goes into the slot


def test_shape_grasps_of_a_plate_and_a_box() -> None:
    plate = shape_grasps([-0.2, -0.42, -0.015], [0.2, 0.0, 0.015])
    assert {g.label for g in plate} == {"face", "edge"}
    face = [g for g in plate if g.label == "face"]
    assert all(abs(abs(g.pose[2, 2]) - 1.0) < 1e-12 for g in face)  # along the normal
    box = shape_grasps([-0.1, -0.1, -0.1], [0.1, 0.1, 0.1])
    assert len(box) == 6 * 4


def test_demo_grasps_recover_where_the_fingers_held(chair) -> None:
    demo, task = chair
    c = task.constraints[0]
    obj = next(o for o in task.objects if o.name == c.child)
    gs = demo_grasps(demo, c.child, c.time, bbox=(obj.bbox_min, obj.bbox_max))
    assert gs and gs[0].source == "demo"
    p = gs[0].pose[:3, 3]
    # the person held the leg along its length, near its surface (synthetic scene: 0.10–0.18 m)
    assert 0.08 < p[0] < 0.2
    assert np.hypot(p[1], p[2]) < 0.06
    # the approach points at the leg's axis
    radial = np.array([0.0, -p[1], -p[2]])
    if np.linalg.norm(radial) > 1e-3:
        assert gs[0].pose[:3, 2] @ radial / np.linalg.norm(radial) > 0.5


@pytest.fixture(scope="module")
def chair():
    from thirdhand.synth import make_scene
    from thirdhand.synth.task import truth_task

    demo = make_scene("chair", seed=0)
    return demo, truth_task(demo)


@pytest.fixture(scope="module")
def bench():
    from thirdhand.synth import make_scene
    from thirdhand.synth.task import truth_task

    return truth_task(make_scene("bench", seed=0))


def test_assembly_pose_of_the_bench_lays_the_seat_legs_up(bench) -> None:
    cell = make_workcell(bench)
    assert cell.base == base_part(bench) == "seating"
    # the seat frame's y (towards the legs) points up, the seat rests on the table
    np.testing.assert_allclose(cell.base_pose[:3, 1], [0.0, 0.0, 1.0], atol=1e-12)
    assert cell.fixtures == []
    objs = {o.name: o for o in bench.objects}
    v = part_vertices(objs["seating"]) @ cell.base_pose[:3, :3].T + cell.base_pose[:3, 3]
    assert v[:, 2].min() == pytest.approx(cell.table_z)


def test_assembly_pose_of_the_chair_clears_the_table(chair) -> None:
    _, task = chair
    cell = make_workcell(task)
    objs = {o.name: o for o in task.objects}
    verts = {n: part_vertices(objs[n]) for n in objs if objs[n].kind == "part"}
    placed = assembled_vertices(task, cell.base, verts)
    every = np.vstack(
        [v @ cell.base_pose[:3, :3].T + cell.base_pose[:3, 3] for v in placed.values()]
    )
    assert every[:, 2].min() > cell.table_z  # nothing through the table (the back, the legs)
    assert len(cell.fixtures) == 1
    _, pose, size = cell.fixtures[0]
    assert pose[2, 3] - size[2] / 2 == pytest.approx(cell.table_z)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_start_layout_lies_on_the_table_without_overlaps(bench, seed) -> None:
    cell = make_workcell(bench)
    lay = start_layout(bench, cell, seed)
    assert set(lay) == {"seating", "leg1", "leg2", "leg3", "leg4"}
    np.testing.assert_array_equal(lay["seating"], cell.base_pose)
    objs = {o.name: o for o in bench.objects}
    boxes = []
    for name, t in lay.items():
        v = part_vertices(objs[name]) @ t[:3, :3].T + t[:3, 3]
        if name != "seating":
            assert v[:, 2].min() == pytest.approx(cell.table_z)
            r = np.hypot(*(v[:, :2].mean(axis=0)))
            assert 0.2 < r < 0.9
        boxes.append((v.min(axis=0), v.max(axis=0)))
    for i in range(len(boxes)):
        for j in range(i + 1, len(boxes)):
            a, b = boxes[i], boxes[j]
            assert not (np.all(a[0][:2] < b[1][:2]) and np.all(b[0][:2] < a[1][:2]))
    again = start_layout(bench, cell, seed)
    assert all(np.array_equal(again[k], lay[k]) for k in lay)
