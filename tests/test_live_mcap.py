"""Following a ROS 2 MCAP as it is written: the same frames as the offline reader, the same
steps as the replay, bad input one line."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np
import pytest

from test_live_loop import cut, task_from_labels
from thirdhand import io
from thirdhand.demonstration import BodyInfo
from thirdhand.errors import ThirdhandError
from thirdhand.live.loop import LiveLoop
from thirdhand.live.source import ReplaySource
from thirdhand.synth import make_scene

pytest.importorskip("mcap")
from thirdhand.live.mcap_source import McapSource


def _grow(src: Path, dst: Path, *, piece: int = 4096, pause_s: float = 0.001) -> threading.Thread:
    """Copy ``src`` into ``dst`` a piece at a time, as a recorder appends to its file."""
    data = src.read_bytes()
    start = dst.stat().st_size if dst.exists() else 0  # what the recorder wrote already

    def run() -> None:
        with dst.open("ab" if start else "wb") as f:
            for k in range(start, len(data), piece):
                f.write(data[k : k + piece])
                f.flush()
                time.sleep(pause_s)

    th = threading.Thread(target=run)
    th.start()
    return th


def test_frames_of_a_growing_file_equal_the_offline_reader(tmp_path: Path) -> None:
    demo = cut(make_scene("chair", seed=32), 4.0)
    full = tmp_path / "full.mcap"
    io.save(demo, full)
    th = _grow(full, tmp_path / "growing.mcap")
    source = McapSource(tmp_path / "growing.mcap", idle_s=1.0)
    frames = list(source)
    th.join()
    offline = io.load(full)
    assert [b.name for b in source.bodies] == offline.body_names
    np.testing.assert_array_equal([f.t for f in frames], offline.t)
    for k, name in enumerate(offline.body_names):
        ok = offline.valid(name)
        np.testing.assert_array_equal([f.valid[k] for f in frames], ok)
        np.testing.assert_array_equal(
            np.stack([f.pos[k] for f in frames])[ok], offline.pos(name)[ok]
        )
        np.testing.assert_array_equal(
            np.stack([f.quat[k] for f in frames])[ok], offline.quat(name)[ok]
        )
    assert source.late_messages == 0


@pytest.mark.slow
def test_the_live_loop_on_a_growing_file_recognises_what_the_replay_does(tmp_path: Path) -> None:
    task = task_from_labels(make_scene("chair", seed=31))
    chair = make_scene("chair", seed=32)
    second = sorted(chair.labels.constraints, key=lambda c: c.time)[1]
    full = tmp_path / "full.mcap"
    io.save(cut(chair, second.time + 1.5), full)
    offline = io.load(full)
    want = LiveLoop(task, offline.bodies, offline.meta).run(ReplaySource(offline, 0)).to_dict()
    th = _grow(full, tmp_path / "growing.mcap", piece=65536)
    source = McapSource(tmp_path / "growing.mcap", idle_s=2.0)
    got = LiveLoop(task, source.bodies, source.meta).run(source).to_dict()
    th.join()
    assert len(want["steps"]) == 2
    assert [(s["constraint"], s["child"], s["recognised_s"]) for s in got["steps"]] == [
        (s["constraint"], s["child"], s["recognised_s"]) for s in want["steps"]
    ]


def test_a_file_without_thirdhand_meta_needs_its_bodies(tmp_path: Path) -> None:
    from mcap.writer import Writer

    path = tmp_path / "bare.mcap"
    with path.open("wb") as f:
        w = Writer(f)
        w.start()
        w.finish()
    with pytest.raises(ThirdhandError, match="no /thirdhand/meta message first") as err:
        McapSource(path, idle_s=0.2)
    assert "\n" not in str(err.value)
    # given bodies, it reads the (empty) stream to its footer
    assert list(McapSource(path, [BodyInfo("a")], meta={}, idle_s=0.2)) == []
    with pytest.raises(ThirdhandError, match="not given: b"):
        McapSource(path, [BodyInfo("a")], topics={"/b": "b"}, meta={}, idle_s=0.2)
    with pytest.raises(ThirdhandError, match="no such file after waiting"):
        McapSource(tmp_path / "never.mcap", [BodyInfo("a")], idle_s=0.05)


def test_a_lab_bag_written_by_another_writer_with_its_own_topics(tmp_path: Path) -> None:
    """``mcap_ros2``'s writer, a PoseStamped topic among /tf and a battery topic: the frames
    are the camera's poses at its header stamps, from the first one."""
    pytest.importorskip("mcap_ros2.writer")
    from test_io_mcap_foreign import _write_foreign

    path = tmp_path / "lab.mcap"
    truth = _write_foreign(path)
    source = McapSource(
        path, [BodyInfo("camera")], topics={"/camera/pose": "camera"}, meta={}, idle_s=0.5
    )
    frames = list(source)
    stamps = np.asarray(truth["cam_stamps"])
    p, q = truth["camera"]
    np.testing.assert_array_equal([f.t for f in frames], (stamps - stamps[0]) / 1e9)
    np.testing.assert_array_equal(np.stack([f.pos[0] for f in frames]), p)
    np.testing.assert_array_equal(np.stack([f.quat[0] for f in frames]), q)
    assert all(f.valid[0] for f in frames)


def test_being_written_is_told_by_the_closing_magic(tmp_path: Path) -> None:
    from thirdhand.live.mcap_source import MAGIC, being_written

    full = tmp_path / "full.mcap"
    io.save(cut(make_scene("chair", seed=32), 1.0), full)
    data = full.read_bytes()
    assert data.startswith(MAGIC) and data.endswith(MAGIC) and not being_written(full)
    part = tmp_path / "part.mcap"
    part.write_bytes(data[: len(data) // 2])
    assert being_written(part)
    other = tmp_path / "other.mcap"
    other.write_bytes(b"not an mcap file at all")
    assert not being_written(other) and not being_written(tmp_path / "none.mcap")


@pytest.mark.slow
def test_the_command_follows_a_file_being_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``thirdhand live growing.mcap --task T``: the steps of the finished file's replay,
    and ``--record`` writes what arrived."""
    import json

    from cli_helpers import call

    task = task_from_labels(make_scene("chair", seed=31))
    tf = tmp_path / "task.json"
    tf.write_text(json.dumps(task.to_json_dict()))
    chair = make_scene("chair", seed=32)
    second = sorted(chair.labels.constraints, key=lambda c: c.time)[1]
    full = tmp_path / "full.mcap"
    io.save(cut(chair, second.time + 1.5), full)
    rc, _, err = call(capsys, "live", str(full), "--task", str(tf), "--speed", "0",
                      "--json", str(tmp_path / "want.json"))  # fmt: skip
    assert rc == 0, err
    growing = tmp_path / "growing.mcap"
    growing.write_bytes(full.read_bytes()[:65536])  # the recorder has started
    rc, _, err = call(capsys, "live", str(growing), "--task", str(tf), "--speed", "0")
    assert rc == 1 and "is being written" in err and err.count("\n") == 1
    th = _grow(full, growing, piece=65536)
    got_json, rec = tmp_path / "got.json", tmp_path / "rec"
    rc, _, err = call(capsys, "live", str(growing), "--task", str(tf),
                      "--json", str(got_json), "--record", str(rec))  # fmt: skip
    th.join()
    assert rc == 0, err
    want = json.loads((tmp_path / "want.json").read_text())
    got = json.loads((tmp_path / "got.json").read_text())
    assert len(want["steps"]) == 2
    assert [(s["constraint"], s["child"], s["recognised_s"]) for s in got["steps"]] == [
        (s["constraint"], s["child"], s["recognised_s"]) for s in want["steps"]
    ]
    replay = io.load(tmp_path / "rec.parquet")
    offline = io.load(full)
    np.testing.assert_array_equal(replay.t, offline.t)
    for name in offline.body_names:
        ok = offline.valid(name)
        np.testing.assert_array_equal(replay.valid(name), ok)
        np.testing.assert_array_equal(replay.pos(name)[ok], offline.pos(name)[ok])
