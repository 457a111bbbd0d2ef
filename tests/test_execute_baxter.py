"""Baxter's work cell (right arm, torso on its pedestal behind the table) and runs on it."""

from __future__ import annotations

import numpy as np
import pytest

from thirdhand.execute import CollisionScene, Robot
from thirdhand.execute.executor import ExecutionOptions, Executor
from thirdhand.execute.layout import make_workcell, start_layout


def _task(scene: str):
    from thirdhand.synth import make_scene
    from thirdhand.synth.task import truth_task

    return truth_task(make_scene(scene, seed=0))


@pytest.fixture(scope="module")
def baxter():
    return Robot.load("baxter", base_pose=([-0.25, 0.22, 0.93], [0.0, 0.0, 0.0, 1.0]))


def test_baxter_stands_at_the_table_without_touching_it(baxter) -> None:
    task = _task("bench")
    cell = make_workcell(task, "baxter")
    np.testing.assert_allclose(cell.robot_base[:3, 3], [-0.25, 0.22, 0.93])
    np.testing.assert_allclose(baxter.base_pose[0], cell.robot_base[:3, 3])
    # the right shoulder is where the cell says the arm is
    shoulder, _ = baxter.frame_pose(baxter.home, "right_upper_shoulder")
    np.testing.assert_allclose(shoulder[:2], cell.arm_xy, atol=2e-3)
    assert shoulder[2] - cell.table_z == pytest.approx(0.31, abs=0.01)
    scene = CollisionScene(baxter)
    scene.add_table(height=cell.table_z, size=cell.table_size, center=cell.table_center)
    assert scene.is_valid(baxter.home), scene.collisions(baxter.home)
    # the table reaching 10 cm nearer would cut the pedestal's column
    x0, x1, y0, y1 = cell.table_extent
    near = CollisionScene(baxter)
    near.add_table(height=cell.table_z, size=(x1 - x0 + 0.1, y1 - y0),
                   center=((x0 - 0.1 + x1) / 2, (y0 + y1) / 2))  # fmt: skip
    assert not near.is_valid(baxter.home)
    assert any("pedestal" in a or "pedestal" in b for a, b in near.collisions(baxter.home))


@pytest.mark.parametrize("scene", ["chair", "bench"])
def test_baxter_layouts_lie_on_the_table_within_the_arm_band(scene) -> None:
    task = _task(scene)
    cell = make_workcell(task, "baxter")
    x0, x1, y0, y1 = cell.table_extent
    for seed in range(4):
        poses = start_layout(task, cell, seed)
        assert set(poses) == {cell.base} | {c.child for c in task.constraints}
        for name, t in poses.items():
            if name == cell.base:
                continue
            assert x0 < t[0, 3] < x1 and y0 < t[1, 3] < y1
            d = np.hypot(t[0, 3] - cell.arm_xy[0], t[1, 3] - cell.arm_xy[1])
            assert d < cell.reach[1] + 0.2  # the body origin is within the part's extent


@pytest.mark.slow
@pytest.mark.parametrize("scene", ["chair", "bench"])
def test_baxter_right_arm_does_every_step_without_collisions(scene, baxter, shared_data) -> None:
    search = [str(shared_data / "3rdhand" / "meshes")]
    task = _task(scene)
    cell = make_workcell(task, "baxter", search=search)
    start = start_layout(task, cell, 0, search=search)
    ex = Executor(baxter, task, cell, start, ExecutionOptions(), search=search)
    result = ex.run_offline(seed=0)
    assert result.success, [r.status for r in result.steps]
    assert result.n_collisions == 0
    # the executor chooses the order: every slot once, each with its own part here
    assert {r.constraint: r.child for r in result.steps} == {
        s.constraint: s.child for s in task.plan
    }
    assert all(r.success and r.n_dense > 0 for r in result.steps)
