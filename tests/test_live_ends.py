"""How ``thirdhand live`` ends: a stream cut or never closed, a speed out of bounds,
Ctrl-C, and its settings from ``--config``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from cli_helpers import call, settings_file
from test_live_loop import cut, task_from_labels
from thirdhand import io
from thirdhand.live.assist import AssistOptions
from thirdhand.live.settings import LiveSettings
from thirdhand.live.source import ReplaySource
from thirdhand.synth import make_scene


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("live_ends")
    chair = make_scene("chair", seed=32)
    first = min(chair.labels.constraints, key=lambda c: c.time)
    rec = folder / "chair.parquet"
    io.save(cut(chair, first.time + 1.5), rec)
    tf = folder / "task.json"
    tf.write_text(json.dumps(task_from_labels(make_scene("chair", seed=31)).to_json_dict()))
    return {"dir": folder, "rec": rec, "task": tf}


@pytest.mark.parametrize("speed", ["1e-300", "1e-9", "0.001", "1e9", "inf", "nan", "-1"])
def test_a_speed_out_of_bounds_is_one_line(
    files: dict[str, Path], capsys: pytest.CaptureFixture[str], speed: str
) -> None:
    rc, _, err = call(capsys, "live", str(files["rec"]), "--task", str(files["task"]),
                      "--speed", speed)  # fmt: skip
    assert (
        rc == 1 and err.startswith("thirdhand: error: --speed must be 0") and err.count("\n") == 1
    ), err


def test_the_settings_give_the_assist_its_defaults() -> None:
    assert LiveSettings().assist_options() == AssistOptions()
    moved = LiveSettings(base_track_m=0.0, robot="panda").assist_options()
    assert moved.base_track_m == 0.0 and moved.base_speed == AssistOptions().base_speed


@pytest.mark.parametrize("keep", ["all but the closing magic", "half"])
def test_an_mcap_never_closed_ends_the_stream_cleanly(
    files: dict[str, Path], capsys: pytest.CaptureFixture[str], keep: str
) -> None:
    """A recorder that crashed leaves a file without its closing record (or cut
    mid-record): the stream is followed to its last complete message, the step
    recognised in it is printed, the report written, and the command ends with 0."""
    pytest.importorskip("mcap")
    folder = files["dir"]
    full = folder / "full.mcap"
    if not full.exists():
        io.save(io.load(files["rec"]), full)
    rc, out_full, err = call(capsys, "live", str(full), "--task", str(files["task"]),
                             "--speed", "0")  # fmt: skip
    assert rc == 0, err
    data = full.read_bytes()
    broken = folder / f"broken_{len(keep)}.mcap"
    broken.write_bytes(data[:-8] if keep.startswith("all") else data[: len(data) // 2])
    cfg = settings_file(folder, "live", follow_idle_s=0.2)
    report = folder / f"broken_{len(keep)}.json"
    rc, out, err = call(capsys, "live", str(broken), "--task", str(files["task"]),
                        "--config", str(cfg), "--json", str(report))  # fmt: skip
    assert rc == 0, err
    assert err == ""
    assert "ended without the file's closing record" in out
    doc = json.loads(report.read_text())
    assert doc["interrupted"] is False and doc["frames"] > 0
    if keep.startswith("all"):  # every message is there: the same steps as the whole file
        assert [ln for ln in out.splitlines() if "recognised" in ln] == [
            ln for ln in out_full.splitlines() if "recognised" in ln
        ]


def test_ctrl_c_writes_the_report_so_far(
    files: dict[str, Path], capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Ctrl-C after 200 frames: the report of those 200 frames is printed and written,
    marked interrupted, and the command exits with 130."""
    frames = ReplaySource.__iter__

    def stopped(self: ReplaySource):  # type: ignore[no-untyped-def]
        for k, frame in enumerate(frames(self)):
            if k == 200:
                raise KeyboardInterrupt
            yield frame

    monkeypatch.setattr(ReplaySource, "__iter__", stopped)
    report = files["dir"] / "interrupted.json"
    rc, out, err = call(capsys, "live", str(files["rec"]), "--task", str(files["task"]),
                        "--speed", "0", "--json", str(report))  # fmt: skip
    assert rc == 130
    assert err.startswith("thirdhand: error: interrupted") and err.count("\n") == 1
    assert "interrupted: the report covers the stream up to" in out
    doc = json.loads(report.read_text())
    assert doc["interrupted"] is True and doc["frames"] == 200
