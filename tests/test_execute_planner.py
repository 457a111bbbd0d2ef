"""Motion planning, shortcutting and time parametrisation of thirdhand.execute."""

from __future__ import annotations

import numpy as np
import pytest

from thirdhand import se3
from thirdhand.errors import ThirdhandError
from thirdhand.execute import (
    CollisionScene,
    PlanningError,
    Robot,
    plan_motion,
    shortcut,
    time_parametrize,
)
from thirdhand.execute.planner import joint_length, tool_length

TOP_DOWN = np.array([1.0, 0.0, 0.0, 0.0])


@pytest.fixture(scope="module")
def panda() -> Robot:
    return Robot.load("panda", base_pose=([0.0, 0.0, 0.75], [0, 0, 0, 1]))


@pytest.fixture(scope="module")
def wall_query(panda: Robot) -> tuple[CollisionScene, np.ndarray, np.ndarray]:
    """A pick/place-like query: a wall on the table between the start and the goal."""
    scene = CollisionScene(panda)
    scene.add_table(height=0.75)
    scene.add_box("wall", ([0.5, 0.0, 0.95], [0, 0, 0, 1]), (0.3, 0.04, 0.4))
    qa = panda.ik(([0.5, -0.25, 0.9], TOP_DOWN), seed=0, accept=scene.is_valid)
    qb = panda.ik(([0.5, 0.25, 0.9], TOP_DOWN), seed=0, accept=scene.is_valid)
    assert qa is not None and qb is not None
    return scene, qa, qb


def test_plans_around_a_wall_and_path_is_collision_free(
    panda: Robot, wall_query: tuple[CollisionScene, np.ndarray, np.ndarray]
) -> None:
    scene, qa, qb = wall_query
    assert not scene.check_path(np.stack([qa, qb]))  # the straight motion is blocked
    res = plan_motion(panda, scene, qa, qb, seed=3, time_limit=20.0)
    assert res.success and res.status == "planned", res.status
    assert res.path is not None
    np.testing.assert_array_equal(res.path[0], qa)
    np.testing.assert_array_equal(res.path[-1], qb)
    # Dense re-check at twice the planner's density.
    assert scene.check_path(res.path, max_step_m=0.002, max_step_rad=0.004, clearance=False)
    assert all(panda.within_limits(q) for q in res.path)
    assert res.joint_length_rad == pytest.approx(joint_length(res.path))
    assert res.tool_length_m == pytest.approx(tool_length(panda, res.path))
    # The tool goes around the 0.3 m wide wall: longer than the 0.5 m straight line.
    assert res.tool_length_m > 0.5
    assert res.n_checks > 0 and res.goal_index == 0


def test_same_seed_gives_the_same_path(
    panda: Robot, wall_query: tuple[CollisionScene, np.ndarray, np.ndarray]
) -> None:
    scene, qa, qb = wall_query
    first = plan_motion(panda, scene, qa, qb, seed=11, time_limit=20.0)
    again = plan_motion(panda, scene, qa, qb, seed=11, time_limit=20.0)
    assert first.path is not None and again.path is not None
    np.testing.assert_array_equal(first.path, again.path)
    assert first.n_checks == again.n_checks


def test_direct_motion_and_goal_sets(panda: Robot) -> None:
    scene = CollisionScene(panda)
    scene.add_table(height=0.75)
    q0 = panda.home
    q1 = panda.home + 0.2
    res = plan_motion(panda, scene, q0, q1)
    assert res.status == "direct" and len(res.path) == 2  # type: ignore[arg-type]
    bad = panda.home.copy()
    bad[1], bad[3] = 1.7, -0.3  # elbow in the table
    res = plan_motion(panda, scene, q0, np.stack([bad, q1]))
    assert res.success and res.goal_index == 1
    res = plan_motion(panda, scene, q0, bad)
    assert not res.success and res.path is None and res.status.startswith("goal invalid")
    assert "table" in res.status
    res = plan_motion(panda, scene, bad, q1)
    assert not res.success and res.status.startswith("start invalid")


def test_enclosed_goal_fails_within_the_time_limit(panda: Robot) -> None:
    """A pillar beside the shoulder blocks joint 1 near 0; its limits forbid going round."""
    scene = CollisionScene(panda)
    scene.add_table(height=0.75)
    scene.add_box("pillar", ([0.0, 0.2, 1.08], [0, 0, 0, 1]), (0.06, 0.12, 0.2))
    rng = np.random.default_rng(0)
    crossing = panda.random_q(rng, 300)
    crossing[:, 0] = rng.uniform(-0.2, 0.2, 300)
    assert not scene.valid_mask(crossing).any()  # brute force: the band is blocked

    def sample(lo: float, hi: float) -> np.ndarray:
        while True:
            q = panda.random_q(rng)
            q[0] = rng.uniform(lo, hi)
            if scene.is_valid(q):
                return q

    qa, qb = sample(1.3, 1.8), sample(-1.8, -1.3)
    res = plan_motion(panda, scene, qa, qb, time_limit=1.0, seed=0)
    assert not res.success and res.status == "timeout" and res.path is None
    assert res.planning_time_s < 10.0  # bounded: a 1 s search, not a hang


def test_plans_with_a_grasped_part(panda: Robot) -> None:
    scene = CollisionScene(panda)
    scene.add_table(height=0.75)
    qa = panda.ik(([0.45, -0.3, 1.0], TOP_DOWN), seed=0)
    qb = panda.ik(([0.45, 0.3, 1.0], TOP_DOWN), seed=0)
    assert qa is not None and qb is not None
    grasp = (np.array([0.0, 0.0, 0.1]), se3.quat_identity())
    scene.add_object("rod", se3.pose_compose(*panda.fk(qa), *grasp), size=(0.03, 0.03, 0.2))
    scene.attach("rod", qa)
    # A bar on the table only the hanging rod would hit on the straight motion.
    scene.add_box("bar", ([0.45, 0.0, 0.8], [0, 0, 0, 1]), (0.2, 0.04, 0.1))
    assert not scene.check_path(np.stack([qa, qb]))
    res = plan_motion(panda, scene, qa, qb, seed=0, time_limit=20.0)
    assert res.success and res.path is not None
    assert scene.check_path(res.path, max_step_m=0.002, clearance=False)


def test_shortcut_never_lengthens_and_stays_valid(
    panda: Robot, wall_query: tuple[CollisionScene, np.ndarray, np.ndarray]
) -> None:
    scene, qa, qb = wall_query
    raw = plan_motion(panda, scene, qa, qb, seed=5, simplify=False, time_limit=20.0)
    assert raw.path is not None
    short = shortcut(scene, raw.path, np.random.default_rng(0), iterations=50)
    assert joint_length(short) <= joint_length(raw.path) + 1e-9
    assert scene.check_path(short)
    np.testing.assert_array_equal(short[[0, -1]], raw.path[[0, -1]])


def test_bad_planning_requests(panda: Robot) -> None:
    scene = CollisionScene(panda)
    with pytest.raises(PlanningError, match="unknown planner"):
        plan_motion(panda, scene, panda.home, panda.home, planner="prm?")
    with pytest.raises(PlanningError, match="time_limit"):
        plan_motion(panda, scene, panda.home, panda.home, time_limit=0.0)
    with pytest.raises(PlanningError, match="goal"):
        plan_motion(panda, scene, panda.home, np.zeros(3))


def test_trapezoid_reference_durations() -> None:
    # Full trapezoid: D / v + v / a; triangle: 2 sqrt(D / a).
    traj = time_parametrize([[0.0], [2.0]], [1.0], [2.0], rate_hz=1000.0)
    assert traj.duration_s == pytest.approx(2.0 / 1.0 + 1.0 / 2.0)
    traj = time_parametrize([[0.0], [0.1]], [1.0], [2.0], rate_hz=1000.0)
    assert traj.duration_s == pytest.approx(2.0 * np.sqrt(0.1 / 2.0))
    assert np.max(traj.qd) == pytest.approx(np.sqrt(0.1 * 2.0), rel=1e-2)


def test_time_parametrisation_respects_limits_and_waypoints(panda: Robot) -> None:
    rng = np.random.default_rng(8)
    path = panda.random_q(rng, 5)
    path = np.vstack([path[:2], path[1:2], path[2:]])  # a repeated waypoint
    v, a = panda.velocity_limits, panda.acceleration_limits
    traj = time_parametrize(path, v, a, rate_hz=500.0, scale=0.8)
    assert np.all(np.diff(traj.t) > 0)
    np.testing.assert_array_equal(traj.q[0], path[0])
    np.testing.assert_allclose(traj.q[-1], path[-1], atol=1e-12)
    assert np.all(np.abs(traj.qd) <= 0.8 * v + 1e-9)
    acc = np.diff(traj.qd, axis=0) / np.diff(traj.t)[:, None]
    assert np.all(np.abs(acc) <= 0.8 * a * 1.001 + 1e-6)
    np.testing.assert_allclose(traj.qd[[0, -1]], 0.0, atol=1e-12)
    # Each waypoint is passed at its time, and the motion stays on the straight segments.
    for k, tk in enumerate(traj.waypoint_times):
        i = int(np.argmin(np.abs(traj.t - tk)))
        if abs(traj.t[i] - tk) < 1e-12:
            np.testing.assert_allclose(traj.q[i], path[k], atol=1e-9)
    seg = np.clip(np.searchsorted(traj.waypoint_times, traj.t, side="right") - 1, 0, len(path) - 2)
    d = path[seg + 1] - path[seg]
    r = traj.q - path[seg]
    cross = r - (np.sum(r * d, axis=1) / np.maximum(np.sum(d * d, axis=1), 1e-300))[:, None] * d
    assert np.max(np.abs(cross)) < 1e-9
    with pytest.raises(ThirdhandError):
        time_parametrize(path, v, -a)


def test_clearance_makes_coarse_checks_sound(panda: Robot) -> None:
    """A 2 mm sheet crossed by the hand: the coarse check with clearance still sees it."""
    scene = CollisionScene(panda)
    scene.add_table(height=0.75)
    qa = panda.ik(([0.5, -0.2, 1.0], TOP_DOWN), seed=0)
    assert qa is not None
    qb = panda.ik(([0.5, 0.2, 1.0], TOP_DOWN), q_seed=qa, seed=0)
    assert qb is not None
    scene.add_box("sheet", ([0.5, 0.0, 1.0], [0, 0, 0, 1]), (0.1, 0.002, 0.1))
    assert scene.is_valid(qa) and scene.is_valid(qb)
    path = np.stack([qa, qb])
    assert not scene.check_path(path, max_step_m=0.001, clearance=False)  # ground truth
    for step in (0.01, 0.05, 0.2):
        assert not scene.check_path(path, max_step_m=step, max_step_rad=1.0)
