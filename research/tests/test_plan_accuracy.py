"""Plan-accuracy tables: few runs, units in processes, the CLI's option checks."""

from __future__ import annotations

import pytest


def test_experiment_tables_with_few_runs() -> None:
    from research.plan_accuracy import corrections_table, plan_success_table

    rows = plan_success_table(scene="bench", runs=1, max_demos=2, scale=None)
    assert [r.ours for r in rows] == ["1.000 (1/1)", "1.000 (1/1)"]
    assert rows[0].report == "0.52"
    (row,) = corrections_table(scenes=("bench",), seeds=[0], scale=None)
    assert row.ours.startswith("0.00 of 24")


def test_experiment_units_in_processes_give_the_serial_table() -> None:
    """Every (scene, noise, seed) is a unit; two processes give the serial table exactly."""
    from research.plan_accuracy import constraint_error_table, plan_success_table

    kw = {"scenes": ("bench",), "noise_scales": (None, 1.0), "seeds": [0, 1]}
    serial = constraint_error_table(**kw)  # type: ignore[arg-type]
    assert [r.label for r in serial] == ["bench, noise none", "bench, noise x1"]
    assert serial == constraint_error_table(**kw, jobs=2)  # type: ignore[arg-type]
    plan = {"scene": "bench", "runs": 2, "max_demos": 2, "scale": None}
    assert plan_success_table(**plan) == plan_success_table(**plan, jobs=2)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["plan", "--scene", "nope"], "--scene: unknown scene 'nope'"),
        (["plan", "--runs", "0"], "--runs"),
        (["plan", "--noise", "nan"], "--noise"),
        (["constraints", "--jobs", "0"], "--jobs"),
        (["corrections", "--scheduler", "http://h:1"], "expected tcp://HOST:PORT"),
    ],
)
def test_experiment_options_are_checked(
    args: list[str], expected: str, capsys: pytest.CaptureFixture[str]
) -> None:
    from research.tests.helpers import call

    rc, out, err = call(capsys, "experiment", *args)
    assert rc in (1, 2) and expected in err and err.count("\n") == 1 and not out
