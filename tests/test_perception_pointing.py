"""Pointing gestures and attention on synthetic scenes with known targets; task-file events."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from thirdhand.demonstration import BodyInfo, Demonstration
from thirdhand.errors import TaskFileError, ThirdhandError
from thirdhand.perception import (
    add_perception_events,
    attention_intervals,
    detect_pointing,
    focus_object,
)
from thirdhand.perception.attention import attended_objects, ray_angles
from thirdhand.perception.pointing import PointingEvent, pointing_posture
from thirdhand.synth import make_scene
from thirdhand.taskfile import TaskFile, load_task, save_task


def _score(demo: Demonstration) -> tuple[int, int, int, int]:
    """(gestures, detected once with the right target, wrong target, spurious events)."""
    truth = demo.meta.get("pointing", [])
    events = detect_pointing(demo)
    right = wrong = spurious = 0
    hits = {i: 0 for i in range(len(truth))}
    for e in events:
        match = [i for i, g in enumerate(truth)
                 if g["hand"] == e.hand and g["t0"] < e.t1 and e.t0 < g["t1"]]  # fmt: skip
        if not match:
            spurious += 1
            continue
        hits[match[0]] += 1
        if e.object == truth[match[0]]["object"]:
            right += 1
        else:
            wrong += 1
    once = sum(1 for i, n in hits.items() if n == 1)
    return len(truth), min(right, once), wrong, spurious


@pytest.mark.parametrize("scene", ["chair", "bench", "toolbox"])
def test_pointing_targets_on_synthetic_scenes(scene: str) -> None:
    total = right = 0
    for seed in range(3):
        for head in (False, True):
            n, ok, _wrong, spurious = _score(make_scene(scene, seed=seed, head=head, pointing=4))
            assert spurious == 0
            total += n
            right += ok
    assert total == 24
    assert right / total >= 0.95


def test_pointing_noise_free_is_exact() -> None:
    demo = make_scene("chair", seed=5, sensor=None, head=True, pointing=3)
    events = detect_pointing(demo)
    truth = demo.meta["pointing"]
    assert [(e.hand, e.object) for e in events] == [(g["hand"], g["object"]) for g in truth]
    for e, g in zip(events, truth, strict=True):
        # the posture starts during the approach and ends during the return
        assert e.t0 <= g["t0"] + 1e-9 and e.t1 >= g["t1"] - 1e-9
        assert e.ray == "head" and e.angle_deg < 3.0  # the held hand sways by ±2.5°
    index_ray = detect_pointing(demo, ray="index")
    assert [e.object for e in index_ray] == [g["object"] for g in truth]


@pytest.mark.parametrize(
    ("scene", "options"),
    [
        ("chair", {}),
        ("chair", {"head": True}),
        ("bench", {}),
        ("toolbox", {}),
        ("drawer", {}),
        ("lid", {}),
    ],
)
def test_no_events_during_reaching_and_grasping(scene: str, options: dict[str, bool]) -> None:
    for seed in (0, 1):
        assert detect_pointing(make_scene(scene, seed=seed, **options)) == []


def test_no_events_with_two_people() -> None:
    assert detect_pointing(make_scene("chair", seed=2, n_people=2)) == []


def test_default_scene_unchanged_by_the_pointing_option() -> None:
    plain = make_scene("chair", seed=3, sensor=None)
    zero = make_scene("chair", seed=3, sensor=None, pointing=0)
    assert plain.equals(zero)
    pointed = make_scene("chair", seed=3, sensor=None, pointing=2)
    # the assembly itself is the same, only later
    a = plain.labels.constraints
    b = pointed.labels.constraints
    delay = b[0].time - a[0].time
    assert delay > 3.0 and pointed.meta["pointing"][-1]["t1"] < delay
    assert [(c.parent, c.child) for c in a] == [(c.parent, c.child) for c in b]
    np.testing.assert_allclose([c.time + delay for c in a], [c.time for c in b], atol=1e-9)
    with pytest.raises(ThirdhandError, match="pointing needs one cycle"):
        make_scene("chair", pointing=2, cycles=2)


def test_posture_thresholds() -> None:
    thumb = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [np.nan] * 3])
    middle = np.array([[0.02, 0.0, 0.0], [0.06, 0.0, 0.0], [0.02, 0.0, 0.0]])
    index = np.array([[0.0, 0.08, 0.0], [0.06, 0.02, 0.0], [0.0, 0.08, 0.0]])
    assert pointing_posture(thumb, index, middle).tolist() == [True, False, False]


def test_missing_fingers_is_an_error() -> None:
    demo = make_scene("chair", seed=0).select(["seating", "leg1"])
    with pytest.raises(ThirdhandError, match="no hand with thumb, index and middle"):
        detect_pointing(demo)


def _turning_head() -> tuple[Demonstration, list[tuple[str, float, float]]]:
    """A head at the origin turning about z past three objects at known bearings."""
    t = np.arange(0, 10.0, 0.01)
    yaw = np.deg2rad(-60.0 + 12.0 * t)  # -60° .. +60°
    quat = np.stack([np.zeros_like(t), np.zeros_like(t), np.sin(yaw / 2), np.cos(yaw / 2)], 1)
    bodies = [BodyInfo("head", kind="head"), BodyInfo("a"), BodyInfo("b"), BodyInfo("c")]
    pos = {"head": np.zeros((t.size, 3))}
    quats = {"head": quat}
    for name, bearing in (("a", -40.0), ("b", 0.0), ("c", 40.0)):
        r = np.deg2rad(bearing)
        pos[name] = np.tile([np.cos(r), np.sin(r), 0.0], (t.size, 1))
        quats[name] = np.tile([0.0, 0.0, 0.0, 1.0], (t.size, 1))
    demo = Demonstration(t, bodies, pos, quats)
    # within 15° of a bearing: the head's yaw is bearing ± 15° at (bearing + 60 ∓ 15) / 12 s
    truth = [
        (n, (b + 45.0) / 12.0, (b + 75.0) / 12.0) for n, b in (("a", -40), ("b", 0), ("c", 40))
    ]
    return demo, truth


def test_attention_intervals_exact_without_hysteresis() -> None:
    demo, truth = _turning_head()
    got = attended_objects(demo, hysteresis_deg=0.0)
    assert [a.object for a in got] == ["a", "b", "c"]
    for a, (_, t0, t1) in zip(got, truth, strict=True):
        assert abs(a.t0 - t0) <= 0.011 and abs(a.t1 - t1) <= 0.011


def test_attention_hysteresis_holds_on_and_suppresses_flicker() -> None:
    demo, truth = _turning_head()
    got = attended_objects(demo, hysteresis_deg=3.0)
    # leaving takes 3° more: 0.25 s later at 12°/s
    for a, (_, t0, t1) in zip(got, truth, strict=True):
        assert abs(a.t0 - t0) <= 0.011 and abs(a.t1 - (t1 + 0.25)) <= 0.011
    # a ray wavering between two objects 10° apart, within 2°, does not switch
    t = np.arange(0, 2.0, 0.01)
    wobble = 5.0 + 1.9 * np.sin(2 * np.pi * 3 * t)
    ang = np.stack([wobble, 10.0 - wobble], axis=1)
    flick = attention_intervals(t, ang, ["p", "q"], hysteresis_deg=0.0, min_duration=0.0)
    steady = attention_intervals(t, ang, ["p", "q"], hysteresis_deg=4.0)
    assert len(flick) > 5 and len(steady) == 1 and steady[0].object == "p"


def test_ray_angles_brute_force(rng: np.random.Generator) -> None:
    o = rng.normal(size=(20, 3))
    d = rng.normal(size=(20, 3))
    c = rng.normal(size=(20, 4, 3))
    got = ray_angles(o, d, c)
    for i in range(20):
        for k in range(4):
            v = c[i, k] - o[i]
            ref = np.degrees(np.arccos(v @ d[i] / np.linalg.norm(v) / np.linalg.norm(d[i])))
            assert got[i, k] == pytest.approx(ref, abs=1e-9)
    o[0] = np.nan
    assert np.all(np.isinf(ray_angles(o, d, c)[0]))


def test_events_in_task_file_round_trip(tmp_path: Path) -> None:
    task = TaskFile.new(objects=[{"name": "seating"}, {"name": "leg2"}])
    pointing = [PointingEvent("rh", "leg2", 3.0, 4.0, 1.5, "head")]
    from thirdhand.perception import AttentionInterval

    attention = [AttentionInterval("seating", 0.0, 2.5, 4.0)]
    out = add_perception_events(task, pointing=pointing, attention=attention, source="x.parquet")
    assert task.stages.perception is None
    path = tmp_path / "t.task.json"
    save_task(out, path)
    back = load_task(path)
    block = back.stages.perception
    assert block is not None
    first = {"hand": "rh", "object": "leg2", "t0": 3.0, "t1": 4.0, "angle_deg": 1.5, "ray": "head"}
    assert block.pointing[0].model_dump() == first
    assert focus_object(back, 4.5) == "leg2"  # just pointed at
    assert focus_object(back, 1.0) == "seating"  # looked at
    assert focus_object(back, 20.0) is None
    with pytest.raises(TaskFileError, match=r"pointing\[0\].object: unknown object 'leg9'"):
        add_perception_events(task, pointing=[PointingEvent("rh", "leg9", 0, 1, 1, "index")])


def test_gestures_and_attention_cli(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("typer")
    from thirdhand import io
    from thirdhand.perception.cli import app

    demo = make_scene("bench", seed=1, head=True, pointing=2)
    rec = tmp_path / "bench.parquet"
    io.save(demo, rec)
    task = tmp_path / "bench.task.json"
    save_task(TaskFile.new(objects=[{"name": b} for b in demo.bodies_of_kind("part")]), task)
    with pytest.raises(SystemExit) as done:
        app(["gestures", str(rec), "--json", "-", "--task", str(task)], prog_name="thirdhand")
    assert done.value.code == 0
    data = json.loads(capsys.readouterr().out)
    assert [e["object"] for e in data["pointing"]] == [g["object"] for g in demo.meta["pointing"]]
    block = load_task(task).stages.perception
    assert block is not None and len(block.pointing) == 2
    with pytest.raises(SystemExit) as done:
        app(["attention", str(rec)], prog_name="thirdhand")
    assert done.value.code == 0
    assert "attention intervals" in capsys.readouterr().out
    settings = tmp_path / "settings.toml"
    settings.write_text("[attention]\nforward = [1, 0]\n")
    with pytest.raises(SystemExit) as done:
        app(["attention", str(rec), "--config", str(settings)], prog_name="thirdhand")
    assert done.value.code == 1
    assert "[attention] forward" in capsys.readouterr().err
