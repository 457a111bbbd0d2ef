"""Content checked against what it claims, in the typed models every consumer reads.

A plan step against its constraint and its objects; an empty plan is no success.
"""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

import pytest

from cli_helpers import call, settings_file
from thirdhand.errors import TaskFileError
from thirdhand.task.store import parse_task


@pytest.fixture(scope="module")
def bench_doc() -> dict[str, Any]:
    from thirdhand.synth import make_scene
    from thirdhand.synth.task import truth_task
    from thirdhand.task.store import dump_task

    return json.loads(dump_task(truth_task(make_scene("bench", seed=0))))


def _swap(doc: dict[str, Any]) -> None:
    doc["plan"][0]["parent"], doc["plan"][0]["child"] = (
        doc["plan"][0]["child"],
        doc["plan"][0]["parent"],
    )


def _other_parent(doc: dict[str, Any]) -> None:
    doc["plan"][1]["parent"] = doc["plan"][0]["child"]


def _self(doc: dict[str, Any]) -> None:
    step = doc["plan"][0]
    step["parent"] = step["child"]
    step["constraint"] = None


def _twice(doc: dict[str, Any]) -> None:
    again = copy.deepcopy(doc["plan"][0])
    again["constraint"] = None
    doc["plan"].append(again)


def _finger(doc: dict[str, Any]) -> None:
    doc["objects"].append({"name": "a finger", "kind": "finger"})
    doc["plan"].append({"parent": doc["plan"][0]["parent"], "child": "a finger"})


def _on_a_hand(doc: dict[str, Any]) -> None:
    doc["objects"].append({"name": "a hand", "kind": "hand"})
    doc["plan"].append({"parent": "a hand", "child": doc["plan"][0]["parent"]})


PLAN_CASES = [
    ("parent and child swapped", _swap, "plan[0]: mounts"),
    ("a parent not the constraint's", _other_parent, "plan[1]: mounts"),
    ("a part on itself", _self, "plan[0]: parent and child are both"),
    ("a part mounted twice", _twice, "is already mounted by plan[0]"),
    ("a finger as the child", _finger, "plan[4].child: 'a finger' is a finger of the person"),
    ("a part on a hand", _on_a_hand, "plan[4].parent: 'a hand' is a hand of the person"),
]


@pytest.mark.parametrize(("label", "change", "says"), PLAN_CASES, ids=[c[0] for c in PLAN_CASES])
def test_a_plan_step_contradicting_its_constraint_or_objects_is_refused(
    bench_doc, label, change, says
) -> None:
    parse_task(json.dumps(bench_doc))  # as learned: accepted
    doc = copy.deepcopy(bench_doc)
    change(doc)
    with pytest.raises(TaskFileError, match=None) as err:
        parse_task(json.dumps(doc), name="task.json")
    assert says in str(err.value) and "\n" not in str(err.value), (label, str(err.value))


def test_a_swapped_step_names_both_pairs(bench_doc) -> None:
    doc = copy.deepcopy(bench_doc)
    step = doc["plan"][0]
    _swap(doc)
    with pytest.raises(TaskFileError) as err:
        parse_task(json.dumps(doc), name="task.json")
    assert str(err.value) == (
        f"task.json: plan[0]: mounts {step['child']!r} on {step['parent']!r}, but its constraint "
        f"{step['constraint']!r} mounts {step['parent']!r} on {step['child']!r}"
    )


@pytest.mark.parametrize(("label", "change", "says"), PLAN_CASES[:2], ids=["swap", "other"])
def test_execute_and_convert_refuse_a_contradicting_plan(
    capsys, tmp_path: Path, bench_doc, label, change, says
) -> None:
    doc = copy.deepcopy(bench_doc)
    change(doc)
    path = tmp_path / "task.json"
    path.write_text(json.dumps(doc))
    cfg = settings_file(tmp_path, "execute", step_time=5.0)
    for args in (["execute", str(path), "--config", str(cfg)], ["convert", str(path), "o.xml"]):
        rc, out, err = call(capsys, *args)
        assert rc == 1 and err.count("\n") == 1 and says in err, (label, err)
        assert "succeeded" not in out
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([path.name, cfg.name])


def test_an_empty_plan_is_not_executed_as_a_success(capsys, tmp_path: Path, bench_doc) -> None:
    doc = copy.deepcopy(bench_doc)
    doc["plan"] = []
    path = tmp_path / "task.json"
    path.write_text(json.dumps(doc))
    cfg = settings_file(tmp_path, "execute", step_time=5.0)
    rc, out, err = call(capsys, "execute", str(path), "--config", str(cfg))
    assert rc == 1 and err.count("\n") == 1 and "the task has no plan" in err
    assert "succeeded" not in out
