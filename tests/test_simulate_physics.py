"""Physics simulation: the model's kinematics, a peg into a hole, a weak grasp."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("mujoco")
pytest.importorskip("pinocchio")  # before coacd, whose libraries break its URDF parser
pytest.importorskip("coacd")

import mujoco

from tests.sim_scenes import peg_cell, peg_constraint, peg_plan
from thirdhand.execute import Robot
from thirdhand.simulate.model import TOOL, build_spec
from thirdhand.simulate.runner import Simulation
from thirdhand.simulate.schedule import schedule
from thirdhand.simulate.settings import SimulateSettings


@pytest.fixture(scope="module")
def plan():
    return peg_plan()


def _run(plan, tmp_path, *, hull=False, density=680.0, **settings):
    s = SimulateSettings(cache=str(tmp_path / "cache"), **settings)
    cell, corners = peg_cell(hull=hull, density=density, cache=tmp_path / "cache")
    model = build_spec(cell, s).compile()
    return Simulation(model, plan, {"c1": peg_constraint()}, corners, s).run()


def test_model_forward_kinematics_equal_the_planners() -> None:
    base = np.eye(4)
    base[:3, 3] = [0.3, -0.2, 0.75]
    robot = Robot.load("panda", base_pose=(base[:3, 3], [0.0, 0.0, 0.0, 1.0]))
    cell, _ = peg_cell(hull=True)
    cell = type(cell)("panda", base, 0.75, cell.table_extent, cell.parts, cell.joints)
    model = build_spec(cell, SimulateSettings()).compile()
    data = mujoco.MjData(model)
    tool = model.body(TOOL).id
    rng = np.random.default_rng(3)
    for q in robot.random_q(rng, 20):
        data.qpos[:7] = q
        mujoco.mj_kinematics(model, data)
        pos, quat = robot.fk(q)
        np.testing.assert_allclose(data.xpos[tool], pos, atol=1e-6)
        rot = data.xmat[tool].reshape(3, 3)
        from thirdhand.se3 import matrix_from_quat

        np.testing.assert_allclose(rot, matrix_from_quat(quat), atol=1e-6)


def test_arm_speed_limits_are_the_planners() -> None:
    from thirdhand.simulate.model import ARM_SPEED

    np.testing.assert_array_equal(Robot.load("panda").velocity_limits, ARM_SPEED)


def test_schedule_closes_fastens_opens_and_rests(plan) -> None:
    s = SimulateSettings()
    kinds = [(p.kind, p.segment) for p in schedule(plan.spans, s)]
    assert kinds == [
        ("move", "approach"), ("move", "grasp"), ("close", "close"), ("move", "lift"),
        ("move", "transport"), ("move", "insert"), ("fasten", "fasten"), ("open", "open"),
        ("move", "retreat"), ("rest", "rest"),
    ]  # fmt: skip


@pytest.mark.slow
def test_peg_goes_into_the_hole_with_clearance(plan, tmp_path) -> None:
    r = _run(plan, tmp_path)
    (step,) = r.steps
    assert step.status == "done", step
    assert step.position_error_mm < 2.0 and step.angle_error_deg < 1.0
    assert step.slip_mm < 1.0
    assert r.rest_displacement_mm < 0.5
    assert 0.0 < step.joint_speed < 1.0  # the peg's plan is timed within the limits


@pytest.mark.slow
def test_peg_jams_on_the_holes_convex_hull(plan, tmp_path) -> None:
    r = _run(plan, tmp_path, hull=True)
    (step,) = r.steps
    assert step.status == "jammed", step
    # it stands on the plate (30 mm thick) instead of going through it
    assert 20.0 < step.position_error_mm < 40.0
    assert step.blocked and step.peak_force_n > 10.0


@pytest.mark.slow
def test_weak_grasp_loses_the_part(plan, tmp_path) -> None:
    r = _run(plan, tmp_path, density=8000.0, gripper_force=2.0)  # a 1.3 kg steel peg, 2 N
    (step,) = r.steps
    assert step.status in ("slipped", "dropped"), step
    assert step.slip_mm > 5.0


@pytest.mark.slow
def test_weld_grasp_holds_the_heavy_peg(plan, tmp_path) -> None:
    r = _run(plan, tmp_path, density=8000.0, gripper_force=2.0, grasp="weld")
    (step,) = r.steps
    assert step.status == "done", step
    assert step.slip_mm < 1.0
