"""The synthetic scenes: reproducibility, exact ground truth, human motion, sensor model, I/O."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from thirdhand import io, se3
from thirdhand.demonstration import Demonstration
from thirdhand.synth import SCENES, SensorModel, make_scene
from thirdhand.synth.scenes import layout_chair


@pytest.fixture(scope="module")
def chair() -> Demonstration:
    return make_scene("chair", seed=5, sensor=None)


@pytest.fixture(scope="module")
def toolbox() -> Demonstration:
    return make_scene("toolbox", seed=2, sensor=None)


def _inside(demo: Demonstration, start: float, end: float) -> np.ndarray:
    return np.flatnonzero((demo.t > start + 1e-6) & (demo.t < end - 1e-6))


def _relative(demo: Demonstration, a: str, b: str, idx: np.ndarray) -> tuple:
    return se3.relative_pose(
        demo.pos(a)[idx], demo.quat(a)[idx], demo.pos(b)[idx], demo.quat(b)[idx]
    )


def _same_rotation(q: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """|q · ref|, 1 when ``q`` is the rotation ``ref`` (either sign)."""
    return np.abs(np.sum(q * ref, axis=-1))


def test_same_seed_same_scene_and_seeds_change_the_order() -> None:
    a = make_scene("bench", seed=7)
    b = make_scene("bench", seed=7)
    for name in a.body_names:
        np.testing.assert_array_equal(a.pos(name), b.pos(name))
        np.testing.assert_array_equal(a.quat(name), b.quat(name))
        np.testing.assert_array_equal(a.valid(name), b.valid(name))
    assert a.labels == b.labels
    orders = {
        tuple(s.symbol for s in make_scene("bench", seed=k, sensor=None).labels.plan)
        for k in range(4)
    }
    assert len(orders) > 1


def test_every_scene_builds_with_labels() -> None:
    for name in SCENES:
        demo = make_scene(name, seed=1, sensor=None)
        assert demo.n_frames > 100
        assert demo.labels.constraints and demo.labels.plan
        kinds = {demo.info(i.a).kind for i in demo.labels.interactions}
        assert "finger" in kinds
        for i in demo.labels.interactions:
            assert 0.0 <= i.start < i.end <= demo.t[-1] + 1e-9


@pytest.mark.parametrize("scene", ["chair", "toolbox"])
def test_finger_pose_is_constant_in_the_object_while_interacting(
    scene: str, chair: Demonstration, toolbox: Demonstration
) -> None:
    demo = chair if scene == "chair" else toolbox
    n = 0
    for i in demo.labels.interactions:
        if demo.info(i.a).kind != "finger" and demo.info(i.b).kind != "finger":
            continue
        finger, obj = (i.a, i.b) if demo.info(i.a).kind == "finger" else (i.b, i.a)
        idx = _inside(demo, i.start, i.end)
        if idx.size < 2:
            continue
        p, q = _relative(demo, obj, finger, idx)
        assert np.max(np.abs(p - p[0])) < 1e-9, (finger, obj, i.start)
        assert np.min(_same_rotation(q, q[0])) > 1 - 1e-12, (finger, obj, i.start)
        n += 1
    assert n > 20


def test_constraint_pose_is_the_final_relative_pose(
    chair: Demonstration, toolbox: Demonstration
) -> None:
    for demo in (chair, toolbox):
        for c in demo.labels.constraints:
            p, q = _relative(demo, c.parent, c.child, np.array([demo.n_frames - 1]))
            np.testing.assert_allclose(p[0], c.pos, atol=1e-9)
            assert _same_rotation(q[0], np.array(c.quat)) > 1 - 1e-12


def test_a_leg_only_spins_about_its_axis_while_screwed_in(chair: Demonstration) -> None:
    for c in chair.labels.constraints:
        if not c.child.startswith("leg"):
            continue
        idx = np.flatnonzero(chair.t <= c.time)
        p, q = _relative(chair, c.parent, c.child, idx)
        qc_inv = se3.quat_conjugate(np.array(c.quat))
        # Screwing takes 4–6 turns of over a second each: the last 2 s are all screwing.
        inside = chair.t[idx] > c.time - 2.0
        local = se3.quat_rotate(qc_inv, p - np.array(c.pos))
        rel = se3.quat_multiply(qc_inv, q[inside])
        np.testing.assert_allclose(rel[:, 1:3], 0.0, atol=1e-9)  # rotation about x only
        np.testing.assert_allclose(local[inside][:, 1:], 0.0, atol=1e-9)  # slides along x only
        assert np.ptp(2 * np.arctan2(rel[:, 0], rel[:, 3])) > np.deg2rad(80)  # at least a turn


def test_a_reach_has_a_bell_shaped_speed_profile() -> None:
    rng = np.random.default_rng(3)
    layout = layout_chair(rng, n_people=1, head=False, bench=False)
    sim = layout.new_sim(rng)
    hand = sim.hands["rh"]
    target = (hand.pose[0] + np.array([-0.2, 0.3, 0.05]), hand.pose[1])
    t_end = sim.move_hand(hand, 1.0, 1.0, target)
    t = np.linspace(1.0, t_end, 600)
    p = sim.timeline.evaluate(t, ["rh_index"])["rh_index"][0]
    speed = np.linalg.norm(np.gradient(p, t, axis=0), axis=1)
    peak = int(np.argmax(speed))
    assert 0.4 < peak / (t.size - 1) < 0.6
    # Rising before the peak, falling after (tremor wiggles stay below 5 % of the peak).
    tol = 0.05 * speed[peak]
    assert np.all(np.diff(np.maximum.accumulate(speed[: peak + 1])) >= 0)
    assert np.all(speed[:peak] <= np.maximum.accumulate(speed[:peak]) + tol)
    assert np.all(np.diff(speed[:peak]) > -tol) and np.all(np.diff(speed[peak:]) < tol)
    assert speed[0] < 0.05 * speed[peak] and speed[-1] < 0.05 * speed[peak]


def test_held_parts_move_with_the_hand_and_idle_hands_sway(chair: Demonstration) -> None:
    grasps = [h for h in chair.meta["holds"] if h[0] == "lh_index" and h[1] == "seating"]
    long_hold = max(grasps, key=lambda h: h[3] - h[2])
    idx = _inside(chair, long_hold[2] + 1.0, long_hold[3] - 1.0)
    seat = chair.pos("seating")[idx]
    assert 5e-4 < np.max(np.std(seat, axis=0)) < 0.01  # millimetres, not centimetres
    # Both hands wait at the start of the recording (>= 0.5 s): their own small motion.
    for finger in ("rh_index", "lh_index"):
        idle = chair.pos(finger)[_inside(chair, 0.0, 0.45)]
        assert 3e-4 < np.max(np.std(idle, axis=0)) < 0.01


def test_fingers_interact_with_parts_attached_to_the_held_part(chair: Demonstration) -> None:
    legs = {c.child: c.time for c in chair.labels.constraints if c.child.startswith("leg")}
    carried = [i for i in chair.labels.interactions if i.a.startswith("lh_") and i.b in legs]
    assert carried
    for i in carried:
        # The leg moves rigidly with the seat the hand holds (established, or
        # resting in its thread), and the hand is moving the seat.
        idx = _inside(chair, i.start, i.end)
        if idx.size >= 2:
            p, _ = _relative(chair, "seating", i.b, idx)
            assert np.max(np.abs(p - p[0])) < 1e-9, (i.a, i.b, i.start)
        assert any(
            h[0] == i.a and h[1] == "seating" and h[2] <= i.start + 1e-9 and i.end <= h[3] + 1e-9
            for h in chair.meta["holds"]
        )
        assert any(
            j.a == i.a and j.b == "seating" and j.start <= i.start + 1e-9 and i.end <= j.end + 1e-9
            for j in chair.labels.interactions
        )


def test_sensor_model_statistics() -> None:
    sensor = SensorModel()
    rng = np.random.default_rng(0)
    t = np.arange(20_000) / sensor.rate
    pos = np.tile([0.1, 0.2, 0.8], (t.size, 1))
    quat = np.tile(
        np.array([0.1, 0.2, 0.3, 0.9]) / np.linalg.norm([0.1, 0.2, 0.3, 0.9]), (t.size, 1)
    )
    p, q, valid = sensor.observe(t, pos, quat, "part", rng)
    std = np.nanstd(p - pos, axis=0)
    np.testing.assert_allclose(std, sensor.pos_noise, rtol=0.1)
    assert 0 < np.sum(~valid) < 0.2 * t.size  # gaps, not too many
    assert np.all(np.isnan(p[~valid])) and np.all(np.isfinite(p[valid]))
    dots = np.sum(q[valid][1:] * q[valid][:-1], axis=1)
    assert np.any(dots < 0)  # sign flips
    cont = se3.quat_make_continuous(q, valid)
    dots = np.sum(cont[valid][1:] * cont[valid][:-1], axis=1)
    assert np.all(dots > 0)
    angle = se3.quat_angle(cont[valid], quat[valid])
    assert np.sqrt(np.mean(angle**2)) < 3 * np.sqrt(3) * sensor.rot_noise


def test_noisy_scene_is_the_true_scene_through_the_sensor() -> None:
    noisy = make_scene("lid", seed=4)
    true = make_scene("lid", seed=4, sensor=None)
    np.testing.assert_array_equal(noisy.t, true.t)
    for name in ("lid", "rh_index"):
        v = noisy.valid(name)
        assert not v.all()
        err = noisy.pos(name)[v] - true.pos(name)[v]
        assert 0.7e-3 < np.std(err) < 1.3e-3
    assert noisy.labels == true.labels


@pytest.mark.parametrize("scene", SCENES)
def test_scene_round_trips_through_parquet(scene: str, tmp_path: Path) -> None:
    demo = make_scene(scene, seed=0)
    path = tmp_path / f"{scene}.parquet"
    io.save(demo, path)
    back = io.load(path)
    np.testing.assert_array_equal(back.t, demo.t)
    assert back.body_names == demo.body_names
    for name in demo.body_names:
        assert back.info(name) == demo.info(name)
        np.testing.assert_array_equal(back.valid(name), demo.valid(name))
        np.testing.assert_allclose(back.pos(name), demo.pos(name), atol=1e-12, equal_nan=True)
        np.testing.assert_allclose(back.quat(name), demo.quat(name), atol=1e-12, equal_nan=True)
    assert back.labels == demo.labels


def test_parts_interact_exactly_while_a_chain_of_resting_joints_connects_them(
    chair: Demonstration, toolbox: Demonstration
) -> None:
    for demo in (chair, toolbox):
        n = 0
        for i in demo.labels.interactions:
            if demo.info(i.a).kind != "part" or demo.info(i.b).kind != "part":
                continue
            idx = _inside(demo, i.start, i.end)
            if idx.size < 2:
                continue
            p, q = _relative(demo, i.a, i.b, idx)
            assert np.max(np.abs(p - p[0])) < 1e-9, (i.a, i.b, i.start)
            assert np.min(_same_rotation(q, q[0])) > 1 - 1e-12, (i.a, i.b, i.start)
            n += 1
        assert n > 10
    # A leg being screwed in rests in its thread between strokes: one interval per
    # pause before it is established, none while it turns.
    for c in chair.labels.constraints:
        if not c.child.startswith("leg"):
            continue
        before = [
            i
            for i in chair.labels.interactions
            if {i.a, i.b} == {"seating", c.child} and i.end < c.time - 1e-6
        ]
        assert len(before) >= 3, c.child
        turning = [j for j in range(1, len(before)) if before[j].start - before[j - 1].end > 0.3]
        assert len(turning) == len(before) - 1  # a stroke of at least 0.3 s between pauses
