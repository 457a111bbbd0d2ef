"""The main job (``thirdhand demo``): the synthetic chair through every stage."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from thirdhand.cli import main
from thirdhand.task.meshes import MESH_PATH_ENV
from thirdhand.taskfile import load_task

MESHES = Path(__file__).resolve().parents[2] / "shared" / "data" / "3rdhand" / "meshes"


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
    assert all("back" not in s for s in bench["steps"])
    five = reward["plans"]["chair with 5 legs"]
    assert five["complete"] and five["steps"][-1].startswith("action(seating,back")


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
