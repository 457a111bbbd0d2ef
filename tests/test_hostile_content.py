"""Content checked against what it claims, in the typed models every consumer reads.

A plan step against its constraint and its objects; an empty plan is no success. A
skill library's parameters against what makes them a model; JSON written strictly.
"""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import ValidationError

from cli_helpers import call, settings_file
from test_export_rrd import scene  # noqa: F401 (the fixture)
from thirdhand.errors import TaskFileError
from thirdhand.primitives.checks import PrimitiveError
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


# --- a skill library's parameters ---------------------------------------------------


def _model(k: int = 3, c: int = 2) -> dict[str, Any]:
    """A valid model: entry -> middle -> exit over ``c`` channels at 20 Hz."""
    none = None
    return {
        "channels": ["speed", "logangular", "axial"][:c],
        "rate_hz": 20.0,
        "window": 8,
        "means": [[float(i + j) for j in range(c)] for i in range(k)],
        "covs": [np.diag(np.arange(1.0, c + 1.0)).tolist() for _ in range(k)],
        "duration_log_mean": [1.0, 2.0, 1.5][:k],
        "duration_log_sd": [0.2, 0.3, 0.25][:k],
        "max_duration": 60,
        "log_trans": [[none, 0.0, none], [none, none, 0.0], [none, none, none]],
        "log_init": [0.0, none, none],
        "log_final": [none, none, 0.0],
    }


def _set(key: str, value: Any) -> Any:
    return lambda m: {**m, key: value}


LIBRARY_CASES = [
    ("a negative duration deviation", _set("duration_log_sd", [0.2, -0.3, 0.25]),
     "skills.duration_log_sd[1] is -0.3; a standard deviation is positive"),
    ("a positive log-probability", _set("log_init", [0.5, None, None]),
     "skills.log_init[0] is 0.5 > 0; a log-probability is at most 0"),
    ("a transition row not summing to 1",
     _set("log_trans", [[None, -1.0, None], [None, None, 0.0], [None, None, None]]),
     "skills.log_trans[0]: its probabilities sum to 0.367879, not 1"),
    ("duplicate channels", _set("channels", ["speed", "speed"]),
     "channels: 'speed' is listed twice"),
    ("a 2 MHz rate", _set("rate_hz", 2e6), "rate_hz: expected a rate in (0, 1000] Hz, got 2e+06"),
    ("a billion-sample skill", _set("max_duration", 10**9),
     "skills.max_duration: expected 1 to 72000 samples (at most 3600 s at 20 Hz), got 1000000000"),
    ("a huge log duration", _set("duration_log_mean", [1.0, 50.0, 1.5]),
     "skills.duration_log_mean[1] is 50"),
    ("a NaN mean", _set("means", [[0.0, float("nan")], [1.0, 2.0], [2.0, 3.0]]),
     "skills.means: non-finite value nan"),
    ("a covariance not positive definite", _set("covs", [[[1.0, 2.0], [2.0, 1.0]]] * 3),
     "skills.covs[0] is not positive definite"),
    ("an asymmetric covariance", _set("covs", [[[1.0, 0.5], [0.0, 1.0]]] * 3),
     "skills.covs[0] is not symmetric"),
    ("a huge window", _set("window", 10**9), "window: expected 1 to 10000 samples"),
]  # fmt: skip


@pytest.mark.parametrize(
    ("label", "change", "says"), LIBRARY_CASES, ids=[c[0] for c in LIBRARY_CASES]
)
def test_a_skill_library_that_is_no_model_is_refused(label, change, says) -> None:
    from thirdhand.task.skill_model import skill_model_problem

    assert skill_model_problem(**_model()) is None
    problem = skill_model_problem(**change(_model()))
    assert problem is not None and says in problem and "\n" not in problem, (label, problem)


@settings(max_examples=60, deadline=None)
@given(
    st.integers(1, 5),
    st.integers(1, 3),
    st.floats(0.1, 1000.0),
    st.lists(st.floats(1e-6, 1.0), min_size=25, max_size=25),
    st.sampled_from(["sd", "trans", "init", "rate", "none"]),
)
def test_random_models_pass_and_each_broken_law_is_refused(k, c, rate, weights, broken) -> None:
    from thirdhand.task.skill_model import skill_model_problem

    w = np.asarray(weights).reshape(5, 5)[:k, :k]
    trans = np.log(w / w.sum(axis=1, keepdims=True))
    init = np.log(w[0] / w[0].sum())
    model: dict[str, Any] = {
        "channels": ["speed", "logangular", "axial"][:c],
        "rate_hz": rate,
        "window": 8,
        "means": np.zeros((k, c)).tolist(),
        "covs": np.tile(np.eye(c), (k, 1, 1)).tolist(),
        "duration_log_mean": np.zeros(k).tolist(),
        "duration_log_sd": np.full(k, 0.5).tolist(),
        "max_duration": max(1, int(rate)),
        "log_trans": trans.tolist(),
        "log_init": init.tolist(),
        "log_final": np.zeros(k).tolist(),
    }
    if broken == "sd":
        model["duration_log_sd"] = [-0.5, *model["duration_log_sd"][1:]]
    elif broken == "trans":
        model["log_trans"] = (trans + 0.01).tolist()
    elif broken == "init":
        model["log_init"] = (init - 0.01).tolist()
    elif broken == "rate":
        model["rate_hz"] = 1000.0 + rate * 1e4
    assert (skill_model_problem(**model) is None) == (broken == "none")


def test_a_task_s_skill_library_is_checked_on_load_and_written_without_nan() -> None:
    from thirdhand.primitives.pose_channels import PoseTrack
    from thirdhand.primitives.skill_library import SkillLibrary, SkillParserOptions
    from thirdhand.task.stages import SkillLibraryRecord as Block

    t = np.arange(200) / 50.0
    pos = np.column_stack([np.sin(t), np.cos(2 * t), 0.1 * t])
    quat = np.tile([0.0, 0.0, 0.0, 1.0], (t.size, 1))
    lib = SkillLibrary(SkillParserOptions(n_skills=3)).fit([PoseTrack(t, pos, quat)])
    doc = lib.to_dict()
    text = json.dumps(doc, allow_nan=False)  # impossible moves are null, not NaN
    assert "null" in text
    SkillLibrary.from_dict(json.loads(text))
    Block.model_validate(json.loads(text))
    bad = json.loads(text)
    bad["skills"]["duration_log_sd"][0] = -1.0
    with pytest.raises(PrimitiveError, match=r"duration_log_sd\[0\] is -1.0"):
        SkillLibrary.from_dict(bad)
    with pytest.raises(ValidationError, match=r"duration_log_sd\[0\] is -1.0"):
        Block.model_validate(bad)


def test_json_writers_refuse_nan_in_one_line() -> None:
    from thirdhand.errors import OutputError
    from thirdhand.jsontext import dumps

    assert dumps({"a": [1.0, None]}, what="x.json") == '{"a": [1.0, null]}'
    with pytest.raises(OutputError, match=r"x.json: not written, \$.a\[1\].b = nan"):
        dumps({"a": [1.0, {"b": float("nan")}]}, what="x.json")


def test_every_json_writer_is_strict() -> None:
    """No ``json.dumps`` in the package that could write a NaN literal."""
    import re

    src = Path(__file__).resolve().parents[1] / "src" / "thirdhand"
    loose = []
    for path in src.rglob("*.py"):
        for k, line in enumerate(path.read_text().splitlines(), 1):
            call = re.search(r"json\.dumps?\((.*)", line)
            if call and "allow_nan=False" not in line:
                loose.append(f"{path.relative_to(src)}:{k}: {line.strip()}")
    assert loose == []


# --- primitives library input tracks ------------------------------------------------


def _track_files(tmp_path: Path) -> list[Path]:
    from test_primitives_skill_library import wipe_track

    out = []
    for s in range(2):
        tr = wipe_track(s)[0]
        path = tmp_path / f"T{s}.csv"
        np.savetxt(path, np.column_stack([tr.t, tr.pos, tr.quat]), delimiter=",")
        out.append(path)
    return out


def _library_error(args: list[str]) -> str:
    from typer.testing import CliRunner

    from thirdhand.primitives.cli import app

    res = CliRunner().invoke(app, ["library", *args, "--skills", "3"])
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert res.exit_code == 1 and len(lines) == 1, res.output
    return lines[0]


def test_library_tracks_keep_the_recording_rules(tmp_path: Path) -> None:
    a, b = _track_files(tmp_path)
    arr = np.loadtxt(a, delimiter=",")
    five = tmp_path / "five.csv"
    bad = arr.copy()
    bad[10, 4:8] *= 5.0
    np.savetxt(five, bad, delimiter=",")
    assert "five.csv line" not in (line := _library_error([str(five), str(b)]))
    assert "row 11: quaternion of norm 5, expected a unit one" in line
    mm = tmp_path / "mm.csv"
    scaled = arr.copy()
    scaled[:, 1:4] *= 1000.0
    np.savetxt(mm, scaled, delimiter=",")
    line = _library_error([str(mm), str(b)])
    assert "are these millimetres?" in line  # 300 mm read as metres: beyond 50 m
    # a 3 cm wipe in millimetres (values within 50) beside one in metres: 1000 times larger
    small_m, small_mm = tmp_path / "small_m.csv", tmp_path / "small_mm.csv"
    shrunk = np.loadtxt(b, delimiter=",")
    shrunk[:, 1:4] *= 0.1
    np.savetxt(small_m, shrunk, delimiter=",")
    scaled[:, 1:4] = arr[:, 1:4] * 0.1 * 1000.0
    np.savetxt(small_mm, scaled, delimiter=",")
    line = _library_error([str(small_m), str(small_mm)])
    assert "small_mm.csv spans" in line and "give every track in metres" in line
    line = _library_error([str(a), str(b), str(a)])
    assert f"{a}: given twice (as {a})" in line
    copy_ = tmp_path / "copy.csv"
    copy_.write_bytes(a.read_bytes())
    line = _library_error([str(a), str(copy_)])
    assert "copy.csv: the same samples as" in line and "T0.csv (track 1)" in line


# --- inputs of another task ---------------------------------------------------------


def test_a_scene_file_of_another_object_set_is_refused(tmp_path: Path) -> None:
    from test_scene_file import _scene, _write_stl
    from thirdhand.errors import FormatError
    from thirdhand.task.meshes import box_triangles
    from thirdhand.task.scene_file import scene_geometry

    _write_stl(tmp_path / "box.stl", box_triangles([0, 0, 0], [100, 40, 10]))
    spec = {"mesh": "box.stl", "transformation": [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]]}
    path = _scene(tmp_path / "scene_x.json", {"/toolbox/a": spec, "/toolbox/b": spec})
    assert set(scene_geometry(path, ["/toolbox/a", "rh"], parts=["/toolbox/a"])) == {"/toolbox/a"}
    with pytest.raises(FormatError, match="lists none of the recording's bodies") as err:
        scene_geometry(path, ["/chair/seat", "/chair/leg"])
    assert "\n" not in str(err.value)
    with pytest.raises(FormatError, match="does not list the recording's part '/chair/leg'"):
        scene_geometry(path, ["/toolbox/a", "/chair/leg"], parts=["/toolbox/a", "/chair/leg"])


def _another_task_recording(folder: Path) -> Path:
    import dataclasses

    from thirdhand import io
    from thirdhand.demonstration import Demonstration
    from thirdhand.synth import make_scene

    other = folder / "other.parquet"
    demo = make_scene("drawer", seed=1, sensor=None).slice(0.0, 1.0)
    new = {n: f"/elsewhere/{k}" for k, n in enumerate(demo.body_names)}
    renamed = Demonstration(
        demo.t,
        [dataclasses.replace(b, name=new[b.name]) for b in demo.bodies],
        {new[n]: demo.pos(n) for n in demo.body_names},
        {new[n]: demo.quat(n) for n in demo.body_names},
    )
    io.save(renamed, other)
    return other


def test_rrd_with_files_of_another_task_are_refused(tmp_path: Path, capsys, scene) -> None:  # noqa: F811
    target = tmp_path / "x.rrd"
    phases = json.loads(scene["phases"].read_text())
    phases["pairs"][0]["a"] = "/elsewhere/lid"
    bad_phases = tmp_path / "phases.json"
    bad_phases.write_text(json.dumps(phases))
    run = json.loads(scene["execution"].read_text())
    run["steps"] = [{"index": 0, "parent": "/elsewhere/base", "child": "/elsewhere/lid"}]
    bad_run = tmp_path / "run.json"
    bad_run.write_text(json.dumps(run))
    cases = [
        ([str(scene["rec"]), "--with", str(scene["task"]), "--with", str(bad_phases)],
         "pairs[0].a: '/elsewhere/lid' is a body of neither the task nor its recording"),
        ([str(scene["rec"]), "--with", str(scene["task"]), "--with", str(bad_run)],
         "steps[0].parent: '/elsewhere/base' is not an object of the task"),
        ([str(scene["task"]), "--with", str(_another_task_recording(tmp_path))],
         "shows none of the task's objects"),
    ]  # fmt: skip
    for args, says in cases:
        rc, _, err = call(capsys, "convert", args[0], str(target), *args[1:])
        assert rc == 1 and err.count("\n") == 1 and says in err, err
        assert not target.exists()


def test_review_demo_of_another_task_is_refused(tmp_path: Path, capsys, scene) -> None:  # noqa: F811
    other = _another_task_recording(tmp_path)
    rc, _, err = call(capsys, "review", str(scene["task"]), "--demo", str(other))
    assert rc == 1 and err.count("\n") == 1
    assert f"--demo {other}: shows none of the task's objects" in err


def test_a_primitive_s_scales_are_checked_when_read() -> None:
    from thirdhand.primitives.dmp import DMP
    from thirdhand.primitives.promp import ProMP
    from thirdhand.primitives.serialize import (
        dmp_from_dict,
        dmp_to_dict,
        promp_from_dict,
        promp_to_dict,
    )

    t = np.linspace(0.0, 2.0, 101)
    y = np.column_stack([np.sin(t), np.cos(t)])
    doc = dmp_to_dict(DMP(20).fit(t, y))
    dmp_from_dict(doc)
    for key, value, says in [
        ("tau", -2.0, "tau: expected a positive number, got -2.0"),
        ("dt", 0.0, "dt: expected a positive number, got 0.0"),
        ("tau", 1e9, "expected dt <= tau <= 3600 s"),
        ("goal", [float("nan"), 0.0], "goal: non-finite values"),
    ]:
        with pytest.raises(PrimitiveError, match=None) as err:
            dmp_from_dict({**doc, key: value})
        assert says in str(err.value), str(err.value)
    pdoc = promp_to_dict(ProMP(8).fit([(t, y), (t, y + 0.01 * t[:, None])]))
    promp_from_dict(pdoc)
    for key, value, says in [
        ("noise", -1.0, "noise must be a variance >= 0"),
        ("duration", 1e12, "duration must be in (0, 3600] s"),
    ]:
        with pytest.raises(PrimitiveError, match=None) as err:
            promp_from_dict({**pdoc, key: value})
        assert says in str(err.value), str(err.value)
