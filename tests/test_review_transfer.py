"""Transfer of a task onto another object set, and the scripted user's correction counts."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from thirdhand.review.edits import apply_edit
from thirdhand.review.transfer import (
    TransferError,
    _relink,
    load_target,
    match_objects,
    transfer,
)
from thirdhand.synth import make_scene
from thirdhand.synth.task import truth_task
from thirdhand.taskfile import TaskFile, load_task, save_task

MESHES = Path(__file__).resolve().parents[2] / "shared" / "data" / "3rdhand" / "meshes"


@pytest.fixture(scope="module")
def chair() -> TaskFile:
    return truth_task(make_scene("chair", seed=0, sensor=None))


@pytest.fixture(scope="module")
def bench() -> TaskFile:
    return truth_task(make_scene("bench", seed=0, sensor=None))


def test_match_objects() -> None:
    got = match_objects(
        ["seating", "leg1", "leg2", "back", "leg3"],
        ["/bench/leg2", "/bench/seat", "/bench/leg1", "/bench/leg3", "/bench/leg4"],
    )
    assert got == {
        "seating": "/bench/seat",
        "leg1": "/bench/leg1",
        "leg2": "/bench/leg2",
        "leg3": "/bench/leg3",
    }
    # Same role, other numbering: paired in index order.
    assert match_objects(["leg1", "leg2"], ["leg_a", "leg7", "leg5"]) == {
        "leg1": "leg5",
        "leg2": "leg7",
    }


def test_relink_through_dropped_steps() -> None:
    # Chain 0 <- 1 <- 2 <- 3, step 2 dropped: 3 follows 1.
    assert _relink([[], [0], [1], [2]], [0, 1, 3]) == [[], [0], [1]]
    # Diamond: 3 after 1 and 2, both after 0; drop 1.
    assert _relink([[], [0], [0], [1, 2]], [0, 2, 3]) == [[], [0], [1]]


def test_chair_to_bench(chair: TaskFile) -> None:
    result = transfer(chair, "bench")
    task = result.task
    parts = {o.name for o in task.objects if o.kind == "part"}
    assert parts == {"seating", "leg1", "leg2", "leg3", "leg4"}
    assert any("back" in n and "dropped" in n for n in result.notes)
    assert {c.child for c in task.constraints} == {"leg1", "leg2", "leg3", "leg4"}
    assert [s.child for s in task.plan] == [s.child for s in chair.plan if s.child != "back"]
    # Bench seat 0.3 x 0.04 x 0.3 m, chair seat 0.3 x 0.02 x 0.3 m: y doubled about the centre.
    for c in task.constraints:
        old = chair.constraint_by_id(c.id)
        assert c.pos == pytest.approx((old.pos[0], 2 * old.pos[1], old.pos[2]), abs=1e-12)
        assert c.quat == old.quat and c.free_dofs == old.free_dofs and c.type == old.type
        assert c.confidence == pytest.approx(old.confidence / 2)
    seat = task.objects_by_name()["seating"]
    assert seat.mesh == "bench_sitting.stl" and seat.bbox_max == (0.15, 0.02, 0.15)
    assert task.stages.transfer is not None and task.stages.transfer.to == "bench"
    # A valid task file that round-trips.
    assert "back" not in {n for s in task.plan for n in s.keyframe}


def test_transfer_keeps_partial_order(chair: TaskFile) -> None:
    po = chair.model_copy(deep=True)
    for s, after in zip(po.plan, [[], [0], [1], [2], [3]], strict=True):
        s.after = after
    moved = apply_edit(TaskFile.model_validate(po.model_dump(by_alias=True)), _move_back_first())
    # back first, then the legs in a chain: dropping the back re-links leg2 to nothing.
    out = transfer(moved, "bench").task
    assert [s.after for s in out.plan] == [[], [0], [1], [2]]


def _move_back_first():  # type: ignore[no-untyped-def]
    from thirdhand.review.edits import MoveStep

    return MoveStep(4, 0)


def test_transfer_from_3rdhand_meshes(chair: TaskFile, bench: TaskFile) -> None:
    if not MESHES.is_dir():
        pytest.skip(f"3rdHand meshes not found at {MESHES}")
    by_scene = transfer(chair, "bench").task
    by_mesh = transfer(chair, MESHES / "scene_bench.json").task
    for a, b in zip(by_scene.constraints, by_mesh.constraints, strict=True):
        assert np.allclose(a.pos, b.pos, atol=1e-6)
    # The mesh box lands on the object's box in the body frame (body axes from the chair's).
    from thirdhand.io.stl import read_stl
    from thirdhand.se3 import quat_rotate

    for obj in by_mesh.objects:
        if obj.kind != "part":
            continue
        tri = read_stl(MESHES / str(obj.mesh)).reshape(-1, 3) * 1e-3
        assert obj.mesh_to_body is not None and obj.bbox_min is not None
        body = quat_rotate(obj.mesh_to_body.quat, tri) + np.asarray(obj.mesh_to_body.pos)
        assert np.allclose(body.min(axis=0), obj.bbox_min, atol=1e-6)
        assert np.allclose(body.max(axis=0), obj.bbox_max, atol=1e-6)
        truth = bench.objects_by_name()[obj.name]
        assert truth.bbox_min is not None and truth.bbox_max is not None
        assert np.allclose(
            np.subtract(obj.bbox_max, obj.bbox_min),
            np.subtract(truth.bbox_max, truth.bbox_min),
            atol=2e-3,
        )


def test_transfer_from_mesh_folder(chair: TaskFile, tmp_path: Path) -> None:
    if not MESHES.is_dir():
        pytest.skip(f"3rdHand meshes not found at {MESHES}")
    shutil.copy(MESHES / "bench_sitting.stl", tmp_path / "seat.stl")
    for k in (1, 2, 3):
        shutil.copy(MESHES / "bench_leg.stl", tmp_path / f"leg{k}.stl")
    result = transfer(chair, tmp_path)
    assert {c.child for c in result.task.constraints} == {"leg1", "leg2", "leg3"}
    assert result.mapping["seating"] == "seat"
    assert any("leg4" in n for n in result.notes)


def test_transfer_errors(chair: TaskFile, tmp_path: Path) -> None:
    with pytest.raises(TransferError, match="not a scene name"):
        load_target("no-such-scene")
    with pytest.raises(TransferError, match="no scene_"):
        load_target(tmp_path)
    (tmp_path / "scene_a.json").write_text('{"objects": {}}')
    (tmp_path / "scene_b.json").write_text("{}")
    with pytest.raises(TransferError, match="several scene files"):
        load_target(tmp_path)
    with pytest.raises(TransferError, match="expected"):
        load_target(tmp_path / "scene_a.json")
    (tmp_path / "scene_b.json").write_text('{"objects": {"/x/seat": {"mesh": "nope.stl"}}}')
    with pytest.raises(TransferError, match="not found"):
        load_target(tmp_path / "scene_b.json")
    from thirdhand.review.transfer import TargetSet, transfer_task
    from thirdhand.taskfile import TaskObject

    with pytest.raises(TransferError, match="no constraint"):
        transfer_task(chair, TargetSet("lid", [TaskObject(name="lid"), TaskObject(name="box")]))


def test_transfer_command(chair: TaskFile, tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from thirdhand.cli import app

    def run(*args: str) -> tuple[int, str, str]:
        r = CliRunner().invoke(app, ["transfer", *args])
        return r.exit_code, r.stdout, r.stderr

    src, dst = tmp_path / "chair.json", tmp_path / "bench.json"
    save_task(chair, src)
    code, out, _ = run(str(src), "--to", "bench", "-o", str(dst))
    assert code == 0 and "back: no counterpart" in out
    assert len(load_task(dst).constraints) == 4
    code, _, err = run(str(src), "--to", "bench", "-o", str(dst))
    assert code == 1 and "exists" in err
    code, _, _ = run(str(src), "--to", "bench", "-o", str(dst), "--force")
    assert code == 0 and (tmp_path / "bench.json.bak").is_file()
    code, _, err = run(str(src), "--to", "sofa", "-o", str(tmp_path / "x.json"))
    assert code == 1 and "not a scene name" in err
