"""Editing a constraint's learned motion by its key points (model layer, no browser).

The primitives are learned from the synthetic chair (seed 0) by the primitives
stage. Tolerances: refitting a DMP to its own rollout reproduces it within its
imitation error, 0.16-0.36 mm on these five motions (measured; the fit has as
many weights as the learned one); 1 mm is three times the worst. The browser
test is in ``test_review_gui.py``.
"""

from __future__ import annotations

import copy
import json
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.test_review_gui import (  # noqa: F401  (fixtures)
    TIMEOUT_MS,
    Review,
    chair,
    chromium_browser,
    open_review,
)
from thirdhand.primitives.serialize import pose_dmp_from_record
from thirdhand.review.edits import EditError, SetPrimitivePoint, apply_edit
from thirdhand.review.primitive_edit import (
    KEY_FRACTIONS,
    PrimitiveEditError,
    displacement,
    key_for,
    move_key_point,
    primitive_path,
    refit_position,
    sample,
)
from thirdhand.review.session import ReviewSession
from thirdhand.review.view import motion_path, primitive_key
from thirdhand.synth.task import truth_task
from thirdhand.task.model import TaskFile
from thirdhand.taskfile import load_task, save_task

TOL_M = 1e-3


@pytest.fixture(scope="module")
def task(chair: Any) -> TaskFile:  # noqa: F811
    from thirdhand.primitives.stage import primitives_stage

    t = truth_task(chair)
    t.stages.primitives = primitives_stage([chair])
    return t


def test_displacement_is_the_offsets_at_the_key_times_and_zero_at_the_ends() -> None:
    s = np.linspace(0.0, 4.0, 401)
    times = np.array([1.0, 2.0, 3.0])
    off = np.array([[0.0, 0.0, 0.0], [0.03, -0.01, 0.02], [0.0, 0.0, 0.0]])
    d = displacement(s, times, off)
    np.testing.assert_allclose(d[[100, 200, 300]], off, atol=1e-15)
    np.testing.assert_array_equal(d[[0, -1]], np.zeros((2, 3)))
    # Clamped ends: the path leaves its start and reaches its goal with its own velocity.
    np.testing.assert_allclose((d[1] - d[0]) / 0.01, 0.0, atol=0.01)
    np.testing.assert_allclose((d[-1] - d[-2]) / 0.01, 0.0, atol=0.01)


def test_refit_of_an_unmoved_path_reproduces_it(task: TaskFile) -> None:
    block = task.stages.primitives
    assert block is not None
    for key, record in block.constraints.items():
        path = primitive_path(block, key)
        dmp = pose_dmp_from_record(record)
        again = refit_position(dmp.position_, path.s, path.pos)
        np.testing.assert_array_equal(again.goal_, dmp.position_.goal_)
        np.testing.assert_array_equal(again.start_, dmp.position_.start_)
        _, p, _ = again.rollout()
        assert np.abs(p - path.pos).max() < TOL_M, key


def test_a_moved_key_point_is_followed_and_the_rest_kept(task: TaskFile) -> None:
    block = task.stages.primitives
    assert block is not None
    before = copy.deepcopy(block)
    key = key_for(block, "seating", "leg2")
    assert key is not None
    path = primitive_path(block, key)
    assert path.key_points.shape == (len(KEY_FRACTIONS), 3)
    np.testing.assert_allclose(path.key_times, np.array(KEY_FRACTIONS) * path.s[-1])
    target = path.key_points[1] + np.array([0.0, 0.03, 0.04])  # 5 cm away
    new = move_key_point(block, key, 1, target)
    assert block == before  # the input block is not changed
    moved = primitive_path(new, key)
    np.testing.assert_array_equal(moved.s, path.s)
    assert np.linalg.norm(moved.key_points[1] - target) < TOL_M
    for k in (0, 2):
        assert np.linalg.norm(moved.key_points[k] - path.key_points[k]) < TOL_M
    assert np.linalg.norm(moved.pos[-1] - path.pos[-1]) < TOL_M
    np.testing.assert_array_equal(moved.pos[0], path.pos[0])
    # Orientation, goal and the other motions are unchanged; the edit is recorded.
    entry, old = new.constraints[key], block.constraints[key]
    assert entry.dmp.rotation == old.dmp.rotation
    assert entry.dmp.position.goal == old.dmp.position.goal
    assert entry.goal == old.goal
    assert {k: v for k, v in new.constraints.items() if k != key} == {
        k: v for k, v in block.constraints.items() if k != key
    }
    assert entry.source == "corrected"
    assert [e.model_dump(by_alias=True) for e in entry.edits] == [
        {
            "index": 1,
            "time_s": float(path.key_times[1]),
            "from": tuple(path.key_points[1].tolist()),
            "to": tuple(target.tolist()),
        }
    ]
    # The drawn path passes the moved key point too.
    drawn = moved.drawn()
    assert drawn.shape == (120, 3)
    np.testing.assert_allclose(drawn[[0, -1]], moved.pos[[0, -1]])
    np.testing.assert_allclose(
        sample(moved.s, moved.pos, moved.key_times[1])[0], moved.key_points[1]
    )


def test_edit_is_saved_undoable_and_counted(task: TaskFile, tmp_path: Path) -> None:
    from thirdhand.execute.primitive_motion import find_primitive

    path = tmp_path / "chair.task.json"
    save_task(task, path)
    session = ReviewSession.open(path)
    key = key_for(task.stages.primitives, "seating", "leg2")
    assert key is not None
    target = primitive_path(task.stages.primitives, key).key_points[0] + [0.0, 0.0, 0.05]
    edit = SetPrimitivePoint(key, 0, (float(target[0]), float(target[1]), float(target[2])))
    session.apply(edit)
    assert session.effort.counts() == {"leg2": {"primitive": 1}}
    corr = session.task.provenance.corrections[-1]
    assert corr.field == f"stages.primitives.constraints.{key}.key_points[0]"
    assert corr.new == list(edit.pos)
    saved = session.save()
    block = load_task(saved).stages.primitives
    moved = primitive_path(block, key)
    assert np.linalg.norm(moved.key_points[0] - target) < TOL_M
    assert json.loads(saved.read_text())["stages"]["review"]["effort"]["operations"] == {
        "leg2": {"primitive": 1}
    }
    # Execution follows the edited motion.
    dmp = find_primitive(block, "seating", "leg2")
    assert dmp is not None
    _, p, _ = dmp.rollout()
    np.testing.assert_array_equal(p, moved.pos)
    session.undo()
    assert session.task.stages.primitives == task.stages.primitives


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (SetPrimitivePoint("c9", 0, (0.0, 0.0, 0.0)), "no primitive 'c9'; there are c1"),
        (SetPrimitivePoint("c1", 3, (0.0, 0.0, 0.0)), "no key point 4; it has 3"),
        (SetPrimitivePoint("c1", -1, (0.0, 0.0, 0.0)), "no key point 0; it has 3"),
        (SetPrimitivePoint("c1", 0, (0.0, float("nan"), 0.0)), "key point 1 y"),
        (SetPrimitivePoint("c1", 0, (0.0, 1e9, 0.0)), "1e\\+09 m from the parent is not plausible"),
    ],
)
def test_bad_primitive_edits_are_refused(task: TaskFile, edit: Any, message: str) -> None:
    with pytest.raises(EditError, match=message):
        apply_edit(task, edit)


def test_a_task_without_primitives_is_told(task: TaskFile) -> None:
    bare = task.model_copy(deep=True)
    bare.stages.primitives = None
    with pytest.raises(EditError, match="the task has no learned primitives"):
        apply_edit(bare, SetPrimitivePoint("c1", 0, (0.0, 0.0, 0.0)))
    with pytest.raises(PrimitiveEditError, match="the task has no learned primitives"):
        primitive_path(None, "c1")
    assert key_for(None, "seating", "leg2") is None


def _type(review: Review, name: str, text: str) -> None:
    """Type into a key point field until the server has the text (the client throttles)."""
    handle = review.app.panels.key_values[name]
    for attempt in range(3):
        field = review.text_input(f"key {name}")
        if attempt:
            field.fill("")
        field.fill(text)
        try:
            review.wait_for(lambda: handle.value == text, f"the server to get {text!r}")
            return
        except AssertionError:
            if attempt == 2:
                raise


@pytest.mark.slow
def test_motion_key_point_moved_in_the_browser(open_review: Any, task: TaskFile) -> None:  # noqa: F811
    """Select leg2: its learned motion is drawn with 3 key points; moving the second one
    5 cm up refits the motion, and Save writes it with the effort log."""
    review = open_review(task)
    app = review.app
    review.choose("Object", "leg2")
    review.wait_for(lambda: app.view.selected == "leg2", "selection of leg2")
    key = primitive_key(app.task, app.view)
    assert key is not None and app.scene.motion_view.shown == (key, 0)
    review.page.locator("#th-motion").get_by_text("key point", exact=False).count()
    review.choose("Key point", "2")
    review.wait_for(lambda: app.view.key_point == 1, "key point 2 chosen")
    assert app.scene.motion_view.shown == (key, 1)
    before = primitive_path(task.stages.primitives, key)
    z = before.key_points[1][2] + 0.05
    _type(review, "z", f"{100.0 * z:.2f} cm")
    review.button("Move key point").click()
    review.wait_for(lambda: app.session.dirty, "the key point moved")
    after = motion_path(app.task, app.view)
    assert after is not None
    target = before.key_points[1] + [0.0, 0.0, z - before.key_points[1][2]]
    assert np.linalg.norm(after.key_points[1] - target) < 1e-3 + 5e-5  # + the typed rounding
    np.testing.assert_allclose(app.scene.motion_view.key_points, after.key_points)
    review.page.get_by_text("1 key point move(s)").wait_for(timeout=TIMEOUT_MS)
    review.page.locator("#th-message").get_by_text("key point 2 at").wait_for(timeout=TIMEOUT_MS)
    time.sleep(1.0)  # software WebGL: let the path render before the screenshot
    review.shot("primitive-edit")
    review.button("Save").click()
    review.wait_for(lambda: not app.session.dirty, "the save")
    saved = load_task(review.path)
    moved = primitive_path(saved.stages.primitives, key)
    np.testing.assert_allclose(moved.key_points, after.key_points)
    assert saved.stages.review is not None and saved.stages.review.effort is not None
    effort = saved.stages.review.effort.operations
    assert effort["leg2"]["primitive"] == 1


def test_dragging_the_key_point_handle_moves_it(task: TaskFile, tmp_path: Path) -> None:
    from types import SimpleNamespace

    from thirdhand.review.app import ReviewApp

    path = tmp_path / "chair.task.json"
    save_task(task, path)
    app = ReviewApp(path, port=0, light_rendering=True)
    app.start()
    try:
        app.select("leg2")
        key = primitive_key(app.task, app.view)
        view = app.scene.motion_view
        assert key is not None and view is not None and view.handle is not None
        before = primitive_path(task.stages.primitives, key)
        np.testing.assert_allclose(view.handle.position, before.key_points[0])
        app.choose_key_point(2)
        np.testing.assert_allclose(view.handle.position, before.key_points[2])
        target = before.key_points[2] + np.array([0.03, 0.0, 0.0])

        def drag(phase: str, client_id: int | None) -> None:
            moved = SimpleNamespace(position=tuple(target))
            view.on_event(SimpleNamespace(phase=phase, target=moved, client_id=client_id))

        drag("update", None)  # a drag previews nothing and changes nothing
        assert not app.session.dirty
        app.tabs.editor = 7  # another tab edits: this one's release is refused
        drag("end", 8)
        assert not app.session.dirty and "only views" in app.message
        np.testing.assert_allclose(view.handle.position, before.key_points[2])
        drag("end", 7)
        after = motion_path(app.task, app.view)
        assert after is not None and np.linalg.norm(after.key_points[2] - target) < TOL_M
        assert app.session.effort.counts()["leg2"]["primitive"] == 1
        np.testing.assert_allclose(view.handle.position, after.key_points[2])
    finally:
        app.stop()
