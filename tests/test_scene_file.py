"""3rdHand scene files: reading, the sensor-to-mesh convention decided on real data, learn."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree
from typer.testing import CliRunner

from cli_helpers import settings_file
from thirdhand import io, se3
from thirdhand.errors import FormatError
from thirdhand.io.stl import read_stl
from thirdhand.task.meshes import MESH_PATH_ENV, box_triangles
from thirdhand.task.scene_file import find_scene, read_scene, scene_geometry

BOARDS = ("/toolbox/side_front", "/toolbox/side_left")


def _write_stl(path: Path, tri: np.ndarray) -> None:
    lines = ["solid t"]
    for a, b, c in tri:
        lines += ["facet normal 0 0 0", "outer loop"]
        lines += [f"vertex {x:.9g} {y:.9g} {z:.9g}" for x, y, z in (a, b, c)]
        lines += ["endloop", "endfacet"]
    path.write_text("\n".join([*lines, "endsolid t", ""]), encoding="ascii")


def _scene(path: Path, objects: dict) -> Path:
    path.write_text(json.dumps({"objects": objects}), encoding="utf-8")
    return path


def _surface(tri: np.ndarray, per: int = 12) -> np.ndarray:
    """Vertices and ``per`` random points on every triangle (fixed seed)."""
    w = np.random.default_rng(0).dirichlet([1.0, 1.0, 1.0], size=(tri.shape[0], per))
    return np.vstack([tri.reshape(-1, 3), np.einsum("tkj,tji->tki", w, tri).reshape(-1, 3)])


def test_scene_geometry_inverts_the_transformation(tmp_path: Path) -> None:
    # A 100 x 40 x 10 mm box; the sensor sits at (0.03, -0.01, 0.02) m in the mesh
    # frame, turned 90° about z: the mesh's pose in the body frame is the inverse.
    _write_stl(tmp_path / "box.stl", box_triangles([0, 0, 0], [100, 40, 10]))
    q = se3.quat_from_rotvec([0.0, 0.0, np.pi / 2])
    spec = {"mesh": "box.stl", "transformation": [[0.03, -0.01, 0.02], [float(v) for v in q]]}
    geo = scene_geometry(_scene(tmp_path / "scene_a.json", {"/a": spec}), ["/a", "/b"])
    assert (
        set(geo) == {"/a"}
        and geo["/a"]["scale"] == 1e-3
        and geo["/a"]["mesh"] == str(tmp_path / "box.stl")
    )
    m2b = geo["/a"]["mesh_to_body"]
    # The sensor's own origin, seen from the mesh, maps back onto the body origin.
    back = se3.quat_rotate(m2b.quat, [0.03, -0.01, 0.02]) + np.asarray(m2b.pos)
    assert np.allclose(back, 0.0, atol=1e-12)
    corners = box_triangles([0, 0, 0], [0.1, 0.04, 0.01]).reshape(-1, 3)
    in_body = corners @ se3.matrix_from_quat(m2b.quat).T + np.asarray(m2b.pos)
    assert np.allclose(geo["/a"]["bbox_min"], in_body.min(0), atol=1e-12)
    assert np.allclose(geo["/a"]["bbox_max"], in_body.max(0), atol=1e-12)
    # A translation in the mesh's millimetres (the chair and bench files) is the same pose.
    spec_mm = {"mesh": "box.stl", "transformation": [[30.0, -10.0, 20.0], [float(v) for v in q]]}
    geo_mm = scene_geometry(_scene(tmp_path / "scene_b.json", {"/a": spec_mm}), ["/a"])
    assert np.allclose(geo_mm["/a"]["mesh_to_body"].pos, m2b.pos, atol=1e-12)


@pytest.mark.parametrize(
    ("objects", "where"),
    [
        ({"/a": {"transformation": [[0, 0, 0], [0, 0, 0, 1]]}}, "objects./a.mesh"),
        ({"/a": {"mesh": "box.stl", "transformation": [[0, 0], [0, 0, 0, 1]]}}, "transformation"),
        ({"/a": {"mesh": "box.stl", "transformation": [[0, 0, 0], [0, 0, 0, 2]]}}, "norm 2"),
        ({"/a": {"mesh": "box.stl", "transformation": [[0, 0, "x"], [0, 0, 0, 1]]}}, "finite"),
        ({"/a": {"mesh": "box.stl", "transformation": [[0, 0, 1e999], [0, 0, 0, 1]]}}, "finite"),
        ({}, "objects"),
    ],
)
def test_malformed_scene_files_are_one_error(tmp_path: Path, objects: dict, where: str) -> None:
    with pytest.raises(FormatError, match=where) as err:
        read_scene(_scene(tmp_path / "scene_x.json", objects))
    assert "scene_x.json" in str(err.value) and "\n" not in str(err.value)
    (tmp_path / "scene_y.json").write_text("{", encoding="utf-8")
    with pytest.raises(FormatError, match=r"scene_y\.json.*cannot read"):
        read_scene(tmp_path / "scene_y.json")
    spec = {"mesh": "missing.stl", "transformation": [[0, 0, 0], [0, 0, 0, 1]]}
    with pytest.raises(FormatError, match=r"missing\.stl not found"):
        scene_geometry(_scene(tmp_path / "scene_z.json", {"/a": spec}), ["/a"])


def test_find_scene_along_the_mesh_path(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(MESH_PATH_ENV, raising=False)
    one = {"mesh": "box.stl", "transformation": [[0, 0, 0], [0, 0, 0, 1]]}
    other = {"mesh": "box.stl", "transformation": [[0.1, 0, 0], [0, 0, 0, 1]]}
    _scene(tmp_path / "scene_1.json", {"/a": one, "/b": one})
    assert find_scene(["/a", "/b"], [tmp_path]) == tmp_path / "scene_1.json"
    assert find_scene(["/a", "/c"], [tmp_path]) is None and find_scene([], [tmp_path]) is None
    # A second file that agrees on every part is the same answer; one that disagrees is not.
    _scene(tmp_path / "scene_2.json", {"/a": one, "/b": one, "/c": one})
    assert find_scene(["/a", "/b"], [tmp_path]) == tmp_path / "scene_1.json"
    _scene(tmp_path / "scene_3.json", {"/a": other, "/b": one})
    with pytest.raises(FormatError, match="several scene files"):
        find_scene(["/a", "/b"], [tmp_path])
    monkeypatch.setenv(MESH_PATH_ENV, str(tmp_path))
    assert find_scene(["/c"]) == tmp_path / "scene_2.json"


def test_real_toolbox_boards_touch_once_attached(shared_data: Path) -> None:
    """The convention of the module notes, on the real recording: the screwed boards touch."""
    folder = shared_data / "3rdhand"
    demo = io.load(folder / "toolbox_coop_4")
    scene = folder / "meshes" / "scene_toolbox_coop.json"
    geo = scene_geometry(scene, list(BOARDS))
    raw = read_scene(scene)
    tracks = [demo.track(n) for n in BOARDS]
    both = np.flatnonzero(tracks[0].valid & tracks[1].valid)
    attached = both[demo.t[both] > demo.t[both[-1]] - 35.0][::60]
    assert len(attached) >= 40
    points = {}
    for n in BOARDS:
        tri = read_stl(raw[n].mesh) * geo[n]["scale"]
        points[n] = _surface(tri)

    def gaps(mesh_to_body: dict[str, tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
        out = []
        for k in attached:
            world = []
            for n, tr in zip(BOARDS, tracks, strict=True):
                p, q = mesh_to_body[n]
                body = points[n] @ se3.matrix_from_quat(q).T + p
                world.append(body @ se3.matrix_from_quat(tr.quat[k]).T + tr.pos[k])
            out.append(cKDTree(world[1]).query(world[0])[0].min())
        return np.asarray(out)

    chosen = gaps(
        {n: (np.asarray(geo[n]["mesh_to_body"].pos), geo[n]["mesh_to_body"].quat) for n in BOARDS}
    )
    as_given = gaps({n: raw[n].body_to_mesh for n in BOARDS})
    # Touching: the surfaces meet to within the sampling of the mesh (a few mm between
    # points) and the tracker's noise; the transformation as given leaves a gap.
    assert np.median(chosen) < 1.5e-3
    assert np.median(as_given) > 4e-3


@pytest.mark.slow
def test_real_toolbox_learned_with_its_scene_executes(
    shared_data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from thirdhand.cli import app

    folder = shared_data / "3rdhand"
    task = tmp_path / "task.json"
    runner = CliRunner()
    r = runner.invoke(
        app,
        [
            "learn",
            str(folder / "toolbox_coop_4"),
            "-o",
            str(task),
            "--config",
            str(settings_file(tmp_path, "learn", reward=False)),
            "--scene",
            str(folder / "meshes" / "scene_toolbox_coop.json"),
        ],
    )
    assert r.exit_code == 0, r.output
    doc = json.loads(task.read_text())
    objects = {o["name"]: o for o in doc["objects"]}
    # each mesh recorded by its path from the task file, found from there alone
    meshes = [Path(objects[n]["mesh"]) for n in BOARDS]
    assert [m.name for m in meshes] == ["ToolboxPart2.stl", "ToolboxPart3.stl"]
    assert all(not m.is_absolute() and (tmp_path / m).is_file() for m in meshes)
    assert (tmp_path / doc["stages"]["scene"]["file"]).resolve() == (
        folder / "meshes" / "scene_toolbox_coop.json"
    ).resolve()
    # the person's hand on the board when they picked it up, recorded for execution
    (cid,) = doc["stages"]["grasps"]["constraints"]
    assert [g["hand"] for g in doc["stages"]["grasps"]["constraints"][cid]]
    # no --meshes, no --demo, no THIRDHAND_MESH_PATH: the person's grasp and the real meshes
    monkeypatch.delenv(MESH_PATH_ENV, raising=False)
    r = runner.invoke(app, ["execute", str(task), "--record", str(tmp_path / "run")])
    assert r.exit_code == 0, r.output
    assert "mesh files not found" not in r.output
    record = json.loads((tmp_path / "run.json").read_text())
    assert record["success"] and record["n_collisions"] == 0
    # held where the person held it: their grasp, squared to the board's faces for a
    # parallel gripper (and turned about the board's axis to the way it lies now)
    assert [s["grasp_source"] for s in record["steps"]] == ["demo"]
    assert "/square" in record["steps"][0]["grasp"]
    # exactly what --demo RECORDING does (its fingers' grasps are the recorded ones)
    r = runner.invoke(
        app,
        ["execute", str(task), "--demo", str(folder / "toolbox_coop_4"), "--record",
         str(tmp_path / "demo")],
    )  # fmt: skip
    assert r.exit_code == 0, r.output
    again = json.loads((tmp_path / "demo.json").read_text())

    def same(steps: list[dict]) -> list[dict]:
        return [{k: v for k, v in s.items() if k != "planning_time_s"} for s in steps]

    assert same(again["steps"]) == same(record["steps"])
    # a task without recorded grasps (a thirdhand.task/1 file): a grasp from the board's
    # shape; side_left stands on the table on the edge that is down at its goal
    old = dict(doc, schema="thirdhand.task/1")
    old["stages"] = {k: v for k, v in doc["stages"].items() if k != "grasps"}
    (tmp_path / "old.json").write_text(json.dumps(old))
    r = runner.invoke(
        app, ["execute", str(tmp_path / "old.json"), "--record", str(tmp_path / "shape")]
    )
    assert r.exit_code == 0, r.output
    record = json.loads((tmp_path / "shape.json").read_text())
    assert record["success"] and record["n_collisions"] == 0
    assert [s["grasp_source"] for s in record["steps"]] == ["shape"]
    r = runner.invoke(
        app,
        [
            "learn",
            str(folder / "toolbox_coop_4"),
            "-o",
            str(tmp_path / "x.json"),
            "--scene",
            str(tmp_path / "missing.json"),
        ],
    )
    assert r.exit_code != 0 and "--scene" in str(r.exception)


def test_real_bench_scene_finds_its_renamed_seat_mesh(shared_data: Path) -> None:
    # scene_bench.json names bench_seating.stl; the file is bench_sitting.stl.
    scene = shared_data / "3rdhand" / "meshes" / "scene_bench.json"
    assert not (scene.parent / "bench_seating.stl").exists()
    geo = scene_geometry(scene, ["/bench/seating", "/bench/leg1"])
    assert Path(geo["/bench/seating"]["mesh"]).name == "bench_sitting.stl"
    # millimetre translations (157.5) read in the mesh's units: the seat's box is
    # 40 x 300 x 300 mm wherever it sits, and lies within 0.5 m of its sensor
    lo, hi = (
        np.asarray(geo["/bench/seating"]["bbox_min"]),
        np.asarray(geo["/bench/seating"]["bbox_max"]),
    )
    assert np.allclose(np.sort(hi - lo), [0.04, 0.3, 0.3], atol=1e-6)
    assert np.abs(np.concatenate([lo, hi])).max() < 0.5


def test_learned_from_finds_the_first_readable_recording(tmp_path: Path) -> None:
    from thirdhand.execute.cli import learned_from
    from thirdhand.synth import make_scene
    from thirdhand.task.model import InputFile, TaskFile

    rec = tmp_path / "rec.parquet"
    io.save(make_scene("drawer", seed=0, sensor=None).slice(0.0, 1.0), rec)
    scene = tmp_path / "scene.json"
    scene.write_text("{}")
    task = tmp_path / "task.json"
    inputs = [InputFile(path=str(tmp_path / "gone.parquet"), sha256="0" * 64)]
    inputs.append(InputFile(path=str(scene), sha256="0" * 64))
    assert learned_from(TaskFile.new(inputs=inputs), task) is None
    # a relative path is found beside the task file, if it holds what was recorded
    changed = [*inputs, InputFile(path="rec.parquet", sha256="0" * 64)]
    assert learned_from(TaskFile.new(inputs=changed), task) is None
    inputs.append(InputFile.from_path(rec).model_copy(update={"path": "rec.parquet"}))
    assert learned_from(TaskFile.new(inputs=inputs), task) == tmp_path / "rec.parquet"
    # not from the current folder: only where the task says
    other = tmp_path / "elsewhere"
    other.mkdir()
    assert learned_from(TaskFile.new(inputs=inputs), other / "task.json") is None
