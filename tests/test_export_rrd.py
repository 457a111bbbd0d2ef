"""``thirdhand convert REC|TASK out.rrd``: the Rerun recording read back with the SDK."""

from __future__ import annotations

import json
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from cli_helpers import call
from thirdhand import io
from thirdhand.synth import make_scene
from thirdhand.taskfile import TaskFile, save_task

rr = pytest.importorskip("rerun")
from rerun.chunk import RrdReader  # noqa: E402


def _read(path: Path) -> tuple[dict[str, dict[str, int]], dict[str, set[str]]]:
    """Rows per entity per timeline, and the static component columns per entity."""
    rows: dict[str, dict[str, int]] = defaultdict(lambda: defaultdict(int))
    static: dict[str, set[str]] = defaultdict(set)
    for chunk in RrdReader(path).stream():
        names = chunk.to_record_batch().schema.names
        if chunk.is_static:
            static[chunk.entity_path].update(n for n in names if ":" in n)
        for tl in chunk.timeline_names:
            rows[chunk.entity_path][tl] += chunk.num_rows
    return rows, static


def _entity(name: str, root: str = "/world/bodies") -> str:
    return f"{root}/{rr.escape_entity_path_part(name)}"


@pytest.fixture(scope="module")
def scene(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    tmp = tmp_path_factory.mktemp("rrd")
    demo = make_scene("drawer", seed=2, sensor=None)
    # a 0.5 s tracking gap in the first body
    first = demo.body_names[0]
    gap = (demo.t > 1.0) & (demo.t < 1.5)
    v = demo.valid(first) & ~gap
    tracks = {n: (demo.pos(n), demo.quat(n), demo.valid(n)) for n in demo.body_names}
    tracks[first] = (np.where(v[:, None], demo.pos(first), np.nan), demo.quat(first), v)
    demo = demo.replace(tracks=tracks)
    rec = tmp / "drawer.parquet"
    io.save(demo, rec)
    cons = [
        {
            "id": f"c{i}",
            "parent": c.parent,
            "child": c.child,
            "type": c.type,
            "pos": list(c.pos),
            "quat": list(c.quat),
            "free_dofs": {n: list(c.free_dofs[n]) for n in ("tx", "ty", "tz", "rx", "ry", "rz")},
            "time": c.time,
        }
        for i, c in enumerate(demo.labels.constraints)
    ]

    def keyframe(t: float) -> dict[str, dict[str, list[float]]]:
        k = int(np.searchsorted(demo.t, t))
        return {
            n: {"pos": demo.pos(n)[k].tolist(), "quat": demo.quat(n)[k].tolist()}
            for n in demo.bodies_of_kind("part")
        }

    plan = [
        {
            "parent": c["parent"],
            "child": c["child"],
            "constraint": c["id"],
            "time": c["time"],
            "keyframe": keyframe(c["time"]),
        }
        for c in cons
    ]
    objects = [
        {"name": n, "bbox_min": [-0.05, -0.05, -0.01], "bbox_max": [0.05, 0.05, 0.01]}
        for n in demo.bodies_of_kind("part")
    ]
    task = TaskFile.new(objects=objects, constraints=cons, plan=plan, inputs=[rec])
    task_path = tmp / "task.json"
    save_task(task, task_path)
    # a phases file for one pair, and an execution record with its replay
    a, b = demo.labels.interaction_pairs()[0]
    tp = np.arange(0.0, demo.duration, 0.05)
    phases = tmp / "phases.json"
    phases.write_text(
        json.dumps(
            {
                "format": "thirdhand.phases/1",
                "time": tp.tolist(),
                "pairs": [
                    {
                        "a": a,
                        "b": b,
                        "probability": [None] + [0.5] * (tp.size - 1),
                        "label": [0] * tp.size,
                        "intervals": [],
                    }
                ],
            }
        )
    )
    te = np.arange(0.0, 3.0, 0.02)
    execution = tmp / "run.json"
    execution.write_text(
        json.dumps(
            {
                "t": te.tolist(),
                "q": np.stack([np.sin(te + k) for k in range(7)], 1).tolist(),
                "joint_names": [f"panda_joint{k + 1}" for k in range(7)],
            }
        )
    )
    io.save(demo.select([first]).slice(0.0, 2.0), tmp / "run.parquet")
    return {
        "dir": tmp,
        "rec": rec,
        "task": task_path,
        "phases": phases,
        "execution": execution,
        "n_cons": len(cons),
    }


def test_recording_with_task_phases_execution(
    scene: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    out = scene["dir"] / "all.rrd"
    rc, text, err = call(
        capsys,
        "convert",
        str(scene["rec"]),
        str(out),
        "--with",
        str(scene["task"]),
        "--with",
        str(scene["phases"]),
        "--with",
        str(scene["execution"]),
    )
    assert rc == 0, err
    demo = io.load(scene["rec"])
    rows, static = _read(out)
    for name in demo.body_names:
        e = _entity(name)
        # one pose per tracked frame: gaps hold no sample
        assert rows[e]["time"] == int(demo.valid(name).sum())
        assert "Transform3D:translation" not in static[e]
    first = demo.body_names[0]
    assert rows[_entity(first)]["time"] == demo.n_frames - int(
        ((demo.t > 1.0) & (demo.t < 1.5)).sum()
    )
    # paths split at the gap
    assert "LineStrips3D:strips" in static[_entity(first, "/world/paths")]
    for a, b in demo.labels.interaction_pairs():
        e = "/phases/labels/" + rr.escape_entity_path_part(f"{a}--{b}")
        assert rows[e]["time"] == demo.n_frames
    a, b = demo.labels.interaction_pairs()[0]
    seg = "/phases/segmented/" + rr.escape_entity_path_part(f"{a}--{b}")
    n_phase = len(json.loads(scene["phases"].read_text())["time"])
    assert rows[f"{seg}/label"]["time"] == n_phase
    assert rows[f"{seg}/probability"]["time"] == n_phase - 1  # the null is no sample
    n_cons = scene["n_cons"]
    assert rows["/keyframes"]["time"] == n_cons
    for name in demo.bodies_of_kind("part"):  # every step's keyframe pose, both timelines
        e = _entity(name, "/world/keyframes")
        assert rows[e]["time"] == n_cons and rows[e]["plan_step"] == n_cons
        assert "Mesh3D:vertex_positions" in static[f"{e}/shape"]
    cons = [e for e in static if "/constraints/" in e and e.endswith("/frame")]
    assert len(cons) == n_cons
    glyphs = [e for e in static if e.endswith("/free/translation") or e.endswith("/free/rotation")]
    assert glyphs  # the drawer's prismatic DOF at least
    assert any(e.endswith("/free/translation") for e in glyphs)
    meshes = [e for e in static if e.endswith("/mesh")]
    assert len(meshes) == len(demo.bodies_of_kind("part"))
    for k in range(7):
        assert rows[f"/execution/joints/panda_joint{k + 1}"]["execution_time"] == 150
    assert rows[_entity(first, "/execution/bodies")]["execution_time"] > 0
    assert f"{len(demo)} bodies" in text and f"{n_cons} constraints" in text


def test_task_source_finds_its_recording(
    scene: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    out = scene["dir"] / "task.rrd"
    rc, text, err = call(capsys, "convert", str(scene["task"]), str(out))
    assert rc == 0, err
    rows, _ = _read(out)
    demo = io.load(scene["rec"])
    assert all(rows[_entity(n)]["time"] == int(demo.valid(n).sum()) for n in demo.body_names)
    assert "constraints" in text


def test_rrd_in_missing_folder_is_one_error(
    scene: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    target = tmp_path / "no" / "such" / "out.rrd"
    rc, _, err = call(capsys, "convert", str(scene["rec"]), str(target))
    assert rc == 1
    assert err.count("\n") == 1 and "does not exist" in err and "no/such" in err
    assert not (tmp_path / "no").exists()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--with", "x.json"], "--with: only for a .rrd target"),
        (["--with", "x.json", "--with", "y.json"], "--with: only for a .rrd target"),
    ],
)
def test_rrd_options_on_other_targets(
    scene: dict[str, Any],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    args: list[str],
    message: str,
) -> None:
    target = tmp_path / "out.csv"
    rc, _, err = call(capsys, "convert", str(scene["rec"]), str(target), *args)
    assert rc == 1 and message in err and err.count("\n") == 1
    assert not target.exists()


def test_bad_phases_file_one_error_nothing_written(
    scene: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "p.json"
    bad.write_text('{"format": "other"}')
    target = tmp_path / "out.rrd"
    rc, _, err = call(capsys, "convert", str(scene["rec"]), str(target), "--with", str(bad))
    assert rc == 1 and "not a task, phases or run file" in err and err.count("\n") == 1
    assert not target.exists()
    # A phases file by its format key, but malformed: the phases reader's error.
    bad.write_text('{"format": "thirdhand.phases/1"}')
    rc, _, err = call(capsys, "convert", str(scene["rec"]), str(target), "--with", str(bad))
    assert rc == 1 and "'time' list" in err and err.count("\n") == 1
    # Two files of one kind.
    twice = ["--with", str(scene["task"]), "--with", str(scene["task"])]
    rc, _, err = call(capsys, "convert", str(scene["rec"]), str(target), *twice)
    assert rc == 1 and "a second task file" in err and err.count("\n") == 1
    assert not target.exists()


def _column(path: Path, entity: str, component: str) -> np.ndarray:
    """The rows of one temporal component of one entity, in ``execution_time`` order."""
    rows: list[tuple[Any, list[float]]] = []
    for chunk in RrdReader(path).stream():
        if chunk.entity_path != entity or chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        names = batch.schema.names
        if component in names:
            times = batch.column(names.index("execution_time")).to_pylist()
            values = batch.column(names.index(component)).to_pylist()
            rows += [(t, v[0]) for t, v in zip(times, values, strict=True)]
    rows.sort(key=lambda r: r[0])
    return np.array([v for _, v in rows], dtype=np.float64)


def _run_with_robot(folder: Path, *, stored_base: bool) -> tuple[Path, Any, np.ndarray]:
    """An execution record of the Panda at a turned, shifted base (and its replay)."""
    from thirdhand import se3
    from thirdhand.demonstration import BodyInfo, Demonstration
    from thirdhand.execute.record import TOOL_BODY
    from thirdhand.execute.robot import Robot

    base = (np.array([0.4, -0.2, 0.75]), np.array([0.0, 0.0, np.sin(0.35), np.cos(0.35)]))
    arm = Robot.load("panda", base_pose=base)
    t = np.arange(0.0, 2.0, 0.02)
    q = arm.home[None] + 0.3 * np.sin(t[:, None] + np.arange(7))
    doc: dict[str, Any] = {
        "schema": "thirdhand.trajectory/1",
        "robot": "panda",
        "joint_names": list(arm.joint_names),
        "t": t.tolist(),
        "q": q.tolist(),
    }
    if stored_base:
        doc["base_pose"] = {"pos": base[0].tolist(), "quat": base[1].tolist()}
    path = folder / ("stored.json" if stored_base else "derived.json")
    path.write_text(json.dumps(doc))
    tool = arm.tool_transforms(q)
    pos, quat = se3.pose_from_matrix(tool)
    replay = Demonstration(
        t, [BodyInfo(TOOL_BODY, kind="tool")], {TOOL_BODY: pos}, {TOOL_BODY: quat}
    )
    io.save(replay, path.with_suffix(".parquet"))
    return path, arm, q


@pytest.mark.parametrize("stored_base", [True, False])
def test_execution_draws_the_robot_where_it_was(
    scene: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str], stored_base: bool
) -> None:
    """Every collision shape of the arm, at pinocchio's pose of it, the base stored or derived."""
    import pinocchio as pin

    from thirdhand.export.robot_model import robot_shapes

    execution, arm, q = _run_with_robot(tmp_path, stored_base=stored_base)
    out = tmp_path / "robot.rrd"
    rc, text, err = call(capsys, "convert", str(scene["rec"]), str(out), "--with", str(execution))
    assert rc == 0, err
    shapes = robot_shapes(arm)
    assert f"{len(shapes)} robot shapes" in text
    rows, static = _read(out)
    data, gdata = arm.model.createData(), pin.GeometryData(arm.geometry)
    k = 37
    pin.forwardKinematics(arm.model, data, q[k])
    pin.updateGeometryPlacements(arm.model, data, arm.geometry, gdata)
    kinds = {"cylinder": "Cylinders3D", "sphere": "Ellipsoids3D", "box": "Boxes3D"}
    for g, shape in enumerate(shapes):
        e = "/execution/robot/" + rr.escape_entity_path_part(shape.name)
        assert rows[e]["execution_time"] == q.shape[0]
        assert any(c.startswith(kinds.get(shape.kind, "Mesh3D")) for c in static[e])
        logged = _column(out, e, "Transform3D:translation")
        # float32 storage: 1e-6 m on poses within 2 m of the origin
        assert np.abs(logged[k] - gdata.oMg[g].translation).max() < 1e-5


def test_bad_base_pose_is_one_error(
    scene: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    execution, _, _ = _run_with_robot(tmp_path, stored_base=True)
    doc = json.loads(execution.read_text())
    doc["base_pose"]["quat"] = [0.0, 0.0, 0.0, 2.0]
    execution.write_text(json.dumps(doc))
    target = tmp_path / "x.rrd"
    rc, _, err = call(capsys, "convert", str(scene["rec"]), str(target), "--with", str(execution))
    assert rc == 1 and "'base_pose' must be" in err and err.count("\n") == 1
    assert not target.exists()


def test_a_base_that_drove_carries_the_arm_with_it(
    scene: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A live record whose base drove (``base_pos``): at each sample every shape stands where
    pinocchio puts it for the arm loaded with its root there; a ``base_pos`` of the wrong
    length is one error."""
    import pinocchio as pin

    from thirdhand.execute.robot import Robot
    from thirdhand.export.robot_model import robot_shapes

    execution, _, q = _run_with_robot(tmp_path, stored_base=True)
    doc = json.loads(execution.read_text())
    n = len(doc["t"])
    start = np.asarray(doc["base_pose"]["pos"])
    moved = start + np.outer(np.linspace(0.0, 1.0, n), [0.3, -0.2, 0.0])
    doc["base_pos"] = moved.tolist()
    execution.write_text(json.dumps(doc))
    out = tmp_path / "moved.rrd"
    rc, _, err = call(capsys, "convert", str(scene["rec"]), str(out), "--with", str(execution))
    assert rc == 0, err
    for k in (0, 37, n - 1):
        there = Robot.load("panda", base_pose=(moved[k], np.asarray(doc["base_pose"]["quat"])))
        data, gdata = there.model.createData(), pin.GeometryData(there.geometry)
        pin.forwardKinematics(there.model, data, q[k])
        pin.updateGeometryPlacements(there.model, data, there.geometry, gdata)
        for g, shape in enumerate(robot_shapes(there)):
            e = "/execution/robot/" + rr.escape_entity_path_part(shape.name)
            logged = _column(out, e, "Transform3D:translation")
            assert np.abs(logged[k] - gdata.oMg[g].translation).max() < 1e-5
    doc["base_pos"] = doc["base_pos"][:-1]
    execution.write_text(json.dumps(doc))
    target = tmp_path / "short.rrd"
    rc, _, err = call(capsys, "convert", str(scene["rec"]), str(target), "--with", str(execution))
    assert rc == 1 and "'base_pos' must be" in err and err.count("\n") == 1
    assert not target.exists()
