"""Perception picks the object the clarification round asks about first.

The model layer (``clarification_queue(task, focus=...)``, ``perception_focus``)
on hand-written events, events written by ``add_perception_events`` and
synthetic recordings with known pointing targets; then the app's round and
panel without a browser, and once in headless Debian Chromium.
"""

from __future__ import annotations

import itertools
import json
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from thirdhand.demonstration import Demonstration
from thirdhand.errors import TaskFileError
from thirdhand.perception import AttentionInterval, PointingEvent, add_perception_events
from thirdhand.perception.events import focus_object
from thirdhand.review.clarify import Question, clarification_queue
from thirdhand.review.edits import Confirm, SetParent, apply_edit
from thirdhand.review.focus import find_focus, perception_focus
from thirdhand.synth import make_scene
from thirdhand.synth.task import truth_task
from thirdhand.task.stages import PointingRecord
from thirdhand.taskfile import TaskFile, parse_task, save_task

CHROMIUM = Path("/usr/bin/chromium")


def _key(q: Question) -> tuple[str, str | None, float, str]:
    return (q.constraint, q.dof, q.score, q.text)


@pytest.fixture(scope="module")
def pointing_chair() -> Demonstration:
    """A chair recording opening with three pointing gestures (leg3, leg4, seating)."""
    return make_scene("chair", seed=0, head=True, pointing=3)


@pytest.fixture(scope="module")
def doubtful_task(pointing_chair: Demonstration) -> TaskFile:
    """The chair's true task with leg2 on leg1 and spread confidences: every score differs."""
    task = apply_edit(truth_task(pointing_chair), SetParent("leg2", "leg1"))
    confidence = {"leg1": 0.9, "leg2": 0.3, "leg3": 0.6, "leg4": 0.45, "back": 0.2}
    constraints = [
        c.model_copy(update={"confidence": confidence[c.child]}) for c in task.constraints
    ]
    return task.model_copy(update={"constraints": constraints})


# ---------------------------------------------------------------------------- ordering


def test_queue_without_focus_is_the_uncertainty_order(doubtful_task: TaskFile) -> None:
    base = clarification_queue(doubtful_task)
    assert [_key(q) for q in clarification_queue(doubtful_task, focus=None)] == [
        _key(q) for q in base
    ]
    # constraints in decreasing doubt, before any DOF (the DOFs of a true task are clear)
    assert [q.constraint for q in base[:5]] == ["c5", "c1", "c3", "c4", "c2"]
    assert all(q.dof is None for q in base[:5]) and not any(q.focused for q in base)
    assert all(a.score >= b.score for a, b in itertools.pairwise(base))
    # an object in no constraint (a finger, an unknown name) changes nothing
    for other in ("rh_index", "nothing"):
        queue = clarification_queue(doubtful_task, focus=other)
        assert [_key(q) for q in queue] == [_key(q) for q in base]
        assert not any(q.focused for q in queue)


def test_focus_moves_its_constraint_then_its_children_first(doubtful_task: TaskFile) -> None:
    base = clarification_queue(doubtful_task)
    by_id = {c.id: c for c in doubtful_task.constraints}
    queue = clarification_queue(doubtful_task, focus="leg1")
    own = [_key(q) for q in base if by_id[q.constraint].child == "leg1"]
    children = [_key(q) for q in base if by_id[q.constraint].parent == "leg1"]
    rest = [_key(q) for q in base if "leg1" not in (by_id[q.constraint].child,
                                                    by_id[q.constraint].parent)]  # fmt: skip
    assert len(own) == len(children) == 7
    assert [_key(q) for q in queue] == own + children + rest
    assert [q.focused for q in queue] == [True] * 14 + [False] * len(rest)
    assert queue[0].constraint == "c2" and queue[7].constraint == "c1"
    # the seat is every other constraint's parent: all focused, in the uncertainty order
    seat = clarification_queue(doubtful_task, focus="seating")
    assert [_key(q) for q in seat if q.focused] == [
        _key(q) for q in base if by_id[q.constraint].parent == "seating"
    ]
    # confirmed questions stay out; the focused rest still comes first
    confirmed = apply_edit(doubtful_task, Confirm("c2", None))
    queue = clarification_queue(confirmed, focus="leg1")
    assert queue[0].constraint == "c2" and queue[0].dof == "tx" and queue[0].focused
    assert len(queue) == len(base) - 1


# ---------------------------------------------------------------------------- focus


def test_focus_from_events_written_by_add_perception_events(doubtful_task: TaskFile) -> None:
    pointing = [
        PointingEvent("rh", "leg3", 3.0, 4.0, 1.0, "head"),
        PointingEvent("lh", "leg1", 6.0, 7.0, 2.0, "head"),
        PointingEvent("rh", None, 8.0, 9.0, float("inf"), "head"),  # at nothing: passed over
    ]
    attention = [AttentionInterval("seating", 0.0, 2.5, 4.0), AttentionInterval("back", 10, 20, 3)]
    task = add_perception_events(doubtful_task, pointing=pointing, attention=attention)
    assert perception_focus(task) == "leg1"
    found = find_focus(task)
    assert found is not None and found.kind == "pointing" and found.source == "task"
    assert (found.t0, found.t1, found.reason) == (6.0, 7.0, "you pointed at leg1")
    # at a moment: the perception stage's own answer, wherever there is one
    for t in np.arange(-1.0, 22.0, 0.25):
        assert perception_focus(task, t=float(t)) == focus_object(task, float(t)), t
    assert perception_focus(task, t=1.0) == "seating"
    looking = find_focus(task, t=15.0)
    assert looking is not None and looking.reason == "you looked at back"
    # attention alone: the longest interval
    looked = add_perception_events(doubtful_task, attention=attention)
    assert perception_focus(looked) == "back"
    assert perception_focus(doubtful_task) is None
    # an object the (edited) task no longer has is passed over
    stale = task.model_copy(deep=True)
    assert stale.stages.perception is not None
    stale.stages.perception.pointing.append(
        PointingRecord(hand="rh", object="leg9", t0=30.0, t1=31.0)
    )
    assert perception_focus(stale) == "leg1"


def test_malformed_perception_block_is_a_task_file_error(doubtful_task: TaskFile) -> None:
    doc = doubtful_task.to_json_dict()
    doc["stages"]["perception"] = {"pointing": [{"hand": "rh", "object": "leg1", "t0": 1.0}]}
    with pytest.raises(TaskFileError, match=r"stages\.perception\.pointing\[0\]\.t1: required"):
        parse_task(json.dumps(doc))
    doc["stages"]["perception"] = {"attention": "leg1"}
    with pytest.raises(TaskFileError, match=r"stages\.perception\.attention: Input should be"):
        parse_task(json.dumps(doc))


def test_focus_from_a_pointing_recording_is_the_last_target(pointing_chair: Demonstration) -> None:
    truth = pointing_chair.meta["pointing"]
    task = truth_task(pointing_chair)
    assert "perception" not in task.stages
    found = find_focus(task, pointing_chair)
    assert found is not None and found.source == "recording"
    assert found.object == truth[-1]["object"] == "seating"
    # at the end of each gesture, that gesture's target
    for g in truth:
        assert perception_focus(task, pointing_chair, t=g["t1"]) == g["object"]
    # the task's own events come first
    marked = add_perception_events(task, pointing=[PointingEvent("rh", "leg2", 1, 2, 1, "head")])
    assert perception_focus(marked, pointing_chair) == "leg2"
    # no fingertips, no gestures: no focus (and no detection run)
    parts = pointing_chair.select(pointing_chair.bodies_of_kind("part"))
    assert perception_focus(task, parts) is None


@pytest.mark.parametrize("seed", [3])
def test_focus_from_another_seed_and_bench(seed: int) -> None:
    for scene in ("chair", "bench"):
        demo = make_scene(scene, seed=seed, head=False, pointing=2)
        assert perception_focus(truth_task(demo), demo) == demo.meta["pointing"][-1]["object"]


# ---------------------------------------------------------------------------- the app


def _focused_task(demo: Demonstration, path: Path) -> Path:
    task = add_perception_events(
        truth_task(demo), pointing=[PointingEvent("rh", "leg3", 2.0, 3.0, 1.0, "head")]
    )
    save_task(task, path)
    return path


def test_app_round_starts_with_the_focus_and_says_why(
    pointing_chair: Demonstration, tmp_path: Path
) -> None:
    from thirdhand.review.app import ReviewApp

    path = _focused_task(pointing_chair, tmp_path / "chair.task.json")
    app = ReviewApp(path, demos=[pointing_chair], port=0, light_rendering=True)
    app.start()
    try:
        q = app.clarifier.start()
        assert app.clarifier.round.focus is not None and app.clarifier.round.focus.object == "leg3"
        assert q is not None and q.focused
        assert app.task.constraint_by_id(q.constraint).child == "leg3"
        assert app.view.selected == "leg3"
        assert 'id="th-focus"' in app.panels.question.content
        assert "you pointed at leg3" in app.panels.question.content
        while app.clarifier.question is not None and app.clarifier.question.focused:
            app.clarifier.answer(True)
        assert app.clarifier.round.index == 7  # the constraint and its six DOFs
        assert "th-focus" not in app.panels.question.content
        assert 'id="th-question"' in app.panels.question.content
        # without events, the recording's gestures: the seat was pointed at last
        save_task(truth_task(pointing_chair), path)
        app.reload(force=True)
        app.clarifier.start()
        assert (
            app.clarifier.round.focus is not None
            and app.clarifier.round.focus.source == "recording"
        )
        assert "you pointed at seating" in app.panels.question.content
    finally:
        app.motion.halt()
        app.stop()


@pytest.mark.slow
def test_browser_shows_why_the_round_starts_there(
    pointing_chair: Demonstration, tmp_path: Path
) -> None:
    """The panel in headless Debian Chromium (as ``tests/test_review_gui.py``)."""
    if not CHROMIUM.exists():
        pytest.skip(f"{CHROMIUM} not found: install Debian's chromium package for browser tests")
    from playwright.sync_api import sync_playwright

    from thirdhand.review.app import ReviewApp

    path = _focused_task(pointing_chair, tmp_path / "chair.task.json")
    app = ReviewApp(path, demos=[pointing_chair], port=0, light_rendering=True)
    url = app.start()
    args = ["--headless", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader", "--disable-background-networking"]  # fmt: skip
    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=str(CHROMIUM), args=args)
            page = browser.new_page(viewport={"width": 1280, "height": 900})
            page.goto(url)
            page.get_by_role("button", name="Start clarification", exact=True).click(timeout=20_000)
            page.locator("#th-focus").wait_for(timeout=20_000)
            assert page.locator("#th-focus").inner_text() == "you pointed at leg3"
            _wait(lambda: app.clarifier.question is not None)
            assert app.clarifier.question is not None and app.clarifier.question.focused
            assert app.view.selected == "leg3"
            browser.close()
    finally:
        app.motion.halt()
        app.stop()


def _wait(condition: Any, timeout: float = 10.0) -> None:
    end = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < end, "timed out"
        time.sleep(0.05)
