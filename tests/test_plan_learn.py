"""Symbols, the assembly plan, ``learn`` and its task file, the CLI."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from cli_helpers import settings_file
from thirdhand import io
from thirdhand.errors import OptionError
from thirdhand.learn.figures import plan_figures
from thirdhand.learn.run import learn_task
from thirdhand.plan.assembly import plan_from_demos, plan_success, truth_slot
from thirdhand.synth import SensorModel, make_scene
from thirdhand.taskfile import dump_task, load_task, parse_task


def _bijection(pairs: list[tuple[str, str]]) -> bool:
    fwd = dict(pairs)
    return len(set(fwd.values())) == len(fwd) and all(fwd[a] == b for a, b in pairs)


def test_noise_free_symbols_order_and_plan() -> None:
    demos = [make_scene("chair", seed=s, sensor=None) for s in (0, 1)]
    res = learn_task(demos, segment=False, primitives=False, reward=False, grasps=False).learned
    assert len(res.symbols) == 5
    # Our symbols name the same slots as the truth's, whichever leg went where.
    pairs = [
        (i.symbol, ev.symbol)
        for det, d in zip(res.detections, demos, strict=True)
        for i, ev in zip(det.instances, d.labels.constraints, strict=True)
    ]
    assert _bijection(pairs)  # type: ignore[arg-type]
    assert plan_success(res.plan, res.symbols, demos[0].labels.constraints)
    # Legs went in different orders: some leg steps are interchangeable; the back is last.
    assert res.plan.steps[-1].child == "back"
    assert res.plan.interchangeable()
    traj = res.plan.relational_trajectory()
    assert traj[0] == frozenset() and len(traj[-1]) == 5
    one = learn_task(demos[:1], segment=False, primitives=False, reward=False, grasps=False).learned
    order = [(s.parent, s.child) for s in one.plan.steps]
    assert order == [(c.parent, c.child) for c in demos[0].labels.constraints]
    for sym in one.symbols:
        assert truth_slot(sym, demos[0].labels.constraints) is not None


def test_plan_fails_when_a_slot_is_used_twice() -> None:
    demo = make_scene("bench", seed=0, sensor=None)
    res = learn_task([demo], segment=False, primitives=False, reward=False, grasps=False).learned
    assert plan_success(res.plan, res.symbols, demo.labels.constraints)
    res.plan.steps[1].symbol = res.plan.steps[0].symbol
    assert not plan_success(res.plan, res.symbols, demo.labels.constraints)


def test_a_recording_without_constraints_does_not_vote() -> None:
    demos = [make_scene("chair", seed=s, sensor=None) for s in (0, 1)]
    res = learn_task(demos, segment=False, primitives=False, reward=False, grasps=False).learned
    full, other = res.instances
    truth = demos[0].labels.constraints
    # An excerpt that shows no constraint: before, every slot was seen in 1 of 2
    # recordings and the plan was empty; now the excerpt does not vote.
    for insts in ([full, []], [[], full]):
        plan = plan_from_demos(insts, res.symbols)
        assert len(plan.steps) == 5 and plan.voters == 1 and not plan.left_out
        assert plan.silent == [insts.index([])]
        assert plan_success(plan, res.symbols, truth)
    # A recording cut after its first two attachments does vote: the three slots it
    # lacks are seen in 1 of 2 and left out (and reported) unless min_support is 0.
    cut = sorted(other, key=lambda i: i.start)[:2]
    plan = plan_from_demos([full, cut], res.symbols)
    assert len(plan.steps) == 2 and plan.silent == []
    assert sorted(plan.left_out.values()) == [1, 1, 1]
    assert {s.symbol for s in plan.steps}.isdisjoint(plan.left_out)
    every = plan_from_demos([full, cut], res.symbols, min_support=0.0)
    assert len(every.steps) == 5 and not every.left_out
    assert plan_success(every, res.symbols, truth)
    # The strict majority is unchanged: 2 of 4 is not more than half.
    half = plan_from_demos([full, full, cut, cut], res.symbols)
    assert len(half.steps) == 2 and sorted(half.left_out.values()) == [2, 2, 2]
    for bad in (1.0, -0.1, float("nan")):
        with pytest.raises(OptionError, match="min_support"):
            plan_from_demos([full], res.symbols, min_support=bad)


def test_real_toolbox_with_its_excerpt_keeps_the_plan(shared_data: Path, tmp_path: Path) -> None:
    from thirdhand.cli import app

    folder = shared_data / "3rdhand"
    whole, excerpt = io.load(folder / "toolbox_coop_4"), io.load(folder / "toolbox_coop_4_excerpt")
    alone = learn_task([whole], segment=False, primitives=False, reward=False, grasps=False).task
    assert len(alone.plan) == 1
    for demos, names in (
        ([whole, excerpt], ["whole", "excerpt"]),
        ([excerpt, whole], ["excerpt", "whole"]),
    ):
        both = learn_task(
            demos, names=names, segment=False, primitives=False, reward=False, grasps=False
        )
        res, task = both.learned, both.task
        assert [(s.parent, s.child) for s in task.plan] == [(s.parent, s.child) for s in alone.plan]
        assert task.stages.plan is not None
        assert task.stages.plan.silent_demos == ["excerpt"]
        assert task.stages.plan.support == [1]
        # The keyframe comes from the recording that has the step, whichever is first.
        assert task.plan[0].keyframe == alone.plan[0].keyframe != {}
    from thirdhand.learn.report import write_report

    page = write_report(res, tmp_path / "report").read_text(encoding="utf-8")
    assert "excerpt: no constraint found; it does not vote" in page
    r = CliRunner().invoke(
        app,
        [
            "learn",
            str(folder / "toolbox_coop_4_excerpt"),
            "-o",
            str(tmp_path / "t.json"),
            "--config",
            str(settings_file(tmp_path, "learn", min_support=1.0)),
        ],
    )
    assert r.exit_code != 0 and "[learn] min_support" in str(r.exception)
    assert not (tmp_path / "t.json").exists()


def test_task_file_validates_and_round_trips(tmp_path: Path) -> None:
    demo = make_scene("chair", seed=2, sensor=SensorModel())
    from thirdhand.learn.report import write_report
    from thirdhand.taskfile import save_task

    both = learn_task([demo], primitives=False, reward=False, grasps=False)
    result, task = both.learned, both.task
    save_task(task, tmp_path / "task.json")
    write_report(result, tmp_path / "report")
    block, line = plan_figures(result)
    loaded = load_task(tmp_path / "task.json")
    assert dump_task(parse_task(dump_task(loaded))) == dump_task(loaded)
    assert len(task.constraints) == 5
    by_child = {c.child: c for c in loaded.constraints}
    for leg in ("leg1", "leg2", "leg3", "leg4"):
        assert by_child[leg].free_dofs.free() == ["rx"]
        assert by_child[leg].free_dofs.rx == pytest.approx((-np.pi, np.pi))
    assert by_child["back"].free_dofs.free() == []
    assert [s.constraint for s in loaded.plan] == [c.id for c in loaded.constraints]
    assert all(s.keyframe for s in loaded.plan)
    assert (tmp_path / "report" / "index.html").read_text().count("data:image/png") >= 2
    assert block["pos_error_cm"] < 0.3
    assert line.startswith("plan: 5 steps")


def test_cli_learn(tmp_path: Path) -> None:
    import typer

    from thirdhand.learn.cli import learn_command

    demo = make_scene("bench", seed=3, sensor=None)
    path = tmp_path / "bench.parquet"
    io.save(demo, path)
    app = typer.Typer()
    app.command()(learn_command)
    r = CliRunner().invoke(
        app, [str(path), "-o", str(tmp_path / "t.json"), "--report", str(tmp_path / "rep")]
    )
    assert r.exit_code == 0, r.output
    assert "action(seating" in r.output
    assert len(load_task(tmp_path / "t.json").constraints) == 4
    r = CliRunner().invoke(app, [str(tmp_path / "missing.c3d"), "-o", str(tmp_path / "x.json")])
    assert r.exit_code != 0


def test_toolbox_excerpt_runs_despite_missing_frames(shared_data: Path, tmp_path: Path) -> None:
    demo = io.load(shared_data / "3rdhand" / "toolbox_coop_4_excerpt")
    from thirdhand.taskfile import save_task

    task = learn_task([demo], primitives=False, reward=False, grasps=False).task
    save_task(task, tmp_path / "task.json")
    assert load_task(tmp_path / "task.json").schema_ == task.schema_


def test_report_draws_each_keyframe_with_the_parts_shapes(tmp_path: Path) -> None:
    """The task's meshes where found, else its boxes; one view per step, the pair named."""
    from thirdhand.learn.report import _keyframe_views, part_shapes, write_report
    from thirdhand.task.meshes import box_triangles

    demo = make_scene("chair", seed=2, sensor=None)
    both = learn_task([demo], segment=False, primitives=False, reward=False, grasps=False)
    result, task = both.learned, both.task
    # No mesh file beside the task and no search path: every part is its box.
    boxed = task.model_copy(
        update={"objects": [o.model_copy(update={"mesh": None}) for o in task.objects]}
    )
    shapes = part_shapes(result, 0, boxed, tmp_path / "task.json")
    with_box = [o for o in boxed.objects if o.bbox_min is not None]
    assert with_box and set(shapes) == {o.name for o in with_box}
    for o in with_box:
        np.testing.assert_array_equal(shapes[o.name], box_triangles(o.bbox_min, o.bbox_max))
    # Without a task, the recording's own geometry gives the same boxes.
    own = part_shapes(result, 0)
    assert set(own) >= {"seating", "leg1", "back"}
    assert _keyframe_views(result, 0, shapes)  # a PNG
    page = write_report(result, tmp_path / "report", boxed, tmp_path / "task.json").read_text()
    assert "<h3>Keyframes</h3>" in page and "(child)" in page


@pytest.mark.slow
def test_learn_explains_new_motions_with_an_earlier_tasks_skill_library(tmp_path: Path) -> None:
    """Learned once, reused: ``[learn] skill_library`` parses a new chair with chair 3's skills."""
    from thirdhand.cli import app

    runner = CliRunner()
    for seed in (3, 4):
        r = runner.invoke(app, ["synth", "chair", "-o", str(tmp_path / f"c{seed}.parquet"),
                                "--seed", str(seed)])  # fmt: skip
        assert r.exit_code == 0, r.output
    first = tmp_path / "first.json"
    cfg = settings_file(tmp_path, "learn", reward=False)
    r = runner.invoke(app, ["learn", str(tmp_path / "c3.parquet"), "-o", str(first),
                            "--config", str(cfg)])  # fmt: skip
    assert r.exit_code == 0, r.output
    reuse = tmp_path / "reuse"
    reuse.mkdir()
    cfg2 = settings_file(reuse, "learn", reward=False, skill_library=str(first))
    second = tmp_path / "second.json"
    r = runner.invoke(app, ["learn", str(tmp_path / "c4.parquet"), "-o", str(second),
                            "--config", str(cfg2)])  # fmt: skip
    assert r.exit_code == 0, r.output
    a, b = (load_task(p).stages.primitives for p in (first, second))
    assert a is not None and b is not None and a.skill_library and b.skill_library
    # the same skills, not a new fit; chair 4's own motions explained by them
    assert b.skill_library.skills == a.skill_library.skills
    assert all(c.skills and c.skills[0].source == "c4.parquet" for c in b.constraints.values())
    turn = int(np.argmax([s.typical_angular_speed_rad_s for s in a.skill_library.summary]))
    legs = [c for c in b.constraints.values() if c.child.startswith("leg")]
    assert len(legs) == 4
    assert all(turn in [s.skill for s in c.skills[0].steps] for c in legs if c.skills)
    # `primitives library --library TASK` parses a track with the task's skills
    chair = io.load(tmp_path / "c4.parquet")
    leg = chair.track("leg1")
    csv = tmp_path / "leg1.csv"
    rows = np.column_stack([chair.t, leg.pos, leg.quat])[leg.valid]
    np.savetxt(csv, rows, delimiter=",")
    r = runner.invoke(app, ["primitives", "library", str(csv), "--library", str(first), "--json"])
    assert r.exit_code == 0, r.output
    parsed = json.loads(r.output)
    assert parsed["n_skills"] == a.skill_library.n_skills and parsed["library"] == str(first)
    assert turn in parsed["tracks"][0]["labels"]
    # a task without a library: one line, nothing written
    bare = tmp_path / "bare.json"
    cfg0 = settings_file(tmp_path, "learn", reward=False, skills=0)
    r = runner.invoke(app, ["learn", str(tmp_path / "c3.parquet"), "-o", str(bare),
                            "--config", str(cfg0)])  # fmt: skip
    assert r.exit_code == 0, r.output
    cfg3 = settings_file(reuse, "learn", skill_library=str(bare))
    r = runner.invoke(app, ["learn", str(tmp_path / "c4.parquet"), "-o", str(tmp_path / "x.json"),
                            "--config", str(cfg3)])  # fmt: skip
    msg = str(r.exception)
    assert r.exit_code != 0 and "has no stages.primitives.skill_library" in msg and "\n" not in msg
    assert not (tmp_path / "x.json").exists()
