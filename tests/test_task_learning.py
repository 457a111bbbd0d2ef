"""``thirdhand.learn``: every stage that needs no robot, in memory, into one task."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from thirdhand import io
from thirdhand.demonstration import Labels
from thirdhand.errors import ThirdhandError
from thirdhand.learn.run import learn_task
from thirdhand.learn.stages import learned_events, reward_targets
from thirdhand.synth import make_scene
from thirdhand.taskfile import dump_task, load_task, parse_task


@pytest.fixture(scope="module")
def bench():
    return make_scene("bench", seed=3, sensor=None)


@pytest.fixture(scope="module")
def learned_bench(bench):
    return learn_task([bench], segment=False, seed=0)


def test_every_stage_block_in_one_task(learned_bench) -> None:
    task = learned_bench.task
    assert task.stages.names() == ["constraints", "plan", "primitives", "reward", "grasps"]
    ids = {c.id for c in task.constraints}
    assert len(ids) == 4
    assert task.stages.primitives is not None and set(task.stages.primitives.constraints) == ids
    # the person's hand on every leg when they picked it up, for execution
    assert task.stages.grasps is not None and set(task.stages.grasps.constraints) == ids
    assert learned_bench.skipped == ("segment: skipped by the user",)
    # the in-memory task is a valid task file (what `learn -o` writes is this object)
    assert dump_task(parse_task(dump_task(task))) == dump_task(task)


def test_primitives_use_the_learned_constraints_not_the_labels(bench, learned_bench) -> None:
    events = learned_events(learned_bench.learned)
    assert len(events) == 1
    instances = learned_bench.learned.instances[0]
    assert sorted(e.time for e in events[0]) == sorted(i.start for i in instances)
    assert {(e.parent, e.child) for e in events[0]} == {(i.parent, i.child) for i in instances}
    # without any ground truth in the recording, the same motions are learned
    blind = learn_task([bench.replace(labels=Labels())], segment=False, reward=False)
    assert blind.primitives == learned_bench.primitives
    assert bench.labels.constraints  # the recording's labels are untouched


def test_reward_plans_every_target(learned_bench) -> None:
    plans = learned_bench.reward.plans
    assert set(plans) == {"as demonstrated", "3 leg", "5 leg"}
    assert all(p.complete for p in plans.values())
    assert len(plans["3 leg"].steps) == 3 and len(plans["5 leg"].steps) == 5
    block = learned_bench.task.stages.reward
    assert block is not None
    assert block.plans["5 leg"].parts == ["seating", "leg1", "leg2", "leg3", "leg4", "leg5"]


def test_reward_targets() -> None:
    chair = ["seating", "leg1", "leg2", "leg3", "leg4", "back"]
    assert reward_targets(chair) == {
        "as demonstrated": chair,
        "3 leg": ["seating", "back", "leg1", "leg2", "leg3"],
        "5 leg": ["seating", "back", "leg1", "leg2", "leg3", "leg4", "leg5"],
    }
    # unnumbered parts of distinct names are not varied
    boards = ["/toolbox/side_front", "/toolbox/side_left"]
    assert reward_targets(boards) == {"as demonstrated": boards}
    # digits that are identities (AR tags: a table and its leg), not counts, are not varied
    tags = ["ar_0", "ar_13"]
    assert reward_targets(tags) == {"as demonstrated": tags}
    # a variant of fewer than two parts is not an assembly
    assert reward_targets(["leg1", "leg2"]) == {
        "as demonstrated": ["leg1", "leg2"],
        "3 leg": ["leg1", "leg2", "leg3"],
    }


def test_a_one_step_plan_of_two_objects_has_a_finite_reward() -> None:
    from thirdhand.learn.stages import learn_task_reward, reward_block
    from thirdhand.plan.assembly import AssemblyPlan, PlanAction
    from thirdhand.relational.assembly import plan_with_reward
    from thirdhand.relational.logic import RelationalError

    plan = AssemblyPlan([PlanAction("ar_0", "ar_13", "c1")], "ar_0", 1)
    result = learn_task_reward(plan)
    assert list(result.plans) == ["as demonstrated"]
    got = result.plans["as demonstrated"]
    assert got.steps == ["action(ar_0,ar_13,c)"]
    assert 0.0 < got.perf <= 1.0
    assert reward_block(result).plans["as demonstrated"].perf == got.perf
    # a part set of one object has nothing to assemble: said, not a NaN
    with pytest.raises(RelationalError, match="at least two parts"):
        plan_with_reward(result.model, ["ar_1"])


def test_skipped_stages_say_why(bench) -> None:
    res = learn_task([bench], segment=False, primitives=False, reward=False, grasps=False)
    assert res.task.stages.names() == ["constraints", "plan"]
    assert res.skipped == (
        "segment: skipped by the user",
        "primitives: skipped by the user",
        "reward: skipped by the user",
        "grasps: skipped by the user",
    )
    assert res.primitives is None and res.reward is None


def test_no_demonstration_is_an_error() -> None:
    with pytest.raises(ThirdhandError, match="no demonstration"):
        learn_task([])


def test_progress_names_each_stage(bench) -> None:
    said: list[str] = []
    learn_task([bench], segment=False, reward=False, progress=said.append)
    assert said == ["constraints and plan", "primitives"]


@pytest.mark.slow
def test_cli_learn_on_the_real_toolbox(shared_data: Path, tmp_path: Path, capsys) -> None:
    from cli_helpers import call

    out = tmp_path / "toolbox.json"
    status, text, err = call(
        capsys, "learn", str(shared_data / "3rdhand" / "toolbox_coop_4"), "-o", str(out)
    )
    assert status == 0, err
    task = load_task(out)
    # the scene and the person's grasps when THIRDHAND_MESH_PATH finds the scene file (the
    # boards' boxes place the hand on them; without, their origins are too far from it)
    blocks = set(task.stages.names())
    assert blocks - {"scene", "grasps"} == {"constraints", "plan", "primitives", "reward"}
    assert ("scene" in blocks) == ("grasps" in blocks)
    assert [c.type for c in task.constraints] == ["fixed"]
    assert "reward plan for as demonstrated: 1 steps, complete" in text
    # followed live, the one step is recognised within 1 s of the offline detection
    # (the boards slide 3 cm along each other for 1.5 s after they first
    # meet; the offline run starts where they settle, the live loop 0.4 s + 0.2 s later)
    (inst,) = task.stages.constraints.demos[0].instances
    doc_path = tmp_path / "live.json"
    rec = str(shared_data / "3rdhand" / "toolbox_coop_4")
    status, _, err = call(
        capsys, "live", rec, "--task", str(out), "--speed", "0", "--json", str(doc_path)
    )
    assert status == 0, err
    doc = json.loads(doc_path.read_text())
    (step,) = doc["steps"]
    assert 0.0 <= step["recognised_s"] - inst.start <= 1.0
    assert step["undone_s"] is None and doc["done"] == [step["step"]]
    # the recording itself is never written
    assert not any(p.suffix == ".json" for p in (shared_data / "3rdhand").iterdir())


def test_cli_learn_chair_writes_every_block(tmp_path: Path, capsys) -> None:
    from cli_helpers import call, settings_file

    path = tmp_path / "chair.parquet"
    io.save(make_scene("chair", seed=1, sensor=None), path)
    out = tmp_path / "task.json"
    cfg = ("--config", str(settings_file(tmp_path, "learn", segment=False)))
    status, _, err = call(capsys, "learn", str(path), "-o", str(out), *cfg)
    assert status == 0, err
    task = load_task(out)
    assert set(task.stages.names()) >= {"constraints", "plan", "primitives", "reward"}
    assert len(task.plan) == 5
    legs = [c for c in task.constraints if c.child.startswith("leg")]
    assert all(np.isclose(c.free_dofs.rx[1] - c.free_dofs.rx[0], 2 * np.pi) for c in legs)
    status, _, err = call(capsys, "learn", str(path), "-o", str(out), *cfg)
    assert status == 1 and "exists" in err and err.count("\n") == 1


@pytest.mark.slow
def test_cli_learn_in_two_processes_writes_the_serial_task(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``learn --jobs 2``: each recording segmented and detected in a unit; same task file."""
    import json

    from cli_helpers import call, settings_file
    from thirdhand import io
    from thirdhand.synth import make_scene

    recs = []
    for s in (1, 2):
        recs.append(str(tmp_path / f"d{s}.parquet"))
        io.save(make_scene("drawer", seed=s, sensor=None), recs[-1])
    docs = []
    for extra in ([], ["--jobs", "2"]):
        out = tmp_path / f"task{len(docs)}.json"
        cfg = settings_file(tmp_path, "learn", reward=False)
        rc, _, err = call(capsys, "learn", *recs, "-o", str(out), "--config", str(cfg), *extra)
        assert rc == 0, err
        doc = json.loads(out.read_text())
        doc.pop("provenance")
        docs.append(doc)
    assert docs[0]["constraints"] and docs[0]["plan"]
    assert docs[0] == docs[1]


def test_recorded_grasps_are_those_execute_demo_takes(bench, learned_bench) -> None:
    """``stages.grasps`` holds what ``execute --demo`` finds in the recording's fingers."""
    from thirdhand.execute.grasps import demo_grasps

    task = learned_bench.task
    block = task.stages.grasps
    assert block is not None
    objects = task.objects_by_name()
    for c in task.constraints:
        obj = objects[c.child]
        assert c.time is not None and obj.bbox_min is not None and obj.bbox_max is not None
        box = (np.asarray(obj.bbox_min), np.asarray(obj.bbox_max))
        want = demo_grasps(bench, c.child, c.time, bbox=box)
        got = block.constraints[c.id]
        assert [g.hand for g in got] == [g.label for g in want] and want
        for g, w in zip(got, want, strict=True):
            np.testing.assert_allclose(g.pose.matrix(), w.pose, atol=1e-12)
            assert (g.demo, g.time) == (c.demo, c.time)
