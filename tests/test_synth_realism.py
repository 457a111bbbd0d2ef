"""The synthetic world made realistic: the report's label meaning, sensor and human models."""

from __future__ import annotations

import numpy as np
import pytest

from thirdhand.demonstration import Demonstration
from thirdhand.errors import ThirdhandError
from thirdhand.synth import HumanModel, SensorModel, make_scene
from thirdhand.synth.motion import Hold, PosePath, ScrewPath, Wobble, hold_motion
from thirdhand.synth.script import Sim


@pytest.fixture(scope="module")
def chair() -> Demonstration:
    return make_scene("chair", seed=5, sensor=None)


@pytest.fixture(scope="module")
def toolbox() -> Demonstration:
    return make_scene("toolbox", seed=2, sensor=None)


def _pose(p: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray]:
    return np.array(p, dtype=np.float64), np.array([0.0, 0.0, 0.0, 1.0])


def test_moving_spans_follow_the_parent_chain() -> None:
    sim = Sim(rng=np.random.default_rng(0))
    sim.timeline.put("board", 0.0, Hold(*_pose((0.0, 0.0, 0.8))))
    start, end = _pose((0.0, 0.0, 0.8)), _pose((0.3, 0.0, 0.8))
    sim.timeline.put("board", 1.0, PosePath.between(1.0, 2.0, start, end))
    shift, turn = hold_motion(np.random.default_rng(1))
    sim.timeline.put("board", 2.0, Wobble(*end, end[0], shift, turn, 2.0))
    sim.timeline.put("board", 4.0, Hold(*end))
    sim.timeline.put("screw", 0.0, Hold(*_pose((0.01, 0.0, 0.0))), "board")
    turn_path = ScrewPath(
        5.0, 5.5, np.zeros(3), np.array([0, 0, 0, 1.0]), np.array([1.0, 0, 0]), 0.0, 1.0, 0.0, 0.0
    )
    sim.timeline.put("screw", 5.0, turn_path, "board")
    sim.timeline.put("screw", 5.5, Hold(*_pose((0.01, 0.0, 0.0))), "board")
    # The board is carried 1-2 s; the wobble (2-4 s) and holds are not moves.
    assert sim.moving_spans("board", 0.0, 10.0) == [(1.0, 2.0)]
    # The screw rides on the board (1-2 s) and is turned in it (5-5.5 s).
    assert sim.moving_spans("screw", 0.0, 10.0) == [(1.0, 2.0), (5.0, 5.5)]
    assert sim.moving_spans("screw", 1.5, 5.2) == [(1.5, 2.0), (5.0, 5.2)]
    # A zero move is no move.
    sim.timeline.put("cup", 0.0, PosePath.between(0.0, 1.0, start, start))
    assert sim.moving_spans("cup", 0.0, 2.0) == []


def _hands_objects(demo: Demonstration) -> list[tuple[str, str, float, float]]:
    out = []
    for i in demo.labels.interactions:
        ka, kb = demo.info(i.a).kind, demo.info(i.b).kind
        if ka == "finger" and kb in ("part", "tool"):
            out.append((i.a, i.b, i.start, i.end))
    return out


@pytest.mark.parametrize("scene", ["chair", "toolbox"])
def test_a_finger_interacts_only_while_it_holds_and_moves_the_object(
    scene: str, chair: Demonstration, toolbox: Demonstration
) -> None:
    demo = chair if scene == "chair" else toolbox
    holds = demo.meta["holds"]
    rows = _hands_objects(demo)
    assert len(rows) > 20
    dt = float(np.median(np.diff(demo.t)))
    moved = 0
    for finger, obj, s, e in rows:
        # Inside a hold of that finger (of the object or of a part carrying it).
        assert any(h[0] == finger and h[2] <= s + 1e-9 and e <= h[3] + 1e-9 for h in holds)
        idx = np.flatnonzero((demo.t > s + 1e-6) & (demo.t < e - 1e-6))
        if idx.size < 3:
            continue
        # The object's world pose changes at every frame of the interval: a
        # scripted move, not a hold (a Hold is constant; a wobble is no label).
        step = np.linalg.norm(np.diff(demo.pos(obj)[idx], axis=0), axis=1)
        turn = np.linalg.norm(np.diff(demo.quat(obj)[idx], axis=0), axis=1)
        assert np.all((step > 0) | (turn > 0)), (finger, obj, s)
        # ... by more than a holding hand's wobble (a few mm, 1-3 Hz) at its fastest.
        speed = np.max(step) / dt
        moved += speed > 0.05 or np.max(turn) / dt > 0.5
    assert moved >= 0.9 * sum(1 for r in rows if r[3] - r[2] > 0.3)


@pytest.mark.parametrize("scene", ["chair", "toolbox"])
def test_static_holds_are_not_interactions(
    scene: str, chair: Demonstration, toolbox: Demonstration
) -> None:
    demo = chair if scene == "chair" else toolbox
    held = sum(h[3] - h[2] for h in demo.meta["holds"])
    direct = {(f, o): [] for f, o, *_ in demo.meta["holds"]}
    for f, o, s, e in _hands_objects(demo):
        if (f, o) in direct:
            direct[(f, o)].append((s, e))
    labelled = sum(e - s for spans in direct.values() for s, e in spans)
    assert labelled < 0.8 * held  # a large part of every scene is steadying, not moving
    # A hold of 2 s or more with the object still but for the hand's wobble is unlabelled.
    found = False
    for f, o, s, e in demo.meta["holds"]:
        idx = np.flatnonzero((demo.t > s) & (demo.t < e))
        if e - s < 2.0 or np.max(np.std(demo.pos(o)[idx], axis=0)) > 0.01:
            continue
        inside = [(a, b) for a, b in direct[(f, o)] if b > s and a < e]
        if sum(b - a for a, b in inside) < 0.25 * (e - s):
            found = True
    assert found


def test_random_sensors_span_the_real_trackers() -> None:
    rng = np.random.default_rng(0)
    sensors = [SensorModel.random(rng) for _ in range(400)]
    noise = np.array([s.pos_noise for s in sensors])
    assert noise.min() >= 1e-5 and noise.max() <= 1e-3
    assert noise.min() < 2e-5 and noise.max() > 5e-4  # both ends are drawn
    rates = {s.rate for s in sensors}
    assert min(rates) == 20.0 and max(rates) == 120.0
    lost = np.array([s.dropout_rate * (1 + s.dropout_max) / 2 / s.rate for s in sensors])
    assert lost.max() <= 0.25 + 1e-12 and np.mean(lost == 0) > 0.2
    assert all(0 <= s.time_jitter < 0.5 for s in sensors)


def test_hub_dropouts_hit_every_sensor_of_a_hub_together() -> None:
    sensor = SensorModel(
        rate=100.0, finger_gap_rate=0.0, body_gap_rate=0.0, dropout_rate=15.0, dropout_max=3
    )
    demo = make_scene("toolbox", seed=1, sensor=sensor)
    fingers = [b.name for b in demo.bodies if b.kind == "finger" and b.name.startswith("rh_")]
    objects = [b.name for b in demo.bodies if b.kind in ("part", "tool")]
    for group in (fingers, objects):
        masks = np.array([demo.valid(n) for n in group])
        assert (masks == masks[0]).all()
    # Runs of 1-3 frames, Poisson starts: P(lost) = 1 - exp(-rate / fps * E[length]).
    expected = 1.0 - np.exp(-15.0 / 100.0 * 2.0)
    lost = 1.0 - demo.valid(fingers[0]).mean()
    assert abs(lost - expected) < 0.03
    assert not np.array_equal(demo.valid(fingers[0]), demo.valid(objects[0]))


def test_time_stamps_jitter_and_keep_their_order() -> None:
    sensor = SensorModel(rate=100.0, time_jitter=0.4)
    demo = make_scene("lid", seed=3, sensor=sensor)
    nominal = np.arange(demo.t.size) / 100.0
    err = demo.t - nominal
    assert np.all(np.diff(demo.t) > 0)
    assert np.all(np.abs(err) <= 0.45 / 100.0 + 1e-12)
    assert 0.15 / 100.0 < np.std(err) < 0.21 / 100.0  # 0.2 periods, a little clipped
    plain = make_scene("lid", seed=3, sensor=SensorModel(rate=100.0))
    np.testing.assert_array_equal(plain.t, nominal)


def test_bad_sensor_parameters_are_refused() -> None:
    for kwargs in (
        {"dropout_max": 0},
        {"time_jitter": 1.0},
        {"rate": float("inf")},
        {"dropout_rate": -1.0},
        {"pos_noise": float("nan")},
    ):
        with pytest.raises(ThirdhandError, match="SensorModel"):
            SensorModel(**kwargs)  # type: ignore[arg-type]


def test_a_still_person_rests_truly_still_and_the_default_person_is_unchanged() -> None:
    still = make_scene("chair", seed=4, sensor=None, human=HumanModel(idle=0.0))
    base = make_scene("chair", seed=4, sensor=None)
    same = make_scene("chair", seed=4, sensor=None, human=HumanModel())
    for name in base.body_names:
        np.testing.assert_array_equal(base.pos(name), same.pos(name))
    assert base.labels == same.labels
    # Both hands wait at the start: the still person's fingers do not move at all.
    idx = np.flatnonzero(still.t < 0.45)
    for finger in ("rh_index", "lh_index"):
        assert np.ptp(still.pos(finger)[idx], axis=0).max() == 0.0
        assert np.ptp(base.pos(finger)[idx], axis=0).max() > 3e-4
    assert still.meta["human"]["idle"] == 0.0
    with pytest.raises(ThirdhandError, match=r"HumanModel\.hold"):
        HumanModel(hold=-1.0)


def test_a_flexing_grip_moves_the_fingertips_on_the_object_and_stays_continuous() -> None:
    grip = 2e-3
    demo = make_scene("chair", seed=6, sensor=None, human=HumanModel(grip=grip, seed=1))
    rigid = make_scene("chair", seed=6, sensor=None)
    assert demo.labels == rigid.labels  # the grip changes what the sensors see, not the task
    moved = 0
    for f, o, s, e in demo.meta["holds"]:
        idx = np.flatnonzero((demo.t > s + 0.35) & (demo.t < e - 0.35))
        if idx.size < 60:
            continue
        rel = demo.pos(f)[idx] - demo.pos(o)[idx]  # world frame; the object turns slowly
        from thirdhand import se3

        local = se3.quat_rotate(se3.quat_conjugate(demo.quat(o)[idx]), rel)
        spread = np.ptp(local, axis=0).max()
        assert spread <= 2.0 * grip + 1e-9, (f, o, s)  # three sinusoids, each <= grip / 3
        moved += spread > 0.2 * grip
    assert moved > 5
    # Continuous at every grasp and release: frame to frame, a fingertip moves as
    # with a rigid grip but for the flex's own speed (three sinusoids of at most
    # 3 Hz and grip / 3 each: 2 pi 3 grip / 120 Hz = 0.3 mm), no jump.
    for b in demo.bodies:
        if b.kind == "finger":
            step = np.linalg.norm(np.diff(demo.pos(b.name), axis=0), axis=1)
            base = np.linalg.norm(np.diff(rigid.pos(b.name), axis=0), axis=1)
            assert np.max(np.abs(step - base)) < 2 * np.pi * 3.0 * grip / 120.0, b.name


def test_random_scenes_are_seeded_and_can_withhold_geometry() -> None:
    from thirdhand.synth import random_scene

    a = random_scene("lid", 3)
    b = random_scene("lid", 3, geometry=False)
    np.testing.assert_array_equal(a.t, b.t)
    np.testing.assert_array_equal(a.pos("lid"), b.pos("lid"), strict=True)
    assert a.meta["geometry"] and b.meta["geometry"] == {}
    assert a.meta["sensor"] == SensorModel.random(np.random.default_rng([3, 31337])).to_meta()
    assert a.meta["human"]["grip"] > 0
