"""The stage API (``import thirdhand as th``) and the README's notebook example."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

import thirdhand as th

README = Path(__file__).resolve().parents[1] / "README.md"


def _example() -> str:
    text = README.read_text()
    match = re.search(r"<!-- api-example -->\n```python\n(.*?)```", text, re.S)
    assert match, "README has no api-example block"
    return match.group(1)


def test_import_is_light() -> None:
    code = (
        "import sys, thirdhand\n"
        "heavy = ('scipy', 'numba', 'cma', 'pinocchio', 'coal', 'matplotlib', 'pyarrow')\n"
        "print([m for m in heavy if m in sys.modules])\n"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert run.stdout.strip() == "[]", run.stdout + run.stderr


def test_unknown_attribute_is_an_attribute_error() -> None:
    with pytest.raises(AttributeError, match="no attribute 'nonsense'"):
        _ = th.nonsense  # type: ignore[attr-defined]


def test_bad_arguments_are_one_line_errors() -> None:
    with pytest.raises(th.ThirdhandError, match="no detection"):
        th.plan_assembly([])
    with pytest.raises(th.ThirdhandError, match="no task given"):
        th.learn_reward([])
    with pytest.raises(th.ThirdhandError, match="2 constraint lists for 1 recordings"):
        th.fit_primitives([th.synth.make_scene("bench", seed=0, sensor=None)], [(), ()])


def test_execute_rejects_unknown_robot_and_mode() -> None:
    from thirdhand.taskfile import parse_task

    task = parse_task(
        '{"schema": "thirdhand.task/2", "objects": [], "constraints": [], "plan": []}'
    )
    with pytest.raises(th.ThirdhandError, match="robot 'ur5' unknown"):
        th.execute_task(task, robot="ur5")
    with pytest.raises(th.ThirdhandError, match="mode 'live' unknown"):
        th.execute_task(task, mode="live")  # type: ignore[arg-type]


def test_verbs_agree_with_learn_task() -> None:
    demo = th.synth.make_scene("bench", seed=3, sensor=None)
    detection = th.detect_constraints(demo)
    plan = th.plan_assembly([detection])
    learned = th.learn_task([demo], segment=False)
    assert [str(s) for s in plan.steps] == [str(s) for s in learned.learned.plan.steps]
    events = th.learn.learned_events(learned.learned)
    prims = th.fit_primitives([demo], events)
    # learn_task adds each motion's explanation by library skills beside the DMP and ProMP
    assert learned.primitives is not None
    stored = learned.primitives.constraints
    assert all(c.skills for c in stored.values())
    without = {k: c.model_copy(update={"skills": None}) for k, c in stored.items()}
    assert prims.constraints == without and prims.skill_library is None
    # the stage verb is the pipeline's stage: with a library, the very same block
    names = learned.learned.names
    assert th.fit_primitives([demo], events, skills=4, names=names) == learned.primitives
    model = th.learn_reward([plan], seed=0)  # the AssemblyPlan itself, or task files
    assert learned.task.stages.reward is not None
    assert str(model.rcsi.reward) == learned.task.stages.reward.reward_tree
    assert str(th.learn_reward([learned.task], seed=0).rcsi.reward) == str(model.rcsi.reward)


@pytest.mark.slow
def test_readme_example_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    exec(compile(_example(), "README.md api-example", "exec"), {})
    out = capsys.readouterr().out
    assert out.splitlines()[0].startswith("seating ")
    assert "4 of 4 steps done" in out
    assert th.taskfile.load_task(tmp_path / "bench_task.json").stages.reward


def test_no_verb_is_shadowed_by_a_stage_package() -> None:
    import importlib
    import inspect

    for module in th._LAZY_MODULES:
        importlib.import_module(f"thirdhand.{module}")
    verbs = [n for n in th.__all__ if n[0].islower() and not n.startswith("__")]
    assert len(verbs) == 8
    for name in verbs:
        assert inspect.isfunction(getattr(th, name)), name


def test_stages_do_not_import_the_synthetic_world() -> None:
    # Nor the experiments and data sets kept at the edges of the package.
    code = (
        "import sys, thirdhand.task, thirdhand.task.meshes, thirdhand.taskfile\n"
        "import thirdhand.learn.build, thirdhand.segment, thirdhand.constraints\n"
        "import thirdhand.primitives, thirdhand.execute, thirdhand.review\n"
        "import thirdhand.learn.run, thirdhand.learn.stages\n"
        "edges = ('thirdhand.synth', 'research', 'thirdhand.datasets')\n"
        "print([m for m in sys.modules if m.startswith(edges)])\n"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert run.stdout.strip() == "[]", run.stdout + run.stderr
