"""``stages.execution`` of a task file: the robot and assembly spot ``execute`` uses when the
command line and ``--config`` say nothing (an explicit choice wins)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from tests.cli_helpers import call, settings_file
from thirdhand.errors import ThirdhandError
from thirdhand.execute import executor as executor_mod
from thirdhand.execute.executor import task_defaults
from thirdhand.task.stages import ExecutionDefaults


@pytest.fixture(scope="module")
def bench() -> Any:
    from thirdhand.synth import make_scene
    from thirdhand.synth.task import truth_task

    return truth_task(make_scene("bench", seed=0))


def test_explicit_then_the_task_then_panda(bench: Any) -> None:
    assert task_defaults(bench) == ("panda", None)
    task = bench.model_copy(deep=True)
    task.stages.execution = ExecutionDefaults(robot="baxter", assembly_xy=(0.6, -0.1))
    assert task_defaults(task) == ("baxter", (0.6, -0.1))
    assert task_defaults(task, "panda", (0.5, 0.0)) == ("panda", (0.5, 0.0))
    task.stages.execution = ExecutionDefaults(assembly_xy=(0.6, -0.1))
    assert task_defaults(task) == ("panda", (0.6, -0.1))


def _task_file(tmp_path: Path, bench: Any, block: dict[str, Any] | None) -> Path:
    from thirdhand.task.store import dump_task

    doc = json.loads(dump_task(bench))
    if block is not None:
        doc["stages"]["execution"] = block
    path = tmp_path / "task.json"
    path.write_text(json.dumps(doc))
    return path


@pytest.mark.parametrize(
    ("block", "extra", "config", "want"),
    [
        (None, (), {}, ("panda", None)),
        ({"robot": "baxter", "assembly_xy": [0.6, -0.1]}, (), {}, ("baxter", (0.6, -0.1))),
        ({"robot": "baxter"}, ("--robot", "panda"), {"assembly_at": [0.5, 0.1]},
         ("panda", (0.5, 0.1))),
    ],
)  # fmt: skip
def test_execute_reads_the_task_s_execution_defaults(
    capsys, tmp_path, monkeypatch, bench, block, extra, config, want
) -> None:
    seen: list[tuple[str, Any]] = []

    def fake(task: Any, robot_name: str = "panda", **kw: Any) -> None:
        seen.append((robot_name, kw.get("assembly_xy")))
        raise ThirdhandError("stopped before planning")

    monkeypatch.setattr(executor_mod.Executor, "for_task", staticmethod(fake))
    path = _task_file(tmp_path, bench, block)
    args = ["execute", str(path), *extra]
    if config:
        args += ["--config", str(settings_file(tmp_path, "execute", **config))]
    rc, _, err = call(capsys, *args)
    assert rc == 1 and "stopped before planning" in err
    assert seen == [(want[0], None if want[1] is None else tuple(want[1]))]


def test_unknown_robot_and_bad_block_are_one_line(capsys, tmp_path, bench) -> None:
    path = _task_file(tmp_path, bench, None)
    rc, _, err = call(capsys, "execute", str(path), "--robot", "ur5")
    assert rc != 0 and "--robot ur5: unknown" in err and len(err.strip().splitlines()) == 1
    path = _task_file(tmp_path, bench, {"robot": "ur5"})
    rc, _, err = call(capsys, "execute", str(path))
    assert rc != 0 and "Traceback" not in err and "execution" in err
    assert len([ln for ln in err.splitlines() if ln.strip()]) == 1
