"""``thirdhand live … --record OUT``: the stream, the simulated arm and the recognised steps."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from cli_helpers import call
from test_live_loop import cut, task_from_labels
from thirdhand import io
from thirdhand.execute.record import TOOL_BODY
from thirdhand.execute.robot import Robot
from thirdhand.live.assist import AssistOptions
from thirdhand.synth import make_scene


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    tmp = tmp_path_factory.mktemp("live_record")
    task = task_from_labels(make_scene("chair", seed=31))
    chair = make_scene("chair", seed=32)
    second = sorted(chair.labels.constraints, key=lambda c: c.time)[1]
    rec = tmp / "chair.parquet"
    io.save(cut(chair, second.time + 1.5), rec)
    tf = tmp / "task.json"
    tf.write_text(json.dumps(task.to_json_dict()))
    return {"rec": rec, "task": tf, "dir": tmp}


@pytest.mark.slow
def test_the_record_holds_the_stream_the_arm_and_the_steps(
    files: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    out, rep = files["dir"] / "run", files["dir"] / "live.json"
    rc, _, err = call(capsys, "live", str(files["rec"]), "--task", str(files["task"]),
                      "--speed", "0", "--assist", "--record", str(out),
                      "--json", str(rep))  # fmt: skip
    assert rc == 0, err
    report = json.loads(rep.read_text())
    doc = json.loads(out.with_suffix(".json").read_text())
    replay = io.load(out.with_suffix(".parquet"))
    stream = io.load(files["rec"])
    # every streamed frame and body, as it arrived, and the arm's tool beside them
    np.testing.assert_array_equal(replay.t, stream.t)
    assert replay.body_names == [*stream.body_names, TOOL_BODY]
    for name in stream.body_names:
        np.testing.assert_array_equal(replay.valid(name), stream.valid(name))
        ok = stream.valid(name)
        np.testing.assert_allclose(replay.pos(name)[ok], stream.pos(name)[ok], atol=1e-12)
    # the joints are on the stream's clock, and the tool frame is their forward kinematics
    assert doc["schema"] == "thirdhand.trajectory/1" and doc["source"] == "thirdhand.live"
    t, q = np.asarray(doc["t"]), np.asarray(doc["q"])
    np.testing.assert_allclose(t, stream.t, atol=1e-6)
    base = doc["base_pose"]
    arm = Robot.load(doc["robot"], base_pose=(np.asarray(base["pos"]), np.asarray(base["quat"])))
    # where the base stood at each frame: where it stood first, unless it drove
    where = np.asarray(doc.get("base_pos", [base["pos"]] * t.size))
    assert where.shape == (t.size, 3)
    np.testing.assert_allclose(where[0], base["pos"], atol=1e-6)
    # it drives at its speed at most (positions rounded to 1e-6 m)
    speed = np.linalg.norm(np.diff(where, axis=0), axis=1) / np.diff(t)
    assert np.all(speed <= AssistOptions().base_speed + 1e-3)
    # q rounded to 1e-6 rad: the tool moves < 1e-6 · (sum of lever arms ≈ 1.5 m) per joint;
    # checked with the arm loaded with its root where the base stood
    for place in np.unique(where.round(4), axis=0):
        there = np.all(np.abs(where - place) < 1e-4, axis=1)
        arm_there = Robot.load(doc["robot"], base_pose=(place, np.asarray(base["quat"])))
        tool = arm_there.tool_transforms(q[there])
        np.testing.assert_allclose(replay.pos(TOOL_BODY)[there], tool[:, :3, 3], atol=2e-4)
    # home until the first assist's arm moves; at the hand-over pose once it is ready
    before = t < report["assists"][0]["start"]
    np.testing.assert_allclose(q[before], np.repeat(arm.home[None], before.sum(), 0), atol=1e-6)
    ready = [
        a
        for a in report["assists"]
        if a["ready"] is not None and (a["end"] is None or a["ready"] < a["end"])
    ]
    assert ready, report["assists"]
    a = ready[0]
    held = (t > a["ready"] + 1e-6) & (t < (np.inf if a["end"] is None else a["end"]))
    assert held.any()
    assert np.ptp(q[held], axis=0).max() < 1e-9  # it holds still at the hand-over pose
    # and home again once the person took the part, before the next assist moves
    done = [b for b in report["assists"] if b["end"] is not None]
    if len(report["assists"]) > len(done) > 0:
        after = (t >= done[-1]["end"]) & (t < report["assists"][len(done)]["start"])
        np.testing.assert_allclose(q[after], np.repeat(arm.home[None], after.sum(), 0), atol=1e-6)
    # the recognised steps, with their times, as the report has them
    formed = [s for s in doc["recognised"] if s["kind"] == "formed"]
    assert [(s["constraint"], s["child"]) for s in formed] == [
        (s["constraint"], s["child"]) for s in report["steps"]
    ]
    for s, r in zip(formed, report["steps"], strict=True):
        assert s["t"] == pytest.approx(r["recognised_s"], abs=1e-4)
    # never over an existing record without --force
    rc, _, err = call(capsys, "live", str(files["rec"]), "--task", str(files["task"]),
                      "--speed", "0", "--record", str(out))  # fmt: skip
    assert rc == 1 and "--force" in err and err.count("\n") == 1


def test_without_the_assist_the_record_is_the_stream_and_its_steps(
    files: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    out = files["dir"] / "plain.parquet"
    rc, _, err = call(capsys, "live", str(files["rec"]), "--task", str(files["task"]),
                      "--speed", "0", "--record", str(out))  # fmt: skip
    assert rc == 0, err
    doc = json.loads(out.with_suffix(".json").read_text())
    assert doc["t"] == [] and doc["q"] == [] and doc["robot"] is None
    assert [s["kind"] for s in doc["recognised"]] == ["formed", "formed"]
    replay = io.load(out)
    assert TOOL_BODY not in replay.body_names
    # the review lists the recognised steps beside the playback
    from thirdhand.review.panels import live_steps_html

    assert replay.meta["live_steps"] == doc["recognised"]
    page = live_steps_html(replay.meta)
    for s in doc["recognised"]:
        assert f"{s['t']:.2f} s" in page and f"step {s['step']} recognised" in page
        assert f"{s['constraint']}: {s['parent']} ← {s['child']}" in page
    assert live_steps_html({}) == ""
    # --record and --json may not name the same file
    rc, _, err = call(capsys, "live", str(files["rec"]), "--task", str(files["task"]),
                      "--speed", "0", "--record", str(files["dir"] / "same"),
                      "--json", str(files["dir"] / "same.json"))  # fmt: skip
    assert rc == 1 and "name the same file" in err and err.count("\n") == 1


def test_the_record_opens_in_rerun_with_the_steps_on_the_stream_clock(
    files: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("rerun")
    from rerun.chunk import RrdReader

    out = files["dir"] / "forrrd"
    rc, _, err = call(capsys, "live", str(files["rec"]), "--task", str(files["task"]),
                      "--speed", "0", "--record", str(out))  # fmt: skip
    assert rc == 0, err
    rrd = files["dir"] / "run.rrd"
    rc, _, err = call(capsys, "convert", str(out.with_suffix(".parquet")), str(rrd),
                      "--with", str(out.with_suffix(".json")),
                      "--with", str(files["task"]))  # fmt: skip
    assert rc == 0, err
    steps = [c for c in RrdReader(rrd).stream() if c.entity_path == "/live/steps"]
    assert sum(c.num_rows for c in steps) == 2
    times = sorted(v for c in steps for v in c.to_record_batch().column("time").to_pylist())
    doc = json.loads(out.with_suffix(".json").read_text())
    want = sorted(s["t"] for s in doc["recognised"])
    # rerun stores durations in nanoseconds
    got = [v.total_seconds() if hasattr(v, "total_seconds") else v / 1e9 for v in times]
    np.testing.assert_allclose(got, want, atol=1e-6)
