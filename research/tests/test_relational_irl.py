"""The relational IRL tables: trials, checkpoints, the research CLI."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from research.cli import app
from research.irl_tables import run_experiment
from research.relational_irl import (
    Trial,
    _grid,
    format_markdown,
    format_table,
    run_trial,
)
from thirdhand.relational.logic import RelationalError


def test_trial_and_table() -> None:
    trial = Trial("unstack", ("blocks4",), ("blocks4", "blocks4-fixed"), n_trees=10, n_eval=100)
    res = run_trial(trial)
    assert set(res) == {"BLMRIL", "RCSI", "RCSI+shaping"}
    for per in res.values():
        assert set(per) == {"blocks4", "blocks4-fixed"}
        assert all(0.0 <= v <= 1.0 + 1e-9 for v in per.values())
    with pytest.raises(RelationalError, match="unknown experiment"):
        run_experiment("bogus")
    table = format_table(
        {
            "experiment": "noise",
            "runs": 3,
            "columns": ["RCSI"],
            "rows": [
                {"label": "stack", "values": {"RCSI": (0.9, 0.01, 3)}, "paper": {"RCSI": 0.97}}
            ],
        }
    )
    assert "0.900 ± 0.010" in table and "RCSI: 0.97" in table
    md = format_markdown(
        {
            "experiment": "noise",
            "runs": 3,
            "columns": ["RCSI"],
            "rows": [
                {"label": "stack", "values": {"RCSI": (0.9, 0.01, 3)}, "paper": {"RCSI": 0.97}}
            ],
        }
    )
    assert md.splitlines()[2] == "| stack | 0.900 ± 0.010 | RCSI: 0.97 |"


def test_checkpoint_resumes(tmp_path: Path) -> None:
    ck = tmp_path / "ck.jsonl"
    base = {"n_trees": 3, "n_eval": 50, "methods": ("BLMRIL", "RCSI")}
    rows: list[tuple[str, Trial, dict[str, float]]] = [
        ("a", Trial("unstack", ("blocks3",), ("blocks3",), **base), {}),  # type: ignore[arg-type]
        ("b", Trial("stack", ("blocks3",), ("blocks3",), **base), {}),  # type: ignore[arg-type]
    ]
    cols = [("RCSI", "RCSI", "blocks3"), ("BLMRIL", "BLMRIL", "blocks3")]
    first = _grid("t", rows, cols, 2, 1, ck)
    lines = ck.read_text().splitlines()
    # Seed-major order: every row's first seed before any row's second.
    assert [json.loads(x)["label"] for x in lines] == ["a", "b", "a", "b"]
    assert first["runs"] == 2 and first["rows"][0]["values"]["RCSI"][2] == 2
    with open(ck, "a") as fh:
        fh.write('{"experiment": "t", "label": "a", "se')  # a run stopped mid-write
    part = _grid("t", rows, cols, 3, 1, ck, tabulate_only=True)
    assert part["runs"] == 2
    again = _grid("t", rows, cols, 3, 1, ck)
    recs = [json.loads(x) for x in ck.read_text().splitlines()[5:]]
    assert [(r["label"], r["seed"]) for r in recs] == [("a", 2017), ("b", 2017)]
    assert again["runs"] == 3
    # Resumed results are the stored ones: the first two seeds are not rerun.
    assert again["rows"][1]["values"]["BLMRIL"][2] == 3


def test_cli_experiment(tmp_path: Path) -> None:
    out = tmp_path / "dyn.json"
    res = CliRunner().invoke(app, ["irl", "dynamics", "--runs", "2", "--json", str(out)])
    assert res.exit_code == 0, res.output
    assert "0.98 -> 0.57" in res.output
    data = json.loads(out.read_text())
    assert data["runs"] == 2 and len(data["rows"]) == 2
    res = CliRunner().invoke(app, ["irl", "dynamics", "--runs", "2", "--tabulate"])
    assert res.exit_code != 0 and "needs --checkpoint" in str(res.exception)


def test_experiment_bad_name_and_runs() -> None:
    res = CliRunner().invoke(app, ["irl", "huge", "--runs", "2"])
    assert isinstance(res.exception, RelationalError) and "unknown experiment 'huge'" in str(
        res.exception
    )
    res = CliRunner().invoke(app, ["irl", "large", "--runs", "0"])
    assert res.exit_code != 0


def test_large_experiment_refuses_checkpoints(tmp_path: Path) -> None:
    ck = tmp_path / "ck.jsonl"
    res = CliRunner().invoke(
        app,
        [
            "irl",
            "large",
            "--runs",
            "2",
            "--checkpoint",
            str(ck),
            "--json",
            str(tmp_path / "o.json"),
        ],
    )
    assert isinstance(res.exception, RelationalError)
    assert "--checkpoint and --tabulate are not supported" in str(res.exception)
