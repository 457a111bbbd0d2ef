"""The main job (``thirdhand demo``): the synthetic chair through every stage."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from conftest import DATA
from thirdhand.cli import main
from thirdhand.task.meshes import MESH_PATH_ENV, missing_meshes, resolve_mesh
from thirdhand.taskfile import load_task

MESHES = DATA / "3rdhand" / "meshes"


@pytest.fixture(scope="module")
def demo_out(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The main job's outputs, with the real part meshes when ``../shared`` has them."""
    out = tmp_path_factory.mktemp("chair")
    with pytest.MonkeyPatch.context() as mp:
        if MESHES.is_dir():
            mp.setenv(MESH_PATH_ENV, str(MESHES))
        try:
            status = main(["demo", "-o", str(out)])
        except SystemExit as exc:  # typer's standalone mode exits with the status
            status = int(exc.code or 0)
    assert status == 0
    return out


@pytest.mark.slow
def test_demo_writes_every_stage(demo_out: Path) -> None:
    for name in ("demonstration.parquet", "phases.json", "task.json", "summary.json"):
        assert (demo_out / name).is_file(), name
    assert (demo_out / "report" / "index.html").is_file()
    task = load_task(demo_out / "task.json")
    assert len(task.plan) == 5 and len(task.constraints) == 5
    assert sorted(c.type for c in task.constraints) == ["fixed"] + ["revolute"] * 4
    assert {"constraints", "plan", "primitives", "reward"} <= set(task.stages.names())
    # the parts carry their geometry for the GUI and the executor
    legs = [o for o in task.objects if o.name.startswith("leg")]
    assert all(o.mesh is not None and o.bbox_max is not None for o in legs)
    assert all(Path(o.mesh).name == "chair_leg.stl" for o in legs if o.mesh is not None)


@pytest.mark.slow
def test_demo_reward_plans_other_sizes(demo_out: Path) -> None:
    reward = load_task(demo_out / "task.json").stages.reward
    assert reward is not None
    bench = reward.plans["bench"]
    assert bench.complete and len(bench.steps) == 4
    assert all("back" not in s for s in bench.steps)
    five = reward.plans["chair with 5 legs"]
    assert five.complete and five.steps[-1].startswith("action(seating,back")


@pytest.mark.slow
def test_demo_summary_names_every_stage(demo_out: Path) -> None:
    summary = json.loads((demo_out / "summary.json").read_text())
    stages = [line.split(":")[0] for line in summary["lines"]]
    for stage in ("demonstration", "segmentation", "plan", "primitives", "reward", "execution"):
        assert stage in stages


@pytest.mark.slow
def test_demo_executes_the_learned_plan(demo_out: Path) -> None:
    from thirdhand import io

    summary = json.loads((demo_out / "summary.json").read_text())["execution"]
    assert summary["steps"] == 5 and summary["collisions"] == 0
    assert summary["succeeded"] == 5
    replay = io.load(demo_out / "execution.parquet")
    assert {"seating", "leg1", "back"} <= set(replay.body_names)


@pytest.mark.slow
def test_demo_task_finds_its_meshes_with_no_flag_and_no_environment(
    demo_out: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    if not MESHES.is_dir():
        pytest.skip(f"part meshes not found at {MESHES}")
    monkeypatch.delenv(MESH_PATH_ENV, raising=False)
    monkeypatch.chdir(demo_out.parent)  # wherever the user stands
    path = demo_out / "task.json"
    task = load_task(path)
    # recorded relative to the task file, found from there alone (review and execute
    # both look meshes up through resolve_mesh)
    assert missing_meshes(task, path) == {}
    parts = [o for o in task.objects if o.kind == "part"]
    assert len(parts) == 6 and all(o.mesh and not Path(o.mesh).is_absolute() for o in parts)
    for o in parts:
        found = resolve_mesh(o, path)
        assert found is not None and found.resolve() == (MESHES / Path(found).name).resolve()
    # the demonstration's grasps are in the task: execute needs no --demo either
    assert task.stages.grasps is not None
    assert set(task.stages.grasps.constraints) == {c.id for c in task.constraints}
    run = demo_out / "noflag"
    try:
        status = main(["execute", str(path), "--record", str(run)])
    except SystemExit as exc:
        status = int(exc.code or 0)
    out = capsys.readouterr().out
    assert status == 0, out
    assert "mesh files not found" not in out
    record = json.loads(run.with_suffix(".json").read_text())
    assert record["success"] and record["n_collisions"] == 0
    assert "demo" in {s["grasp_source"] for s in record["steps"]}


def test_a_missing_recorded_mesh_is_a_clear_note(tmp_path: Path) -> None:
    from thirdhand.task.meshes import missing_mesh_note
    from thirdhand.taskfile import TaskFile

    task = TaskFile.new(
        objects=[
            {"name": "leg1", "mesh": "../meshes/chair_leg.stl", "scale": 0.001},
            {"name": "seat"},
        ]
    )
    note = missing_mesh_note(task, tmp_path / "task.json")
    assert note is not None and "\n" not in note
    assert "leg1 (../meshes/chair_leg.stl)" in note and "seat" not in note
    assert f"beside {tmp_path / 'task.json'}" in note and MESH_PATH_ENV in note
