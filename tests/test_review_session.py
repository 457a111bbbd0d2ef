"""Review sessions (save, conflicts, effort), the clarification queue and the scripted user."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import pytest

from thirdhand.errors import ThirdhandError
from thirdhand.review.edits import EditError, MoveStep, SetDofRange, SetParent, SetPoseValue
from thirdhand.review.effort import EffortLog, changed_parameters
from thirdhand.review.session import ConflictError, ReviewSession
from thirdhand.synth import make_scene
from thirdhand.synth.task import truth_task
from thirdhand.taskfile import TaskFile, load_task, save_task


@pytest.fixture(scope="module")
def chair() -> TaskFile:
    return truth_task(make_scene("chair", seed=0, sensor=None))


@pytest.fixture
def task_path(tmp_path: Path, chair: TaskFile) -> Path:
    p = tmp_path / "chair.task.json"
    save_task(chair, p)
    return p


def test_session_edit_save_reload(task_path: Path) -> None:
    s = ReviewSession.open(task_path)
    assert not s.dirty
    s.apply(SetPoseValue("c1", "x", 0.2))
    s.apply(SetParent("leg1", "leg2"))
    s.apply(MoveStep(4, 0))
    assert s.dirty
    assert s.save() == task_path
    assert not s.dirty
    back = load_task(task_path)
    assert back.constraint_by_id("c1").pos[0] == 0.2
    assert back.plan[0].child == "back"
    assert back.stages.review is not None and back.stages.review.effort is not None
    effort = back.stages.review.effort.model_dump(exclude_none=True)
    assert effort["operations"] == {
        "leg2": {"movex": 1},
        "leg1": {"parent": 1},
        "actions": {"reordering": 1},
    }
    assert "c1.x" in effort["changed_parameters"] and "c4.parent" in effort["changed_parameters"]
    assert "plan.order" in effort["changed_parameters"]
    assert back.provenance.corrections[0].field == "constraints[0].pos[0]"
    # The previous version is kept.
    old = load_task(task_path.with_name(task_path.name + ".bak"))
    assert old.constraint_by_id("c1").pos[0] == 0.115
    # The effort log continues across sessions.
    s2 = ReviewSession.open(task_path)
    s2.apply(SetPoseValue("c1", "x", 0.21))
    assert s2.effort.counts()["leg2"] == {"movex": 2}


def test_refused_edit_counts_nothing(task_path: Path) -> None:
    s = ReviewSession.open(task_path)
    with pytest.raises(EditError):
        s.apply(SetDofRange("c1", "rx", 1.0, -1.0))
    assert not s.dirty and s.effort.total() == 0


def test_conflict_nothing_lost(task_path: Path, tmp_path: Path) -> None:
    s = ReviewSession.open(task_path)
    s.apply(SetPoseValue("c1", "x", 0.2))
    # Another program rewrites the file meanwhile.
    other = json.loads(task_path.read_text())
    other["constraints"][1]["pos"][0] = 0.3
    task_path.write_text(json.dumps(other))
    theirs = task_path.read_bytes()
    assert s.conflict()
    with pytest.raises(ConflictError, match="changed on disk since it was loaded"):
        s.save()
    assert task_path.read_bytes() == theirs  # their version untouched
    assert s.dirty  # ours still in the session
    mine = tmp_path / "mine.task.json"
    assert s.save_as(mine) == mine
    assert load_task(mine).constraint_by_id("c1").pos[0] == 0.2
    assert load_task(task_path).constraints[1].pos[0] == 0.3
    # The session now lives on the new file: a further save goes there, no conflict.
    s.apply(SetPoseValue("c1", "x", 0.25))
    assert s.save() == mine
    assert load_task(mine).constraint_by_id("c1").pos[0] == 0.25


def test_conflict_force_keeps_theirs_as_backup(task_path: Path) -> None:
    s = ReviewSession.open(task_path)
    s.apply(SetPoseValue("c1", "x", 0.2))
    task_path.write_text(task_path.read_text().replace('"demo": "truth"', '"demo": "theirs"', 1))
    theirs = task_path.read_bytes()
    s.save(force=True)
    assert task_path.with_name(task_path.name + ".bak").read_bytes() == theirs
    assert load_task(task_path).constraint_by_id("c1").pos[0] == 0.2


def test_save_twice_no_false_conflict(task_path: Path) -> None:
    s = ReviewSession.open(task_path)
    s.apply(SetPoseValue("c1", "x", 0.2))
    s.save()
    s.apply(SetPoseValue("c1", "x", 0.22))
    s.save()
    assert load_task(task_path).constraint_by_id("c1").pos[0] == 0.22


def test_effort_log() -> None:
    log = EffortLog({"leg1": {"movex": 2, "bogus": 3}})
    log.record("rotz", "leg1")
    log.record("reordering", "actions")
    assert log.counts() == {"leg1": {"movex": 2, "rotz": 1}, "actions": {"reordering": 1}}
    assert log.total() == 4
    with pytest.raises(ThirdhandError, match="unknown effort operation"):
        log.record("jump", "leg1")


def test_changed_parameters(chair: TaskFile) -> None:
    from thirdhand.review.edits import apply_edit

    t = apply_edit(chair, SetPoseValue("c5", "yaw", 0.1))
    t = apply_edit(t, SetDofRange("c1", "rx", -1.0, 1.0))
    assert changed_parameters(chair, t) == ["c1.range.rx", "c5.yaw"]
    t2 = apply_edit(chair, SetParent("back", "leg1"))
    got = changed_parameters(chair, t2)
    assert got[0] == "c5.parent" and set(got[1:]) <= {
        f"c5.{n}" for n in ("x", "y", "z", "roll", "pitch", "yaw")
    }


def test_clarification_queue_order(chair: TaskFile) -> None:
    from thirdhand.review.clarify import clarification_queue, dof_ambiguity
    from thirdhand.review.edits import Confirm, apply_edit

    t = chair.model_copy(deep=True)
    t.constraints[2].confidence = 0.1  # c2: the least confident constraint
    # c3's ry: 6 degrees, right at the noise boundary (5 degrees)
    t.constraints[1].free_dofs = dataclasses.replace(
        t.constraints[1].free_dofs, ry=(-math.radians(3.0), math.radians(3.0))
    )
    q = clarification_queue(t)
    assert (q[0].constraint, q[0].dof) == ("c2", None)
    assert q[0].score == pytest.approx(0.9)
    assert (q[1].constraint, q[1].dof) == ("c3", "ry")
    assert "noise" not in q[1].text or "locked" in q[1].text
    rank = {(x.constraint, x.dof): k for k, x in enumerate(q)}
    # Near the boundary before clearly locked (c3 rz) and clearly full (c3 rx).
    assert rank[("c3", "ry")] < rank[("c3", "rz")]
    assert rank[("c3", "ry")] < rank[("c3", "rx")]
    assert dof_ambiguity(0.0, 0.0, "rx") == 0.0
    assert dof_ambiguity(-math.pi, math.pi, "rx") == 0.0
    # A nearly full turn is doubtful too; a half turn much less.
    assert dof_ambiguity(-3.0, 3.0, "rx") > 0.9 > dof_ambiguity(-0.6, 0.6, "rx")
    # Translations: 5 mm is the boundary.
    assert dof_ambiguity(0.0, 0.005, "tz") == pytest.approx(1.0)
    assert dof_ambiguity(0.0, 0.2, "tz") < 0.01
    scores = [x.score for x in q]
    assert q[1].score == pytest.approx(
        0.5 * dof_ambiguity(-math.radians(3.0), math.radians(3.0), "ry")
    )
    assert scores == sorted(scores, reverse=True)
    assert len(q) == 7 * len(t.constraints)
    # Confirmed questions leave the queue.
    t2 = apply_edit(apply_edit(t, Confirm("c2")), Confirm("c3", "ry"))
    q2 = clarification_queue(t2)
    assert ("c2", None) not in {(x.constraint, x.dof) for x in q2}
    assert ("c3", "ry") not in {(x.constraint, x.dof) for x in q2}
    assert len(q2) == len(q) - 2


def test_study_effort_reference_values(shared_data: Path) -> None:
    from thirdhand.io.iros15 import read_user_study
    from thirdhand.review.effort import study_effort

    got = study_effort(read_user_study(shared_data / "3rdhand" / "iros15_user_study.yaml"))
    assert set(got) == {
        ("blue_chair", "A"),
        ("blue_chair", "B"),
        ("green_bench", "C"),
        ("green_bench", "D"),
        ("test", "test"),
    }
    assert got[("blue_chair", "B")]["attempts"] == 15
    assert got[("blue_chair", "B")]["parameters"] == pytest.approx(16.33, abs=0.01)
    assert got[("green_bench", "D")]["parameters"] == pytest.approx(12.0)
    assert got[("blue_chair", "A")]["parameters"] == pytest.approx(30.4, abs=0.01)
