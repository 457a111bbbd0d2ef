"""The task file thirdhand.task/1: round trips, unknown fields, validation messages, safe saving."""

from __future__ import annotations

import copy
import hashlib
import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from thirdhand.demonstration import BODY_KINDS
from thirdhand.demonstration import CONSTRAINT_TYPES as DEMO_CONSTRAINT_TYPES
from thirdhand.errors import TaskFileError
from thirdhand.task.model import OBJECT_KINDS
from thirdhand.taskfile import (
    CONSTRAINT_TYPES,
    SCHEMA,
    Constraint,
    FreeDofs,
    Pose,
    TaskFile,
    dump_task,
    infer_constraint_type,
    load_task,
    parse_task,
    save_task,
)


def full_task() -> dict[str, Any]:
    """A task document that sets every field of the schema."""
    h = 0.70710678118654757
    return {
        "schema": SCHEMA,
        "objects": [
            {
                "name": "seating",
                "kind": "part",
                "mesh": "meshes/seating.stl",
                "scale": 0.001,
                "mesh_to_body": {"pos": [0.0125, -0.003, 0.1], "quat": [0.0, 0.0, h, h]},
            },
            {"name": "leg1", "kind": "part", "mesh": None, "scale": None, "mesh_to_body": None},
            {
                "name": "screwdriver",
                "kind": "tool",
                "mesh": None,
                "scale": 1.0,
                "mesh_to_body": None,
            },
        ],
        "constraints": [
            {
                "id": "c2",
                "parent": "seating",
                "child": "leg1",
                "type": "revolute",
                "pos": [0.11500000208616257, 0.004999999888241291, 0.11699999868869781],
                "quat": [0.9999890923500061, 0.0, 0.0, 0.004665976390242577],
                "frame": {"pos": [0.0, 0.0, 0.0], "quat": [0.0, 0.0, 0.0, 1.0]},
                "free_dofs": {
                    "tx": [0.0, 0.0],
                    "ty": [0.0, 0.0],
                    "tz": [0.0, 0.0],
                    "rx": [0.0, 0.0],
                    "ry": [-3.1416, 3.1416],
                    "rz": [0.0, 0.0],
                },
                "symbol": "c2",
                "confidence": 0.8125,
                "source": "learned",
                "time": 12.345678901234567,
                "demo": "chair_01.parquet",
            },
            {
                "id": "tool",
                "parent": "leg1",
                "child": "screwdriver",
                "type": "cylindrical",
                "pos": [1e-9, -2.5e-17, 0.30000000000000004],
                "quat": [0.5, -0.5, 0.5, 0.5],
                "frame": {"pos": [0.0, 0.01, 0.0], "quat": [h, 0.0, 0.0, h]},
                "free_dofs": {
                    "tx": [0.0, 0.0],
                    "ty": [0.0, 0.0],
                    "tz": [-0.02, 0.0],
                    "rx": [0.0, 0.0],
                    "ry": [0.0, 0.0],
                    "rz": [-6.283185307179586, 6.283185307179586],
                },
                "symbol": None,
                "confidence": 1.0,
                "source": "corrected",
                "time": None,
                "demo": None,
            },
        ],
        "plan": [
            {
                "action": "action",
                "parent": "seating",
                "child": "leg1",
                "symbol": "c2",
                "constraint": "c2",
                "time": 12.345678901234567,
                "keyframe": {
                    "seating": {"pos": [0.1, 0.2, 0.3], "quat": [0.0, 0.0, 0.0, 1.0]},
                    "leg1": {"pos": [0.2, 0.2, 0.4], "quat": [h, 0.0, 0.0, h]},
                },
                "after": None,
            },
            {
                "action": "screw",
                "parent": "leg1",
                "child": "screwdriver",
                "symbol": None,
                "constraint": "tool",
                "time": None,
                "keyframe": {},
                "after": [0],
            },
        ],
        "stages": {
            # known blocks first, in schema order; a field the model does not know
            # ("library") and a block it does not know ("segmentation") are kept
            "plan": {"n_demos": 2, "steps": ["action(seating, leg1, c1)"]},
            "primitives": {"library": ["dmp-0", "dmp-1"]},
            "review": {"confirmed": {"c1": ["constraint", "rz"]}},
            "segmentation": {"model": "crf", "nll": 0.123},
        },
        "provenance": {
            "inputs": [{"path": "chair_01.parquet", "sha256": "ab" * 32}],
            "thirdhand_version": "0.1.0",
            "parameters": {"crf": {"c2": 0.01}, "threshold": 0.5},
            "created": "2026-11-22T03:00:00Z",
            "modified": "2026-11-22T04:00:00.250000Z",
            "corrections": [
                {
                    "who": "adele",
                    "when": "2026-11-22T04:00:00.250000Z",
                    "field": "constraints[1].free_dofs.tz",
                    "old": [0.0, 0.0],
                    "new": [-0.02, 0.0],
                }
            ],
        },
    }


def write_json(path: Path, doc: Any) -> Path:
    path.write_text(json.dumps(doc, indent=1))
    return path


def test_full_task_round_trips_exactly(tmp_path: Path) -> None:
    doc = full_task()
    src = write_json(tmp_path / "in.json", doc)
    task = load_task(src)
    out = tmp_path / "out.json"
    save_task(task, out)
    assert json.loads(out.read_text()) == doc
    again = load_task(out)
    assert again == task
    assert dump_task(again) == out.read_text()


def test_random_floats_round_trip_bit_exactly(tmp_path: Path, rng: np.random.Generator) -> None:
    doc = full_task()
    # Magnitudes from 1e-15 to a few hundred metres (beyond MAX_COORDINATE_M is refused).
    values = rng.standard_normal(400) * 10.0 ** rng.integers(-15, 3, 400)
    for i, v in enumerate(values[:200]):
        doc["plan"][0]["keyframe"][f"b{i}"] = {
            "pos": [float(v), float(values[200 + i]), float(np.float32(v))],
            "quat": [0.0, 0.0, 0.0, 1.0],
        }
    task = load_task(write_json(tmp_path / "in.json", doc))
    save_task(task, tmp_path / "out.json")
    back = load_task(tmp_path / "out.json").plan[0].keyframe
    got = np.array([back[f"b{i}"].pos for i in range(200)])
    want = np.column_stack([values[:200], values[200:], values[:200].astype(np.float32)])
    assert np.array_equal(got, want)


def test_unknown_fields_survive_load_save_load(tmp_path: Path) -> None:
    doc = full_task()
    doc["future_top"] = {"nested": [1, 2.5, "x", None, True]}
    doc["constraints"][0]["stiffness"] = [100.0, 200.0]
    doc["constraints"][0]["frame"]["label"] = "axis"
    doc["plan"][1]["gripper"] = {"width": 0.04}
    doc["plan"][0]["keyframe"]["leg1"]["velocity"] = [0.0, 0.1, 0.0]
    doc["objects"][0]["colour"] = "blue"
    doc["provenance"]["machine"] = "lab-3"
    doc["provenance"]["corrections"][0]["reason"] = "leg too short"
    src = write_json(tmp_path / "in.json", doc)
    save_task(load_task(src), tmp_path / "out.json")
    task = load_task(tmp_path / "out.json")
    assert json.loads((tmp_path / "out.json").read_text()) == doc
    assert task.model_extra == {"future_top": {"nested": [1, 2.5, "x", None, True]}}
    assert task.constraints[0].model_extra == {"stiffness": [100.0, 200.0]}
    assert task.plan[1].model_extra == {"gripper": {"width": 0.04}}


def _set(path: str, value: Any) -> Callable[[dict[str, Any]], None]:
    """A mutation setting ``path`` (dotted, integers index lists) in a document."""

    def mutate(doc: dict[str, Any]) -> None:
        *head, last = [int(p) if p.isdigit() else p for p in path.split(".")]
        node: Any = doc
        for p in head:
            node = node[p]
        node[last] = value

    return mutate


def _del(path: str) -> Callable[[dict[str, Any]], None]:
    def mutate(doc: dict[str, Any]) -> None:
        *head, last = path.split(".")
        node: Any = doc
        for p in head:
            node = node[int(p) if p.isdigit() else p]
        del node[last]

    return mutate


def _append_plan_step(step: dict[str, Any]) -> Callable[[dict[str, Any]], None]:
    return lambda doc: doc["plan"].append(step)


INVALID = [
    (_set("constraints.1.child", "leg7"), "constraints[1].child: unknown object 'leg7'"),
    (_set("constraints.0.parent", "chair"), "constraints[0].parent: unknown object 'chair'"),
    (_set("constraints.1.id", "c2"), "constraints[1].id: duplicate constraint id 'c2'"),
    (_set("objects.2.name", "leg1"), "objects[2].name: duplicate object name 'leg1'"),
    (_set("plan.1.parent", "table"), "plan[1].parent: unknown object 'table'"),
    (_set("plan.1.constraint", "c9"), "plan[1].constraint: unknown constraint 'c9'"),
    (_set("plan.1.after", [1]), "plan[1].after[0]: step 1 is not an earlier step"),
    (
        _set("schema", "thirdhand.task/3"),
        'schema: expected "thirdhand.task/2", got "thirdhand.task/3"',
    ),
    (_set("schema", 1), 'schema: expected "thirdhand.task/2", got 1'),
    (_set("stages.plan.n_demos", "two"), "stages.plan.n_demos: Input should be a valid integer"),
    (
        _set("stages.review.confirmed", {"c1": "rz"}),
        "stages.review.confirmed.c1: Input should be a valid array",
    ),
    (_del("schema"), "schema: required field is missing"),
    (_set("constraints.0.quat", [0.0, 0.0, 0.0, 0.0]), "constraints[0].quat: quaternion has zero"),
    (_set("constraints.0.quat", [0.0, 0.0, 0.5, 0.5]), "constraints[0].quat: quaternion norm is"),
    (
        _set("plan.0.keyframe.leg1.quat", [1, 1, 0, 0]),
        "plan[0].keyframe.leg1.quat: quaternion norm",
    ),
    (_set("constraints.1.free_dofs.tz", [0.1, -0.1]), "constraints[1].free_dofs: DOF tz: range"),
    (_set("constraints.1.free_dofs.Tz", [0.0, 0.0]), "constraints[1].free_dofs.Tz: Unexpected"),
    (
        _set("constraints.0.confidence", 1.5),
        "constraints[0].confidence: expected a value in [0, 1]",
    ),
    (_set("constraints.0.source", "guessed"), "constraints[0].source: Input should be"),
    (_set("constraints.0.type", "hinge"), "constraints[0].type: Input should be"),
    (
        _set("constraints.0.pos", [0.0, "1", 0.0]),
        "constraints[0].pos[1]: Input should be a valid number",
    ),
    (_set("constraints.0.pos", [0.0, 1.0]), "constraints[0].pos[2]: required field is missing"),
    (_del("constraints.0.child"), "constraints[0].child: required field is missing"),
    (_set("objects.0.kind", "furniture"), "objects[0].kind: Input should be"),
    (_set("objects.0.scale", -1.0), "objects[0].scale: expected a positive number"),
    (_set("objects.0.name", 3), "objects[0].name: Input should be a valid string"),
    (
        _set("provenance.created", "2026-11-22T03:00:00"),
        "provenance.created: Input should have timezone",
    ),
    (_set("provenance.inputs.0.sha256", "xyz"), "provenance.inputs[0].sha256: String should match"),
    (_set("stages.reward", [1, 2]), "stages.reward: Input should be an object"),
]


@pytest.mark.parametrize(("mutate", "expected"), INVALID)
def test_invalid_task_names_file_and_location(
    tmp_path: Path, mutate: Callable[[dict[str, Any]], None], expected: str
) -> None:
    doc = full_task()
    mutate(doc)
    path = write_json(tmp_path / "bad_task.json", doc)
    with pytest.raises(TaskFileError) as info:
        load_task(path)
    message = str(info.value)
    assert message.startswith(f"{path}: ")
    assert expected in message
    assert "\n" not in message


def test_bad_json_gives_line_and_column(tmp_path: Path) -> None:
    path = tmp_path / "broken.json"
    path.write_text('{\n  "schema": "thirdhand.task/1",\n  "objects": [,]\n}\n')
    with pytest.raises(TaskFileError, match=r"broken\.json line 3 column 15: invalid JSON"):
        load_task(path)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ('{"schema": "thirdhand.task/1", "x": NaN}', "NaN is not a JSON number"),
        ('{"schema": "thirdhand.task/1", "x": 1, "x": 2}', "duplicate key 'x'"),
        ("[1, 2]", "expected a JSON object, got list"),
    ],
)
def test_non_standard_json_is_rejected(text: str, expected: str) -> None:
    with pytest.raises(TaskFileError, match=expected):
        parse_task(text, name="t.json")


def test_missing_file_is_a_task_file_error(tmp_path: Path) -> None:
    with pytest.raises(TaskFileError, match=r"nothing\.json: cannot read"):
        load_task(tmp_path / "nothing.json")


def test_quaternion_normalised_within_tolerance_and_kept_when_unit() -> None:
    doc = full_task()
    doc["constraints"][0]["quat"] = [0.0, 0.0, 0.0, 1.005]
    doc["constraints"][1]["quat"] = [0.0, 0.6, 0.0, 0.8000001]
    task = TaskFile.model_validate(doc)
    assert task.constraints[0].quat == (0.0, 0.0, 0.0, 1.0)
    assert task.constraints[1].quat == (0.0, 0.6, 0.0, 0.8000001)


def test_save_keeps_exact_previous_bytes_as_backup(tmp_path: Path) -> None:
    path = tmp_path / "task.json"
    hand_written = json.dumps(full_task(), separators=(",", ":")).encode()
    path.write_bytes(hand_written)
    task = load_task(path)
    task.constraints[0].confidence = 0.5
    save_task(task, path)
    assert (tmp_path / "task.json.bak").read_bytes() == hand_written
    first_save = path.read_bytes()
    task.constraints[0].confidence = 0.25
    save_task(task, path)
    # The first backup (the hand-written original) stays; the next one is numbered.
    assert (tmp_path / "task.json.bak").read_bytes() == hand_written
    assert (tmp_path / "task.json.bak.1").read_bytes() == first_save
    assert load_task(path).constraints[0].confidence == 0.25
    assert sorted(q.name for q in tmp_path.iterdir()) == [
        "task.json",
        "task.json.bak",
        "task.json.bak.1",
    ]


def test_first_save_makes_no_backup(tmp_path: Path) -> None:
    save_task(TaskFile.model_validate(full_task()), tmp_path / "t.json")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.json"]


def test_crash_during_write_leaves_old_file_intact(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "task.json"
    save_task(TaskFile.model_validate(full_task()), path)
    before = path.read_bytes()
    real_replace = os.replace

    def failing_replace(src: Any, dst: Any) -> None:
        if Path(dst) == path:
            raise OSError(28, "No space left on device")
        real_replace(src, dst)

    monkeypatch.setattr(os, "replace", failing_replace)
    task = load_task(path)
    task.objects[0].mesh = "changed.stl"
    with pytest.raises(TaskFileError, match=r"task\.json: cannot write task file"):
        save_task(task, path)
    assert path.read_bytes() == before
    assert (tmp_path / "task.json.bak").read_bytes() == before
    assert not (tmp_path / "task.json.tmp").exists()


def test_invalid_in_memory_task_is_not_written(tmp_path: Path) -> None:
    path = tmp_path / "task.json"
    save_task(TaskFile.model_validate(full_task()), path)
    before = path.read_bytes()
    task = load_task(path)
    task.plan[0].child = "leg9"
    with pytest.raises(TaskFileError, match=r"plan\[0\]\.child: unknown object 'leg9'"):
        save_task(task, path)
    assert path.read_bytes() == before
    assert not (tmp_path / "task.json.bak").exists()


def test_new_fills_provenance_and_hashes_inputs(tmp_path: Path) -> None:
    from thirdhand import __version__

    rec = tmp_path / "demo.parquet"
    rec.write_bytes(b"recording bytes")
    task = TaskFile.new(
        objects=[{"name": "seating"}, {"name": "leg1"}],
        constraints=[{"id": "c1", "parent": "seating", "child": "leg1", "type": "fixed"}],
        plan=[{"parent": "seating", "child": "leg1", "constraint": "c1"}],
        inputs=[rec],
        parameters={"seed": 3},
    )
    prov = task.provenance
    assert prov.thirdhand_version == __version__
    assert prov.created is not None and prov.created == prov.modified
    assert prov.created.utcoffset() is not None
    assert prov.inputs[0].sha256 == hashlib.sha256(b"recording bytes").hexdigest()
    assert prov.parameters == {"seed": 3}
    assert task.schema_ == SCHEMA
    with pytest.raises(TaskFileError, match=r"new task: plan\[0\]\.constraint: unknown"):
        TaskFile.new(
            objects=[{"name": "a"}, {"name": "b"}],
            plan=[{"parent": "a", "child": "b", "constraint": "x"}],
        )


def test_lookups_and_corrections() -> None:
    task = TaskFile.model_validate(full_task())
    assert task.constraint_by_id("tool").child == "screwdriver"
    with pytest.raises(KeyError, match="no constraint with id 'c9'"):
        task.constraint_by_id("c9")
    assert list(task.objects_by_name()) == ["seating", "leg1", "screwdriver"]
    assert task.predecessors() == [[], [0]]
    before = copy.deepcopy(task.provenance.corrections)
    c = task.record_correction(who="bob", field="constraints[0].pos", old=[0, 0, 0], new=[1, 0, 0])
    assert task.provenance.corrections == [*before, c]
    assert task.provenance.modified == c.when


def test_constraint_rows_round_trip() -> None:
    row = [0.1, -0.2, 0.3, 0.0, 0.6, 0.0, 0.8, *([0.0] * 8), -3.1416, 3.1416, 0.0, 0.0]
    c = Constraint.from_row(row, parent="seating", child="leg1", symbol="c2")
    assert (c.id, c.symbol, c.type) == ("c2", "c2", "revolute")
    assert c.free_dofs.ry == (-3.1416, 3.1416)
    assert c.to_row() == row
    short = Constraint.from_row(row[:7], parent="seating", child="leg1", symbol="c3", id="k")
    assert (short.id, short.type) == ("k", "fixed")
    assert short.to_row() == row[:7] + [0.0] * 12
    assert np.array_equal(short.free_dof_array(), np.zeros((6, 2)))


@pytest.mark.parametrize(
    ("row", "expected"),
    [
        ([0.0] * 10, r"expected a row of 19 \(or 7\) numbers, got 10"),
        ([0.0] * 6 + ["1"], r"row\[6\] is '1', expected a number"),
        ([0.0] * 7, "quat: quaternion has zero norm"),
        ([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.5, 0.1, *([0.0] * 10)], "free_dofs: DOF tx: range"),
    ],
)
def test_bad_constraint_rows(row: list[Any], expected: str) -> None:
    with pytest.raises(TaskFileError, match=expected) as info:
        Constraint.from_row(row, parent="a", child="b", symbol="c1")
    assert str(info.value).startswith("constraint 'c1' (a -> b): ")


def test_row_cannot_hold_a_constraint_frame() -> None:
    task = TaskFile.model_validate(full_task())
    with pytest.raises(TaskFileError, match="constraint 'tool': a row cannot hold"):
        task.constraint_by_id("tool").to_row()


@pytest.mark.parametrize(
    ("free", "expected"),
    [
        ([], "fixed"),
        (["tx", "ty", "tz", "rx", "ry", "rz"], "free"),
        (["rz"], "revolute"),
        (["ty"], "prismatic"),
        (["tx", "rx"], "cylindrical"),
        (["tx", "ry"], "free"),
        (["tx", "ty"], "free"),
    ],
)
def test_infer_constraint_type(free: list[str], expected: str) -> None:
    dofs = FreeDofs(**{n: (-1.0, 1.0) for n in free})
    assert dofs.free() == free
    assert infer_constraint_type(dofs) == expected


def test_vocabularies_match_the_core_types() -> None:
    assert CONSTRAINT_TYPES == DEMO_CONSTRAINT_TYPES
    assert OBJECT_KINDS == BODY_KINDS


def test_non_finite_value_is_never_written(tmp_path: Path) -> None:
    # An unknown field is held to the same rule as the known ones ...
    with pytest.raises(ValueError, match=r"future\.scores\[1\]: not a finite number"):
        TaskFile.model_validate({**full_task(), "future": {"scores": [1.0, float("inf")]}})
    # ... and one set after validation is still refused when written.
    task = TaskFile.model_validate(full_task())
    task.future = float("nan")  # type: ignore[attr-defined]
    with pytest.raises(TaskFileError, match="cannot write task: Out of range float"):
        save_task(task, tmp_path / "t.json")
    assert not (tmp_path / "t.json").exists()


finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_subnormal=True)
coordinate = st.floats(min_value=-1e3, max_value=1e3, allow_nan=False, allow_subnormal=True)


@st.composite
def rows(draw: st.DrawFn) -> list[float]:
    pos = [draw(coordinate) for _ in range(3)]
    q = np.array([draw(st.floats(-1.0, 1.0)) for _ in range(4)])
    assume(np.linalg.norm(q) > 1e-3)
    quat = [float(v) for v in q / np.linalg.norm(q)]
    ranges = []
    for _ in range(6):
        lo, hi = sorted((draw(finite), draw(finite)))
        ranges += [lo, hi]
    return pos + quat + ranges


@settings(max_examples=200, deadline=None)
@given(rows())
def test_any_valid_row_round_trips_bit_exactly(row: list[float]) -> None:
    c = Constraint.from_row(row, parent="a", child="b", symbol="s")
    assert c.to_row() == row
    assert parse_task(
        dump_task(TaskFile.new(objects=[{"name": "a"}, {"name": "b"}], constraints=[c]))
    ).constraints == [c]


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=4).filter(
        lambda q: float(np.linalg.norm(q)) > 1e-3
    ),
    st.floats(0.991, 1.009),
)
def test_near_unit_quaternions_are_normalised(q: list[float], norm: float) -> None:
    v = np.asarray(q) / np.linalg.norm(q) * norm
    got = np.asarray(Pose(quat=tuple(v)).quat)
    assert abs(np.linalg.norm(got) - 1.0) <= 1e-6
    assert np.allclose(got, v / np.linalg.norm(v), rtol=0, atol=1e-12)


def test_new_task_owns_copies_of_given_models() -> None:
    c = Constraint(id="c1", parent="a", child="b", type="fixed", note="kept")
    task = TaskFile.new(objects=[{"name": "a"}, {"name": "b"}], constraints=[c])
    task.constraints[0].confidence = 0.5
    assert c.confidence == 1.0
    assert task.constraints[0].model_extra == {"note": "kept"}


def test_pose_matrix() -> None:
    pose = Pose(pos=(1.0, 2.0, 3.0), quat=(0.0, 0.0, np.sin(np.pi / 4), np.cos(np.pi / 4)))
    m = pose.matrix()
    assert np.allclose(m @ [1.0, 0.0, 0.0, 1.0], [1.0, 3.0, 3.0, 1.0])


def test_free_dofs_by_name() -> None:
    import math

    from thirdhand.task.geometry import FreeDofs

    fd = FreeDofs(rx=(-math.pi, math.pi), tz=(0.0, 0.05))
    assert fd["rx"] == (-math.pi, math.pi) and fd["tz"] == (0.0, 0.05) and fd["ty"] == (0.0, 0.0)
    assert fd.ranges()[3] == fd["rx"]
    with pytest.raises(KeyError, match="unknown DOF 'Tx'"):
        fd["Tx"]


# --- thirdhand.task/2: typed stage blocks, the /1 migration ---------------------------------


def _v1(doc: dict[str, Any]) -> dict[str, Any]:
    """The document as thirdhand.task/1 wrote it (schema string, free-form blocks)."""
    old = copy.deepcopy(doc)
    old["schema"] = "thirdhand.task/1"
    return old


def test_a_v1_file_loads_migrated_and_is_written_as_v2(tmp_path: Path) -> None:
    doc = full_task()
    src = write_json(tmp_path / "old.json", _v1(doc))
    task = load_task(src)
    assert task.schema_ == SCHEMA == "thirdhand.task/2"
    assert task.stages.plan is not None and task.stages.plan.n_demos == 2
    assert task.stages.review is not None and task.stages.review.confirmed == {
        "c1": ["constraint", "rz"]
    }
    out = tmp_path / "new.json"
    save_task(task, out)
    # everything else exactly as read: the migration is the schema string
    assert json.loads(out.read_text()) == doc
    assert json.loads(src.read_text())["schema"] == "thirdhand.task/1"  # the input untouched


def test_a_v1_file_with_a_block_that_does_not_fit_names_where(tmp_path: Path) -> None:
    old = _v1(full_task())
    old["stages"]["perception"] = {"pointing": [{"object": "leg1", "t0": 1.0}]}
    path = write_json(tmp_path / "old.json", old)
    with pytest.raises(TaskFileError, match=r"stages\.perception\.pointing\[0\]\.hand: required"):
        load_task(path)


def test_a_v1_dict_is_refused_by_the_model_with_a_hint() -> None:
    with pytest.raises(ValueError, match="load_task and parse_task migrate it"):
        TaskFile.model_validate(_v1(full_task()))


def test_unknown_fields_of_a_known_block_and_unknown_blocks_round_trip(tmp_path: Path) -> None:
    doc = full_task()
    doc["stages"]["plan"]["voted_by"] = {"people": ["ana", "ben"], "weights": [0.5, 0.5]}
    doc["stages"]["future_stage"] = {"a": [1, 2, {"b": None}]}
    task = load_task(write_json(tmp_path / "in.json", doc))
    assert task.stages.plan is not None
    assert task.stages.plan.model_extra == {
        "voted_by": {"people": ["ana", "ben"], "weights": [0.5, 0.5]}
    }
    assert task.stages.other("future_stage") == {"a": [1, 2, {"b": None}]}
    assert task.stages.names() == ["plan", "primitives", "review", "segmentation", "future_stage"]
    out = tmp_path / "out.json"
    save_task(task, out)
    assert json.loads(out.read_text()) == doc


def test_a_block_built_in_code_writes_what_was_set_and_what_differs_from_defaults() -> None:
    from thirdhand.task.stages import PlanBlock, ReviewBlock, Stages

    review = ReviewBlock()
    review.confirmed.setdefault("c1", []).append("rz")  # mutated in place, never assigned
    stages = Stages(plan=PlanBlock(n_demos=1), review=review)
    task = TaskFile.new(stages=stages)
    doc = task.to_json_dict()["stages"]
    assert doc == {"plan": {"n_demos": 1}, "review": {"confirmed": {"c1": ["rz"]}}}
    with pytest.raises(ValueError, match="typed block"):
        stages.set_other("plan", {})


def test_a_stage_that_builds_a_block_with_nan_ends_in_one_line() -> None:
    from thirdhand.task.stages import RewardPlanRecord

    with pytest.raises(TaskFileError) as info:
        RewardPlanRecord(parts=["a", "b"], complete=True, perf=float("nan"), steps=[])
    assert str(info.value) == (
        "RewardPlanRecord: perf: nan is not a finite number (a task file holds no NaN or infinity)"
    )
    # a model built in code keeps pydantic's strictness for nested values
    with pytest.raises(TaskFileError, match=r"RewardBlock: plans\.x\.perf: inf is not a finite"):
        from thirdhand.task.stages import RewardBlock

        RewardBlock(plans={"x": {"parts": [], "complete": True, "perf": float("inf"), "steps": []}})
