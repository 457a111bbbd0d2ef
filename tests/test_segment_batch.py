"""``thirdhand segment batch``: many recordings, one unit each, the same files however run."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from cli_helpers import call
from thirdhand import io
from thirdhand.errors import FormatError, ThirdhandError
from thirdhand.segment.batch import SegmentJob, output_names, recordings_in, segment_unit
from thirdhand.segment.pipeline import segment_demonstration
from thirdhand.synth import make_scene


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two short noise-free drawer recordings (parquet, Motive CSV) and a file no reader knows."""
    root = tmp_path_factory.mktemp("recs")
    io.save(make_scene("drawer", seed=1, sensor=None).slice(0.0, 4.0), root / "one.parquet")
    io.save(make_scene("drawer", seed=2, sensor=None).slice(0.0, 4.0), root / "two.csv")
    (root / "notes.md").write_text("not a recording\n")
    return root


def test_a_folder_is_its_readable_recordings_in_name_order(folder: Path) -> None:
    assert recordings_in([folder]) == [folder / "one.parquet", folder / "two.csv"]
    # a recording named twice (itself and through its folder) is segmented once
    assert recordings_in([folder / "two.csv", folder]) == [
        folder / "two.csv",
        folder / "one.parquet",
    ]


def test_inputs_that_are_nothing_are_refused(folder: Path, tmp_path: Path) -> None:
    with pytest.raises(FormatError, match="no such file"):
        recordings_in([tmp_path / "missing.parquet"])
    with pytest.raises(FormatError, match="holds no readable recording"):
        recordings_in([tmp_path])
    with pytest.raises(FormatError, match="unrecognised recording format"):
        recordings_in([folder / "notes.md"])


def test_output_names_keep_extensions_only_on_a_clash(tmp_path: Path) -> None:
    a, b, c = tmp_path / "a.csv", tmp_path / "a.c3d", tmp_path / "b.parquet"
    for p in (a, b, c):
        p.write_text("")
    assert output_names([a, b, c]) == ["a.csv.phases.json", "a.c3d.phases.json", "b.phases.json"]
    (tmp_path / "x").mkdir()
    twin = tmp_path / "x" / "b.parquet"
    twin.write_text("")
    with pytest.raises(ThirdhandError, match=r"would both be written as b\.parquet\.phases\.json"):
        output_names([c, twin])


def test_unit_equals_segmenting_in_process(folder: Path) -> None:
    outcome = segment_unit(SegmentJob(str(folder / "one.parquet")))
    assert outcome.error is None
    expected = segment_demonstration(io.load(folder / "one.parquet")).to_dict()
    assert outcome.phases == expected
    assert outcome.n_pairs == len(expected["pairs"]) and outcome.n_steps == len(expected["time"])


def test_serial_and_two_processes_write_the_same_files(
    folder: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rc, out, err = call(capsys, "segment", "batch", str(folder), "-o", str(tmp_path / "serial"))
    assert rc == 0, err
    assert "one.parquet: " in out and "two.csv: " in out
    rc, _, err = call(
        capsys, "segment", "batch", str(folder), "-o", str(tmp_path / "jobs"), "--jobs", "2"
    )
    assert rc == 0, err
    for name in ("one.phases.json", "two.phases.json"):
        serial = json.loads((tmp_path / "serial" / name).read_text())
        assert serial["format"] == "thirdhand.phases/1"
        assert serial == json.loads((tmp_path / "jobs" / name).read_text())
    assert sorted(p.name for p in (tmp_path / "serial").iterdir()) == [
        "one.phases.json",
        "two.phases.json",
    ]


def test_a_bad_recording_is_reported_and_the_others_are_written(
    folder: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "cut.parquet"
    bad.write_bytes((folder / "one.parquet").read_bytes()[:200])  # a file cut short
    out_dir = tmp_path / "out"
    rc, out, err = call(
        capsys, "segment", "batch", str(bad), str(folder / "two.csv"), "-o", str(out_dir)
    )
    assert rc == 1
    assert err.count("\n") == 1 and "1 of 2 recordings failed" in err and "cut.parquet" in err
    assert "cut.parquet: FAILED" in out
    assert [p.name for p in out_dir.iterdir()] == ["two.phases.json"]


def test_existing_outputs_are_refused_before_any_work(
    folder: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    (out_dir / "two.phases.json").write_text("mine\n")
    rc, _, err = call(capsys, "segment", "batch", str(folder), "-o", str(out_dir))
    assert rc == 1 and "exists; pass --force" in err and err.count("\n") == 1
    assert sorted(p.name for p in out_dir.iterdir()) == ["two.phases.json"]  # nothing written
    assert (out_dir / "two.phases.json").read_text() == "mine\n"
    rc, _, err = call(capsys, "segment", "batch", str(folder), "-o", str(out_dir), "--force")
    assert rc == 0, err
    assert (out_dir / "two.phases.json.bak").read_text() == "mine\n"


def test_output_inside_an_input_folder_and_bad_options(
    folder: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rc, _, err = call(capsys, "segment", "batch", str(folder), "-o", str(folder / "phases"))
    assert rc == 1 and "inside the input folder" in err
    assert not (folder / "phases").exists()
    a_file = tmp_path / "f.txt"
    a_file.write_text("")
    for extra, expected in (
        (["-o", str(a_file)], "expected a folder, it is a file"),
        (["-o", str(tmp_path / "o"), "--jobs", "0"], "--jobs"),
        (["-o", str(tmp_path / "o"), "--scheduler", "http://x:1"], "expected tcp://HOST:PORT"),
        (["-o", str(tmp_path / "o"), "-m", str(tmp_path / "none.json")], "none.json"),
    ):
        rc, _, err = call(capsys, "segment", "batch", str(folder), *extra)
        assert rc in (1, 2) and expected in err and err.count("\n") == 1, err
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_real_recordings_folder(shared_data: Path, tmp_path: Path) -> None:
    """The shared 3rdHand folder: its two recordings found beside meshes and a YAML file."""
    root = shared_data / "3rdhand"
    found = recordings_in([root])
    assert [p.name for p in found] == ["toolbox_coop_4", "toolbox_coop_4_excerpt"]
    outcome = segment_unit(SegmentJob(str(root / "toolbox_coop_4")))
    assert outcome.error is None
    # the left hand's labels ship with the recording; the shipped model's figure is 0.913
    assert outcome.scores["finger-object"]["frame_f1"] > 0.85
