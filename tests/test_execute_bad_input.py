"""``thirdhand execute`` on bad task files: one line saying what and where, never a crash.

An unreachable goal is a per-step failure report
(``tests/test_execute_executor.py::test_unreachable_constraint_ends_with_a_failure_report``);
``--record OUT`` over the task file is refused (``tests/test_outputs.py``).
"""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

import pytest

from tests.cli_helpers import call, settings_file


@pytest.fixture(scope="module")
def bench_doc() -> dict[str, Any]:
    from thirdhand.synth import make_scene
    from thirdhand.synth.task import truth_task
    from thirdhand.task.store import dump_task

    return json.loads(dump_task(truth_task(make_scene("bench", seed=0))))


def _run(capsys, tmp_path: Path, doc: dict[str, Any], *extra: str) -> tuple[int, str, str]:
    path = tmp_path / "task.json"
    path.write_text(json.dumps(doc))
    before = path.read_bytes()
    cfg = settings_file(tmp_path, "execute", step_time=5.0)
    rc, out, err = call(capsys, "execute", str(path), "--config", str(cfg), *extra)
    assert path.read_bytes() == before
    return rc, out, err


def _one_line(err: str) -> str:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    return lines[0]


def test_constraints_forming_a_cycle_are_refused(capsys, tmp_path, bench_doc) -> None:
    doc = copy.deepcopy(bench_doc)
    a, b = doc["constraints"][0], doc["constraints"][1]
    a["parent"], b["parent"] = b["child"], a["child"]
    rc, _, err = _run(capsys, tmp_path, doc)
    line = _one_line(err)
    assert rc == 1 and "task.json" in line and "cycle" in line
    assert f"{a['child']} -> {b['child']}" in line or f"{b['child']} -> {a['child']}" in line


@pytest.mark.parametrize(
    ("where", "field", "value", "says"),
    [
        ("plan", "child", "leg9", "plan[0].child: unknown object 'leg9'"),
        ("plan", "constraint", "c9", "plan[0].constraint: unknown constraint 'c9'"),
        ("constraints", "child", "leg9", "constraints[0].child: unknown object 'leg9'"),
    ],
)
def test_a_plan_naming_a_missing_part_is_refused(
    capsys, tmp_path, bench_doc, where, field, value, says
) -> None:
    doc = copy.deepcopy(bench_doc)
    doc[where][0][field] = value
    rc, _, err = _run(capsys, tmp_path, doc)
    assert rc == 1 and says in _one_line(err)


def test_a_plan_listing_a_step_twice_is_refused(capsys, tmp_path, bench_doc) -> None:
    # plan = [c1, c1, ...]: the second would pick the part already in its slot
    doc = copy.deepcopy(bench_doc)
    first = doc["plan"][0]
    doc["plan"] = [first, copy.deepcopy(first), *doc["plan"][1:]]
    rc, _, err = _run(capsys, tmp_path, doc)
    line = _one_line(err)
    cid = first["constraint"]
    assert rc == 1 and "task.json" in line
    assert f"plan[1].constraint: constraint {cid!r} is already made by plan[0]" in line


def test_a_step_after_a_later_one_is_refused(capsys, tmp_path, bench_doc) -> None:
    # ``after`` names earlier steps only, so a plan's order cannot form a cycle
    doc = copy.deepcopy(bench_doc)
    doc["plan"][0]["after"] = [1]
    rc, _, err = _run(capsys, tmp_path, doc)
    assert rc == 1 and "plan[0].after[0]" in _one_line(err)


def test_two_base_parts_are_refused(capsys, tmp_path, bench_doc) -> None:
    # a second root: leg2 hangs from leg1, which is nobody's child any more
    doc = copy.deepcopy(bench_doc)
    doc["constraints"] = [c for c in doc["constraints"] if c["child"] != "leg1"]
    doc["plan"] = [s for s in doc["plan"] if s["child"] != "leg1"]
    for s in doc["plan"]:
        s["after"] = None
    leg2 = next(c for c in doc["constraints"] if c["child"] == "leg2")
    leg2["parent"] = "leg1"
    for s in doc["plan"]:
        if s["child"] == "leg2":
            s["parent"] = "leg1"
    rc, _, err = _run(capsys, tmp_path, doc)
    line = _one_line(err)
    assert rc == 1 and "base part" in line and "leg1" in line


def test_unknown_placement_is_refused(capsys, tmp_path, bench_doc) -> None:
    path = tmp_path / "task.json"
    path.write_text(json.dumps(bench_doc))
    cfg = settings_file(tmp_path, "execute", placement="best")
    rc, _, err = call(capsys, "execute", str(path), "--config", str(cfg))
    assert rc == 1 and "[execute] placement: Input should be 'auto', 'geometry' or 'reach'" in (
        _one_line(err)
    )


def test_negative_start_grasps_is_refused(capsys, tmp_path, bench_doc) -> None:
    path = tmp_path / "task.json"
    path.write_text(json.dumps(bench_doc))
    cfg = settings_file(tmp_path, "execute", start_grasps=-1)
    rc, _, err = call(capsys, "execute", str(path), "--config", str(cfg))
    assert rc == 1 and "[execute] start_grasps" in _one_line(err)
