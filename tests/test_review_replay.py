"""The plan's partial order on the timeline, and execution records replayed in the review GUI.

Model-level tests (no browser): the refusal of a reorder that breaks the partial
order, checked against every move by brute force; reading an execution record
and refusing one of another task; when the robot holds a part. The browser
tests of both features are in ``test_review_gui.py``.
"""

from __future__ import annotations

import itertools
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.review_records import CARRY_FROM, partial_order, write_record
from thirdhand.review.edits import EditError, MoveStep, apply_edit, order_conflict
from thirdhand.synth import make_scene
from thirdhand.synth.task import truth_task
from thirdhand.task.model import TaskFile


@pytest.fixture(scope="module")
def chair() -> TaskFile:
    return truth_task(make_scene("chair", seed=0))


def _respects(order: list[int], closure: list[set[int]]) -> bool:
    """Every step after all it must follow, in ``order`` (old indices in the new order)."""
    where = {old: k for k, old in enumerate(order)}
    return all(where[a] < where[b] for b, before in enumerate(closure) for a in before)


def _closure(task: TaskFile) -> list[set[int]]:
    preds = task.predecessors()
    out: list[set[int]] = []
    for p in preds:
        out.append(set(p).union(*(out[j] for j in p)) if p else set())
    return out


def _follows(task: TaskFile) -> dict[str, set[str]]:
    """Each step's child, and the children of every step it must follow (transitively)."""
    return {
        task.plan[b].child: {task.plan[a].child for a in before}
        for b, before in enumerate(_closure(task))
    }


@pytest.mark.parametrize(
    "after",
    [
        [[], [], [], [], [3]],  # the back after leg1 only
        [[], [0], [], [1, 2], [3]],  # two chains joined
        [[], [], [0, 1], [], [2, 3]],  # a diamond-ish order
    ],
)
def test_order_conflict_matches_brute_force(chair: TaskFile, after: list[list[int]]) -> None:
    task = chair.model_copy(deep=True)
    for s, a in zip(task.plan, after, strict=True):
        s.after = a
    closure = _closure(task)
    n = len(task.plan)
    for i, j in itertools.product(range(n), range(n)):
        if i == j:
            continue
        order = list(range(n))
        order.insert(j, order.pop(i))
        why = order_conflict(task, i, j)
        assert (why is None) == _respects(order, closure), (i, j, why)
        edit = MoveStep(i, j, keep_order=True)
        if why is None:
            out = apply_edit(task, edit)
            assert [s.child for s in out.plan] == [task.plan[k].child for k in order]
            # Every dependency kept: each step follows the same steps (by child) as before.
            assert _follows(out) == _follows(task)
        else:
            with pytest.raises(EditError, match="must follow"):
                apply_edit(task, edit)


def test_order_conflict_message_names_both_steps(chair: TaskFile) -> None:
    task = partial_order(chair)
    why = order_conflict(task, 4, 2)
    assert why == (
        "step 5 (back on seating) must follow step 4 (leg1 on seating): "
        "it cannot move to position 3"
    )
    why = order_conflict(task, 3, 4)
    assert why is not None and why.startswith("step 5 (back on seating) must follow step 4")
    # The demonstration's total order (after all None, or a chain): any move is fine.
    assert all(order_conflict(chair, i, j) is None for i in range(5) for j in range(5))
    out = apply_edit(chair, MoveStep(4, 0, keep_order=True))
    assert out.plan[0].child == "back"


def test_load_replay_reads_the_run_and_its_failed_step(chair: TaskFile, tmp_path: Path) -> None:
    from thirdhand.review.replay import load_replay, robot_contacts

    path = write_record(chair, tmp_path / "run")
    r = load_replay(tmp_path / "run", chair, tmp_path / "chair.task.json")
    assert r.path == path and r.success is False and r.note == ""
    assert r.demo.meta["name"] == "execution: run.parquet"
    assert r.summary() == ("execution run.parquet: failed; step 2 (leg3): no collision-free grasp")
    # The robot holds leg2 while it moves: frames 10 to 50 (0.1 s apart), nothing else.
    contacts = robot_contacts(r.demo)
    assert contacts.source == "execution"
    assert contacts.intervals == {("leg2", "robot"): [(pytest.approx(1.0), pytest.approx(5.0))]}
    assert contacts.at(3.0) == {"leg2": "robot"} and contacts.at(5.5) == {}
    # Another task file name is said, not refused.
    r2 = load_replay(path, chair, tmp_path / "chair_fixed.task.json")
    assert "recorded as task 'chair.task'" in r2.summary()


def test_a_record_of_another_task_is_refused(chair: TaskFile, tmp_path: Path) -> None:
    from thirdhand.review.replay import ReplayError, load_replay
    from thirdhand.review.transfer import transfer

    bench = transfer(chair, "bench").task
    path = write_record(bench, tmp_path / "bench_run", task_name="bench.task", failed=None)
    with pytest.raises(ReplayError) as info:
        load_replay(path, chair, tmp_path / "chair.task.json")
    assert str(info.value) == (f"{path}: a record of another task (bench.task): it lacks back")
    # Same parts, but its steps establish constraints this task does not have.
    run = write_record(chair, tmp_path / "other")
    doc = json.loads(run.with_suffix(".json").read_text())
    doc["steps"][0]["constraint"] = "c99"
    run.with_suffix(".json").write_text(json.dumps(doc))
    with pytest.raises(ReplayError, match=r"establish c99, not constraints of chair.task.json"):
        load_replay(run, chair, tmp_path / "chair.task.json")
    # Not a record at all: a recording of the person.
    from thirdhand import io

    demo_path = tmp_path / "person.parquet"
    io.save(make_scene("chair", seed=0).slice(0.0, 1.0), demo_path)
    with pytest.raises(ReplayError, match="not an execution record"):
        load_replay(demo_path, chair, tmp_path / "chair.task.json")
    with pytest.raises(ReplayError, match="no such execution record"):
        load_replay(tmp_path / "missing", chair, tmp_path / "chair.task.json")


def test_cli_refuses_a_record_of_another_task(chair: TaskFile, tmp_path: Path, capsys: Any) -> None:
    from thirdhand.cli import main
    from thirdhand.review.transfer import transfer
    from thirdhand.taskfile import save_task

    path = tmp_path / "chair.task.json"
    save_task(chair, path)
    bench = transfer(chair, "bench").task
    run = write_record(bench, tmp_path / "bench_run", task_name="bench.task")
    assert main(["review", str(path), "--replay", str(run), "--port", "0"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "a record of another task (bench.task)" in err[0]


def test_carry_offset_is_what_the_record_holds(chair: TaskFile, tmp_path: Path) -> None:
    """The helper's own check: the held part starts at goal + CARRY_FROM, ends at its goal."""
    from thirdhand import io
    from thirdhand.review.dofs import world_poses

    demo = io.load(write_record(chair, tmp_path / "run"))
    goal = np.asarray(world_poses(chair)["leg2"].pos)
    np.testing.assert_allclose(demo.pos("leg2")[0], goal + CARRY_FROM, atol=1e-12)
    np.testing.assert_allclose(demo.pos("leg2")[-1], goal, atol=1e-12)


def test_replay_view_sees_every_body_of_the_run(chair: TaskFile, tmp_path: Path) -> None:
    """Every sample of every body of a record lies within 30° of the camera's axis."""
    from thirdhand import io
    from thirdhand.review.replay import replay_view

    demo = io.load(write_record(chair, tmp_path / "run"))
    eye, target = (np.asarray(v) for v in replay_view(demo))
    axis = (target - eye) / np.linalg.norm(target - eye)
    pts = np.concatenate([demo.pos(n) for n in demo.body_names])
    rays = pts - eye
    cos = rays @ axis / np.linalg.norm(rays, axis=1)
    assert np.degrees(np.arccos(cos.min())) < 30.0
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    np.testing.assert_allclose(target, 0.5 * (lo + hi), atol=1e-12)
    assert eye[2] > target[2]  # from above
