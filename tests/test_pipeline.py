"""The main job (``thirdhand demo``): the synthetic chair through every stage."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from thirdhand.cli import main
from thirdhand.taskfile import load_task


@pytest.fixture(scope="module")
def demo_out(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("chair")
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
    assert {"constraints", "plan", "primitives", "reward"} <= set(task.stages)
    # the parts carry their geometry for the GUI and the executor
    legs = [o for o in task.objects if o.name.startswith("leg")]
    assert all(o.mesh == "chair_leg.stl" and o.bbox_max is not None for o in legs)


@pytest.mark.slow
def test_demo_reward_plans_other_sizes(demo_out: Path) -> None:
    reward = load_task(demo_out / "task.json").stages["reward"]
    bench = reward["plans"]["bench"]
    assert bench["complete"] and len(bench["steps"]) == 4
    assert all("back" not in s for s in bench["steps"])
    five = reward["plans"]["chair with 5 legs"]
    assert five["complete"] and five["steps"][-1].startswith("action(seating,back")


@pytest.mark.slow
def test_demo_summary_names_every_stage(demo_out: Path) -> None:
    summary = json.loads((demo_out / "summary.json").read_text())
    stages = [line.split(":")[0] for line in summary["lines"]]
    for stage in ("demonstration", "segmentation", "plan", "primitives", "reward"):
        assert stage in stages
