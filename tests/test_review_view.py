"""The review's pure core without a browser: what is shown, the widgets' input as edits,
the question rounds and the dialogs."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from thirdhand.errors import ThirdhandError
from thirdhand.review.corrections import (
    NONE,
    changed_texts,
    gizmo_edit,
    gizmo_pose,
    nudge_delta,
    nudge_edit,
    parent_edit,
    range_edit,
    reparent_edit,
    step_index,
    value_edits,
)
from thirdhand.review.dialogs import (
    conflict_path,
    discard_dialog,
    next_editor,
    overwrite_dialog,
    refusal_notice,
)
from thirdhand.review.edits import SetDofRange, SetParent, SetPoseValue, apply_edit, pose_values
from thirdhand.review.gizmo import GizmoMove
from thirdhand.review.rounds import (
    ClarificationRound,
    LabelCursor,
    answer_round,
    marked_interval,
    phase_labels_path,
    start_round,
)
from thirdhand.review.view import (
    ReviewView,
    after_reload,
    after_step_move,
    check_step_move,
    choose_step,
    constraint_of,
    drop_unknown,
    moving_step,
    require_constraint,
    select,
    selected_constraint,
    selected_parent,
    show_step,
    shown_poses,
    step_target,
)
from thirdhand.synth import make_scene
from thirdhand.synth.task import truth_task
from thirdhand.taskfile import TaskFile


@pytest.fixture(scope="module")
def chair() -> TaskFile:
    return truth_task(make_scene("chair", seed=0, sensor=None))


def test_selection_and_its_constraint(chair: TaskFile) -> None:
    names = {c.child for c in chair.constraints} | {c.parent for c in chair.constraints}
    view = select(ReviewView(mode="playback"), "leg2", names)
    assert view.selected == "leg2" and view.mode == "task"
    c = selected_constraint(chair, view)
    assert c is not None and c.child == "leg2" and c == constraint_of(chair, "leg2")
    assert selected_parent(chair, view) == c.parent
    with pytest.raises(ThirdhandError, match="unknown object 'nope'"):
        select(view, "nope", names)
    assert drop_unknown(view, {"seat"}).selected is None
    assert drop_unknown(view, names) == view
    with pytest.raises(ThirdhandError, match="select an object with a constraint first"):
        require_constraint(chair, ReviewView())


def test_steps_shown_chosen_and_moved(chair: TaskFile) -> None:
    n = len(chair.plan)
    chosen = choose_step(chair, ReviewView(mode="playback"), 2)
    assert (chosen.step, chosen.chosen_step, chosen.mode) == (None, 2, "playback")
    view = show_step(chair, chosen, 2)
    assert (view.step, view.chosen_step, view.mode) == (2, 2, "task")
    assert show_step(chair, view, None).step is None
    with pytest.raises(ThirdhandError, match=f"no plan step {n + 1}; the plan has {n}"):
        choose_step(chair, view, n)
    assert step_target(chair, 2, -1) == 1 and step_target(chair, 2, 1) == 3
    with pytest.raises(ThirdhandError, match=f"step 1 is already the first of {n}"):
        step_target(chair, 0, -1)
    with pytest.raises(ThirdhandError, match=f"step {n} is already the last of {n}"):
        step_target(chair, n - 1, 1)
    with pytest.raises(ThirdhandError, match="already at position 3"):
        check_step_move(chair, 2, 2)
    with pytest.raises(ThirdhandError, match=f"no position {n + 1}: the plan has {n} steps"):
        check_step_move(chair, 2, n)
    moved = after_step_move(view, 2, 0)
    assert (moved.step, moved.chosen_step) == (0, 0)
    other = after_step_move(replace(view, step=4), 2, 0)
    assert (other.step, other.chosen_step) == (4, 0)
    assert moving_step(chair, ReviewView()) == 0 and moving_step(chair, view) == 2
    short = chair.model_copy(update={"plan": chair.plan[:1]})
    assert after_reload(short, replace(view, step=3)).step is None
    assert after_reload(chair, view) == view


def test_typed_values_become_edits(chair: TaskFile) -> None:
    c = constraint_of(chair, "leg2")
    assert c is not None
    edits = value_edits(c, {"x": "12", "yaw": "90 deg"})
    assert edits == [
        (SetPoseValue(c.id, "x", 0.12), "movex"),
        (SetPoseValue(c.id, "yaw", math.radians(90.0)), "rotz"),
    ]
    task = chair
    for edit, _ in edits:
        task = apply_edit(task, edit)
    moved = task.constraint_by_id(c.id)
    assert pose_values(moved)["x"] == pytest.approx(0.12)
    assert pose_values(moved)["yaw"] == pytest.approx(math.pi / 2)
    with pytest.raises(ThirdhandError):
        value_edits(c, {"x": "12", "y": "twelve"})  # one bad value: no edit at all
    assert changed_texts({"x": "1 cm", "y": "2 cm"}, {"x": "1 cm", "y": "3 cm"}) == {"y": "2 cm"}
    assert nudge_delta("x", "-5") == pytest.approx(-0.05)
    assert nudge_delta("yaw", "+1") == pytest.approx(math.radians(1.0))
    edit, op = nudge_edit(c, "z", 0.01)
    assert edit == SetPoseValue(c.id, "z", pose_values(c)["z"] + 0.01) and op == "movez"
    assert range_edit(c, "tx", "-1", "2 cm") == SetDofRange(c.id, "tx", -0.01, 0.02)
    assert range_edit(c, "rz", "0", "90") == SetDofRange(c.id, "rz", 0.0, math.pi / 2)
    assert parent_edit("leg2", "back") == SetParent("leg2", "back")
    with pytest.raises(ThirdhandError, match="select an object and its new parent first"):
        parent_edit("leg2", NONE)
    with pytest.raises(ThirdhandError, match="shift-click its new parent"):
        reparent_edit(None, "back")
    assert step_index("3. leg2 on seat (c2)") == 2
    with pytest.raises(ThirdhandError, match="no step to choose"):
        step_index("-")


def test_gizmo_release_is_the_dragged_pose_in_the_parent_frame(chair: TaskFile) -> None:
    view = ReviewView(selected="leg2")
    c = selected_constraint(chair, view)
    assert c is not None and c.frame.is_identity
    poses = shown_poses(chair, view)
    move = GizmoMove("end", np.array([0.02, 0.0, 0.0]), np.array([0.0, 0.0, 0.0, 1.0]))
    p, q = gizmo_pose(poses[c.child], c, move)
    edit, op = gizmo_edit(c, poses[c.parent], p, q, move)
    assert op == "movex"
    # Undragged, the same construction gives back the constraint's own pose.
    still = GizmoMove("end", np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]))
    p0, q0 = gizmo_pose(poses[c.child], c, still)
    same, _ = gizmo_edit(c, poses[c.parent], p0, q0, still)
    np.testing.assert_allclose(same.pos, c.pos, atol=1e-12)
    np.testing.assert_allclose(np.abs(np.dot(same.quat, c.quat)), 1.0, atol=1e-12)
    assert np.linalg.norm(np.subtract(edit.pos, c.pos)) == pytest.approx(0.02)


def test_clarification_round(chair: TaskFile) -> None:
    round_ = start_round(chair, None)
    assert round_.index == 0 and round_.question is not None and round_.focus is None
    first = round_.question
    after, edit = answer_round(round_, True)
    assert after.index == 1 and edit is not None and edit.constraint == first.constraint
    _, none = answer_round(round_, False)
    assert none is None
    with pytest.raises(ThirdhandError, match="start the clarification round"):
        answer_round(ClarificationRound(), True)


def test_label_marks_and_paths() -> None:
    cursor = LabelCursor(("rh_index", "leg2"), 3.0)
    assert marked_interval(cursor, 1.5) == (("rh_index", "leg2"), 1.5, 3.0)
    with pytest.raises(ThirdhandError, match="mark where the interval starts first"):
        marked_interval(LabelCursor(("a", "b")), 1.0)
    assert phase_labels_path(Path("/x/chair.task.json")) == Path("/x/chair.task.phases.kvg")


def test_dialogs_and_notices() -> None:
    d = discard_dialog("reload")
    assert d.title == "Unsaved changes" and d.confirm == "Discard and reload"
    assert "Reload and lose them?" in d.markdown
    o = overwrite_dialog("a<b>.json", "a.unsaved.json")
    assert "a&lt;b&gt;.json" in o.markdown and o.cancel == "Keep both"
    assert conflict_path(Path("/x/chair.task.json")) == Path("/x/chair.task.unsaved.json")
    assert refusal_notice(has_token=False).color == "red"
    assert refusal_notice(has_token=True).title == "Read-only"
    assert next_editor([3, 1, 2], 1, [1, 2, 3]) == 2
    assert next_editor([3, 1, 2], 1, [1, 3]) == 3
    assert next_editor([1], 1, [1]) is None
