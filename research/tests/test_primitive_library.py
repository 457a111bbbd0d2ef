"""Experiments of the primitives stage: LASA joins, orientation DMP comparison, the CLI."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from typer.testing import CliRunner

from research.primitive_library import lasa_join_experiment, orientation_comparison
from thirdhand.datasets.primitive_shapes import concatenate_shapes, lasa_shapes, sine_tracks
from thirdhand.primitives.cli import app
from thirdhand.primitives.primitive_library import PrimitiveLibrary

runner = CliRunner()


def test_lasa_joins_are_recovered_and_skills_are_shapes(shared_data: Path) -> None:
    r = lasa_join_experiment(shared_data / "lasa")
    assert r["joins_recovered"] == r["joins"] == 10
    assert r["extra_cuts"] == 0
    assert r["n_candidates"] > r["joins"]  # over-segmented candidates were merged
    assert r["labels_consistent"]
    assert sorted(r["mapping"]) == ["GShape", "PShape", "Worm"]


def test_lasa_reader_and_concatenation(shared_data: Path) -> None:
    demos = lasa_shapes(shared_data / "lasa", "CShape")
    assert len(demos) == 7 and demos[0][1].shape == (1000, 2)
    t, y, joins = concatenate_shapes(demos[:3], rate=100.0)
    np.testing.assert_allclose(np.diff(t), 0.01)
    assert joins.size == 2
    # continuous at the joins: each shape starts where the previous ended
    assert np.abs(np.diff(y, axis=0)).max() < 5.0


def test_both_orientation_dmps_imitate_and_reach_new_goals() -> None:
    r = orientation_comparison()
    for v in r["imitation"].values():
        assert v["pos_mm"] < 1.0 and v["rot_deg"] < 0.2
    for row in r["new_goal"]:
        assert row["quaternion_final_deg"] < 0.2 and row["seven_final_deg"] < 0.2
        assert 0.5 < row["seven_min_norm"] <= 1.0


def test_cli_fit_writes_a_stage_block(tmp_path: Path) -> None:
    from thirdhand import io
    from thirdhand.synth import make_scene

    paths = []
    for s in range(2):
        p = tmp_path / f"chair{s}.parquet"
        io.save(make_scene("chair", seed=s, sensor=None), p)
        paths.append(str(p))
    from thirdhand.taskfile import TaskFile, load_task, save_task

    task = tmp_path / "chair.task.json"
    save_task(TaskFile.new(), task)
    out = tmp_path / "prims.json"
    cfg = tmp_path / "settings.toml"
    cfg.write_text("[primitives.fit]\npromp_weights = 5\n")
    res = runner.invoke(
        app, ["fit", *paths, "-o", str(out), "--config", str(cfg), "--task", str(task)]
    )
    assert res.exit_code == 0, res.output
    stored = load_task(task).stages.primitives
    assert stored is not None and set(stored.constraints) == {"c1", "c2", "c3", "c4", "c5"}
    assert (tmp_path / "chair.task.json.bak").exists()
    block = json.loads(out.read_text())
    assert block["schema"] == "thirdhand.primitives/1"
    assert set(block["constraints"]) == {"c1", "c2", "c3", "c4", "c5"}
    assert "c5" in res.output and "mm" in res.output


def test_cli_library_on_csv_tracks(tmp_path: Path) -> None:
    files = []
    for i, (t, y, _, _) in enumerate(sine_tracks(6, seed=0)):
        f = tmp_path / f"sine{i}.csv"
        np.savetxt(f, np.column_stack([t, y]), delimiter=",")
        files.append(str(f))
    png = tmp_path / "skills.png"
    res = runner.invoke(app, ["library", *files, "--skills", "3", "--plot", str(png), "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.output)
    assert len(data["tracks"]) == 6 and len(data["skill_weights"]) == 3
    assert png.stat().st_size > 10_000


def test_cli_errors_are_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "bad.csv"
    bad.write_text("0,1\n0.1,nan\n0.2,3\n0.3,4\n0.4,5\n")
    res = runner.invoke(app, ["library", str(bad)])
    assert res.exit_code == 1
    assert "row 2 has NaN or infinite values" in res.output
    res = runner.invoke(app, ["fit", str(tmp_path / "missing.parquet"), "-o", str(tmp_path / "o")])
    assert res.exit_code != 0


def test_sine_experiment_finds_three_skills() -> None:
    train = sine_tracks(10, seed=0)
    lib = PrimitiveLibrary(3, threshold=0.05, seed=0).fit([(t, y) for t, y, _, _ in train])
    assert np.all(lib.mixture_.weights_ > 0.1)
    mapping: dict[int, int] = {}
    for t, y, bounds, labels in sine_tracks(10, seed=100):
        p = lib.parse(t, y)
        assert p.bounds.size == bounds.size
        assert np.abs(p.bounds - bounds).max() <= 2
        # the candidates over-segment: every bump's top was a candidate and was merged
        assert p.candidates.size > p.cuts.size
        for found, true in zip(p.labels, labels, strict=True):
            assert mapping.setdefault(int(found), int(true)) == true
    assert sorted(mapping.values()) == [0, 1, 2]
    assert len(lib.skills()) == 3


def test_two_hundred_candidate_cuts_parse_exactly() -> None:
    from research.primitive_library import library_scaling

    r = library_scaling()
    assert r["n_candidates"] >= 200
    assert r["n_cuts"] == r["true_cuts"]
