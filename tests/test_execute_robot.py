"""Robot models, kinematics and the collision scene of thirdhand.execute."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from thirdhand import se3
from thirdhand.execute import CollisionScene, Robot, RobotError, SceneError, as_pose
from thirdhand.execute.kinematics import rotation_error
from thirdhand.execute.meshes import load_mesh, local_aabb
from thirdhand.io.stl import read_stl
from thirdhand.taskfile import Pose

BASE = (
    np.array([0.1, -0.2, 0.75]),
    se3.quat_multiply([0, 0, np.sin(0.2), np.cos(0.2)], [1, 0, 0, 0]),
)
TOP_DOWN = np.array([1.0, 0.0, 0.0, 0.0])  # tool z pointing down


@pytest.fixture(scope="module")
def panda() -> Robot:
    return Robot.load("panda", base_pose=([0.0, 0.0, 0.75], [0, 0, 0, 1]))


@pytest.fixture(scope="module")
def baxter() -> Robot:
    return Robot.load("baxter", base_pose=([-0.2, 0.0, 0.95], [0, 0, 0, 1]))


def _scene(robot: Robot) -> CollisionScene:
    scene = CollisionScene(robot)
    if robot.name == "baxter":  # in front of its pedestal (standing on the floor)
        scene.add_table(height=0.75, size=(1.0, 1.6), center=(0.5, 0.0))
    else:  # Panda mounted on the table
        scene.add_table(height=0.75)
    return scene


@pytest.mark.parametrize("name", ["panda", "baxter"])
def test_fk_matches_pinocchio_frame_placement(name: str) -> None:
    robot = Robot.load(name, base_pose=(BASE[0], BASE[1]))
    qs = robot.random_q(np.random.default_rng(1), 25)
    pos, quat = robot.fk_batch(qs)
    fid = robot.model.getFrameId(robot.tool_frame)
    for q, p, qu in zip(qs, pos, quat, strict=True):
        pin.framesForwardKinematics(robot.model, robot.data, q)
        ref = robot.data.oMf[fid]
        np.testing.assert_allclose(p, ref.translation, atol=1e-12)
        np.testing.assert_allclose(se3.matrix_from_quat(qu), ref.rotation, atol=1e-12)
        p1, _ = robot.fk(q)
        np.testing.assert_allclose(p1, p, atol=1e-15)


def test_base_pose_is_composed_in_front_of_the_arm() -> None:
    plain = Robot.load("panda")
    based = Robot.load("panda", base_pose=BASE)
    q = plain.random_q(np.random.default_rng(2))
    expect = se3.pose_compose(*BASE, *plain.fk(q))
    got = based.fk(q)
    np.testing.assert_allclose(got[0], expect[0], atol=1e-12)
    assert se3.quat_angle(got[1], expect[1]) < 1e-9


def test_jacobian_matches_finite_differences(panda: Robot) -> None:
    q = panda.random_q(np.random.default_rng(3))
    chain = panda.chain
    tj = chain.joint_transforms(q[None])
    tool = panda.tool_transforms(q[None])
    jac = chain.jacobian(tj, tool[:, :3, 3], chain.ancestors(panda.dof - 1))[0]
    eps = 1e-6
    for j in range(panda.dof):
        dq = np.zeros(panda.dof)
        dq[j] = eps
        t1 = panda.tool_transforms((q + dq)[None])[0]
        t0 = panda.tool_transforms((q - dq)[None])[0]
        np.testing.assert_allclose((t1[:3, 3] - t0[:3, 3]) / (2 * eps), jac[:3, j], atol=1e-6)
        w = rotation_error(t1[None, :3, :3], t0[None, :3, :3])[0] / (2 * eps)
        np.testing.assert_allclose(w, jac[3:, j], atol=1e-6)


@pytest.mark.parametrize("name", ["panda", "baxter"])
def test_ik_recovers_the_pose_of_random_configurations(name: str) -> None:
    robot = Robot.load(name)
    qs = robot.random_q(np.random.default_rng(4), 30)
    ok = 0
    for k, q in enumerate(qs):
        target = robot.fk(q)
        sol = robot.ik(target, seed=k)
        if sol is None:
            continue
        ok += 1
        assert robot.within_limits(sol)
        p, qu = robot.fk(sol)
        assert np.linalg.norm(p - target[0]) < 1e-4
        assert se3.quat_angle(qu, target[1]) < 1e-3
    assert ok >= 28


def test_ik_prefers_the_seed_and_rejects_unreachable_targets(panda: Robot) -> None:
    q = panda.home + 0.1
    sol = panda.ik(panda.fk(q), q_seed=q)
    assert sol is not None and np.linalg.norm(sol - q) < 1e-2
    assert panda.ik(([3.0, 0.0, 0.8], TOP_DOWN), n_restarts=4) is None
    assert panda.ik(panda.fk(q), q_seed=q, accept=lambda _: False) is None


def test_ik_batch_and_task_file_pose(panda: Robot) -> None:
    qs = panda.random_q(np.random.default_rng(5), 6)
    targets = panda.tool_transforms(qs)
    q, ok = panda.ik_batch(targets, qs + 0.05)
    assert ok.all()
    np.testing.assert_allclose(panda.tool_transforms(q)[:, :3, 3], targets[:, :3, 3], atol=1e-4)
    p, qu = panda.fk(qs[0])
    pose = Pose(pos=tuple(p.tolist()), quat=tuple(qu.tolist()))
    np.testing.assert_allclose(as_pose(pose)[0], p)
    assert panda.ik(pose, q_seed=qs[0]) is not None


def test_bad_input_raises_package_errors(panda: Robot) -> None:
    with pytest.raises(RobotError, match="unknown robot"):
        Robot.load("ur5")
    with pytest.raises(RobotError, match="shape"):
        panda.fk(np.zeros(3))
    scene = _scene(panda)
    with pytest.raises(SceneError, match="unknown object"):
        scene.set_object_pose("nope", ([0, 0, 0], [0, 0, 0, 1]))
    with pytest.raises(SceneError, match="mesh_path or a box size"):
        scene.add_object("part", ([0, 0, 0], [0, 0, 0, 1]))
    with pytest.raises(SceneError, match="already used"):
        scene.add_box("table", ([0, 0, 0], [0, 0, 0, 1]), (1, 1, 1))


@pytest.mark.parametrize("name", ["panda", "baxter"])
def test_home_is_valid_and_srdf_filters_pairs(name: str, panda: Robot, baxter: Robot) -> None:
    robot = panda if name == "panda" else baxter
    n = robot.geometry.ngeoms
    assert 0 < len(robot.geometry.collisionPairs) < n * (n - 1) // 2
    scene = _scene(robot)
    assert scene.is_valid(robot.home), scene.collisions(robot.home)


def test_arm_through_the_table_is_invalid(panda: Robot) -> None:
    scene = _scene(panda)
    q = panda.home.copy()
    q[1] = 1.7  # shoulder pitched forward, elbow folded down into the table top
    q[3] = -0.3
    pos, _ = panda.fk(q)
    assert pos[2] < 0.7
    assert not scene.is_valid(q)
    assert any("table" in pair for pair in scene.collisions(q))
    assert not scene.valid_mask(np.stack([panda.home, q])).all()
    out_of_limits = panda.home.copy()
    out_of_limits[3] = 0.5
    assert not scene.is_valid(out_of_limits)


def test_scene_agrees_with_pinocchio_collisions(panda: Robot, baxter: Robot) -> None:
    for robot in (panda, baxter):
        scene = _scene(robot)
        scene.add_box("crate", ([0.45, -0.25, 0.9], [0, 0, 0, 1]), (0.15, 0.2, 0.3))
        scene.add_object("block", ([0.4, 0.3, 0.76], [0, 0, 0, 1]), size=(0.1, 0.3, 0.02))
        qs = robot.random_q(np.random.default_rng(6), 150)
        ours = scene.valid_mask(qs)
        gm, gd = scene.to_pinocchio()
        peer = np.array(
            [not pin.computeCollisions(robot.model, robot.data, gm, gd, q, True) for q in qs]
        )
        np.testing.assert_array_equal(ours, peer)
        assert 0.1 < ours.mean() < 0.95  # both outcomes exercised


def test_attached_box_moves_with_the_tool(panda: Robot) -> None:
    scene = _scene(panda)
    q0 = panda.home
    tool = panda.fk(q0)
    offset = (np.array([0.0, 0.0, 0.06]), se3.quat_identity())
    scene.add_object("part", se3.pose_compose(*tool, *offset), size=(0.04, 0.04, 0.08))
    scene.attach("part", q0)
    assert scene.attached == "part" and scene.is_valid(q0)  # touching the fingers is allowed
    q1 = q0 + np.array([0.4, 0.2, -0.3, 0.1, 0.2, -0.2, 0.5])
    expect = se3.pose_compose(*panda.fk(q1), *offset)
    got = scene.object_pose("part", q1)
    np.testing.assert_allclose(got[0], expect[0], atol=1e-12)
    assert se3.quat_angle(got[1], expect[1]) < 1e-9
    # An obstacle only the held part reaches makes the configuration invalid.
    beyond = expect[0] + se3.quat_rotate(expect[1], [0.0, 0.0, 0.045])
    scene.add_box("post", (beyond, expect[1]), (0.03, 0.03, 0.03))
    assert not scene.is_valid(q1)
    assert ("part", "post") in scene.collisions(q1)
    scene.detach("part", q1)
    np.testing.assert_allclose(scene.object_pose("part")[0], expect[0], atol=1e-12)
    assert scene.attached is None
    assert scene.is_valid(q0)  # the part stayed behind at q1's place
    scene.allow("part", "post")
    scene.set_object_pose("part", (np.array([1.5, 1.5, 0.8]), se3.quat_identity()))
    with pytest.raises(SceneError, match="cannot release"):
        scene.detach("part", q0)


def test_gripper_group_allows_finger_contacts(panda: Robot) -> None:
    scene = _scene(panda)
    pos, quat = panda.fk(panda.home)
    scene.add_box("knob", (pos, quat), (0.02, 0.14, 0.02))  # across both fingers
    assert not scene.is_valid(panda.home)
    scene.allow("gripper", "knob")
    assert scene.is_valid(panda.home)
    scene.disallow("gripper", "knob")
    scene.remove_object("knob")
    assert scene.is_valid(panda.home)


def test_interpolation_bounds_point_motion(panda: Robot) -> None:
    scene = _scene(panda)
    rng = np.random.default_rng(7)
    qs = panda.random_q(rng, 4)
    dense = scene.interpolate(qs, max_step_m=0.01, max_step_rad=0.02)
    assert np.all(np.abs(np.diff(dense, axis=0)) <= 0.02 + 1e-12)
    for k in range(len(qs)):
        assert np.any(np.all(dense == qs[k], axis=1))
    # Brute force: corners of every link's box never move more than the bound.
    bodies = scene.checks.bodies.bodies
    centers = np.array([b.center for b in bodies])
    halves = np.array([b.half for b in bodies])
    signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
    corners = centers[:, None] + signs[None] * halves[:, None]  # (B, 8, 3)
    t = scene.checks.transforms(dense)
    pts = np.einsum("nbij,bkj->nbki", t[..., :3, :3], corners) + t[:, :, None, :3, 3]
    step = np.linalg.norm(np.diff(pts, axis=0), axis=-1).max()
    assert step <= 0.01 + 1e-9


def test_part_meshes_load_in_metres(shared_data) -> None:  # type: ignore[no-untyped-def]
    path = shared_data / "3rdhand" / "meshes" / "chair_leg.stl"
    tri = read_stl(path) * 1e-3
    mesh = load_mesh(path)
    c, h = local_aabb(mesh)
    np.testing.assert_allclose(c - h, tri.reshape(-1, 3).min(0), atol=1e-9)
    np.testing.assert_allclose(c + h, tri.reshape(-1, 3).max(0), atol=1e-9)
    assert load_mesh(path) is mesh  # cached
    panda = Robot.load("panda", base_pose=([0.0, 0.0, 0.75], [0, 0, 0, 1]))
    scene = _scene(panda)
    scene.add_object("leg", ([0.5, 0.0, 0.75], [0, 0, 0, 1]), mesh_path=path)
    assert scene.is_valid(panda.home)  # resting on the table is contact, not collision
    q = panda.ik(([0.5, 0.0, 0.9], TOP_DOWN), seed=0)
    assert q is not None and not scene.is_valid(q)  # the hand inside the leg
    assert ("panda_hand", "leg") in scene.collisions(q) or not scene.is_valid(q)
