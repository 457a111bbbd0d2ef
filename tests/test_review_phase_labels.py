"""Labelling interaction phases for calibration (model layer, no browser).

Interval arithmetic is checked against boolean masks by brute force; the
active questions on a marginal with known runs; the label file round-trips
through the reader ``thirdhand segment train/calibrate --labels`` use.
"""

from __future__ import annotations

import dataclasses
import itertools
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from thirdhand.errors import OutputError
from thirdhand.review.phase_labels import (
    PhaseLabelError,
    active_questions,
    phase_labels,
    set_span,
    snap_to_frames,
    uncertain_runs,
    write_phase_labels,
)
from thirdhand.segment.intervals import pair_intervals
from thirdhand.synth import make_scene


def _mask(spans: list[tuple[float, float]], grid: np.ndarray) -> np.ndarray:
    m = np.zeros(grid.size, dtype=bool)
    for s, e in spans:
        m |= (grid >= s) & (grid <= e)
    return m


def test_set_span_matches_mask_arithmetic() -> None:
    rng = np.random.default_rng(0)
    grid = np.arange(0, 30) + 0.5  # between the integer bounds, where closedness is moot
    for _ in range(300):
        spans: list[tuple[float, float]] = []
        for _ in range(rng.integers(0, 5)):
            s = int(rng.integers(0, 28))
            spans = set_span(spans, s, s + int(rng.integers(1, 6)), True)
        s = int(rng.integers(0, 28))
        e = s + int(rng.integers(1, 8))
        value = bool(rng.integers(0, 2))
        new = set_span(spans, s, e, value)
        want = _mask(spans, grid)
        inside = (grid >= s) & (grid <= e)
        want = want | inside if value else want & ~inside
        np.testing.assert_array_equal(_mask(new, grid), want)
        assert new == sorted(new)
        assert all(a[1] < b[0] for a, b in itertools.pairwise(new))  # merged
    for bad in ((2.0, 2.0), (3.0, 1.0), (0.0, float("nan"))):
        with pytest.raises(PhaseLabelError, match="expected start < end"):
            set_span([], *bad, True)


def test_questions_most_uncertain_first() -> None:
    edges = np.arange(0.0, 11.0)  # ten 1 s steps
    p1 = np.array([0.9, 0.5, 0.5, 0.95, 0.1, 0.7, 0.05, np.nan, 0.45, 0.0])
    p2 = np.array([0.0, 0.0, 0.6, 0.6, 0.6, 0.6, 0.0, 0.0, 0.0, 0.0])
    assert uncertain_runs(p1) == [(1, 3), (5, 6), (8, 9)]
    qs = active_questions([("h", "a", p1), ("h", "b", p2)], edges)
    got = [(q.b, q.start, q.end, round(q.score, 9)) for q in qs]
    # Scores: mean(1 - |2p - 1|) x length: p2's 4 s at 0.6 -> 0.8 x 4 = 3.2; p1's 2 s at
    # 0.5 -> 2.0; 0.45 -> 0.9; 0.7 -> 0.6.
    assert got == [("b", 2.0, 6.0, 3.2), ("a", 1.0, 3.0, 2.0), ("a", 8.0, 9.0, 0.9),
                   ("a", 5.0, 6.0, 0.6)]  # fmt: skip
    assert qs[0].probability == pytest.approx(0.6)
    assert "from 2.00 s to 6.00 s" in qs[0].text() and "60%" in qs[0].text()
    answered = active_questions(
        [("h", "a", p1), ("h", "b", p2)], edges, answered={("h", "b"): [(1.5, 6.5)]}
    )
    assert [(q.b, q.start) for q in answered] == [("a", 1.0), ("a", 8.0), ("a", 5.0)]


@pytest.fixture(scope="module")
def chair() -> Any:
    return make_scene("chair", seed=0)


def test_label_file_round_trips_through_the_training_reader(chair: Any, tmp_path: Path) -> None:
    from thirdhand import io
    from thirdhand.segment.cli import _with_labels

    a, b = chair.labels.interaction_pairs()[0]
    old = pair_intervals(chair.labels, a, b)
    spans = set_span(old, old[0][0] - 0.5, old[0][0] + 0.2, True)  # the phase starts earlier
    spans = set_span(spans, old[-1][1] - 1.0, old[-1][1] + 1.0, False)  # and ends sooner
    recording = tmp_path / "chair.parquet"
    io.save(chair, recording)
    path = write_phase_labels(tmp_path / "chair.labels.kvg", chair, {(a, b): spans})
    (demo,) = _with_labels([recording], [path])  # what segment train / calibrate read
    want = snap_to_frames(spans, chair.t)
    np.testing.assert_allclose(pair_intervals(demo.labels, a, b), want, atol=1e-9)
    others = {(i.a, i.b, i.start, i.end) for i in chair.labels.interactions if {i.a, i.b} != {a, b}}
    got = {(i.a, i.b, i.start, i.end) for i in demo.labels.interactions if {i.a, i.b} != {a, b}}
    assert len(got) == len(others)
    half_frame = 0.5 * float(np.median(np.diff(chair.t))) + 1e-9
    for item in others:  # the file holds frames: each time comes back as the nearest frame's
        assert any(
            g[:2] == item[:2] and np.allclose(g[2:], item[2:], rtol=0, atol=half_frame) for g in got
        ), item
    kept = phase_labels(chair, {(a, b): spans}).constraints
    assert len(demo.labels.constraints) == len(kept) > 0
    for c, k in zip(demo.labels.constraints, kept, strict=True):
        assert abs(c.time - k.time) <= half_frame and c == dataclasses.replace(k, time=c.time)
    with pytest.raises(OutputError, match="exists; pass --force"):
        write_phase_labels(path, chair, {(a, b): spans})
    write_phase_labels(path, chair, {(a, b): old}, force=True)
    assert (tmp_path / "chair.labels.kvg.bak").is_file()
    with pytest.raises(PhaseLabelError, match="has no body 'nobody'"):
        phase_labels(chair, {(a, "nobody"): spans})


def test_labelling_session_answers_and_marks(chair: Any, tmp_path: Path) -> None:
    from thirdhand.review.phase_labels import PhaseLabelling

    a, b = chair.labels.interaction_pairs()[0]
    truth = pair_intervals(chair.labels, a, b)
    edges = np.arange(0.0, 11.0)
    p_ab = np.array([0.9, 0.5, 0.5, 0.95, 0.1, 0.7, 0.05, np.nan, 0.45, 0.0])
    p_other = np.array([0.0, 0.0, 0.6, 0.6, 0.6, 0.6, 0.0, 0.0, 0.0, 0.0])
    other = ("nobody-hand", "nobody-part")
    s = PhaseLabelling(chair, [(a, b, p_ab, [(9.0, 9.5)]), (*other, p_other, [(2.0, 6.0)])], edges)
    # The recording's labels start the labelled pair; the CRF's intervals the other.
    assert s.labelled[(a, b)] == truth and s.labelled[other] == [(2.0, 6.0)]
    assert [(q.b, q.start) for q in s.questions] == [(other[1], 2.0), (b, 1.0), (b, 8.0), (b, 5.0)]
    s.mark((a, b), 7.5, 9.5, True)  # the person marks an interval first: 8..9 is not asked
    nxt = s.answer(False)  # "no" to the other pair's 2..6 s
    assert s.labelled[other] == [] and nxt is not None and (nxt.b, nxt.start) == (b, 1.0)
    assert s.answer(True) is not None and (s.question.b, s.question.start) == (b, 5.0)  # type: ignore[union-attr]
    assert s.answer(True) is None
    assert s.labelled[(a, b)] == set_span(
        set_span(set_span(truth, 7.5, 9.5, True), 1.0, 3.0, True), 5.0, 6.0, True
    )
    with pytest.raises(PhaseLabelError, match="no question left"):
        s.answer(True)
    with pytest.raises(PhaseLabelError, match="no pair x - y to label"):
        s.mark(("x", "y"), 0.0, 1.0, True)
    with pytest.raises(PhaseLabelError, match="has no body 'nobody-hand'"):
        s.write(tmp_path / "x.kvg")


@pytest.mark.slow
def test_phases_labelled_in_the_browser(chair: Any, tmp_path: Path) -> None:
    """Start labelling a 15 s excerpt: the most uncertain interval is asked first with the
    band; answer it, mark another interval by hand, save; segment train's reader reads it."""
    from tests.test_review_gui import CHROMIUM, CHROMIUM_ARGS, TIMEOUT_MS, Review

    if not CHROMIUM.exists():
        pytest.skip(f"{CHROMIUM} not found: install Debian's chromium package for browser tests")
    from playwright.sync_api import sync_playwright

    from thirdhand import io
    from thirdhand.review.app import ReviewApp
    from thirdhand.segment.cli import _with_labels
    from thirdhand.synth.task import truth_task
    from thirdhand.taskfile import save_task

    part = chair.slice(20.0, 35.0)
    path = tmp_path / "chair.task.json"
    save_task(truth_task(chair), path)
    app = ReviewApp(path, demos=[part], port=0, light_rendering=True)
    app.start()
    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
            try:
                page = browser.new_page(viewport={"width": 1280, "height": 900})
                page.goto(app.url)
                page.get_by_role("button", name="Save", exact=True).wait_for(timeout=TIMEOUT_MS)
                review = Review(app, page, path)
                page.get_by_text("Label phases", exact=True).click()
                review.button("Start labelling").click()
                review.wait_for(
                    lambda: app.labeller.labelling is not None, "the segmentation", 300.0
                )
                s = app.labeller.labelling
                assert s is not None
                first = s.question
                assert first is not None and first.score == max(q.score for q in s.questions)
                assert app.labeller.cursor.pair == (first.a, first.b)
                assert app.motion.time == pytest.approx(max(first.start, part.t[0]))
                page.locator("#th-band-q").wait_for(timeout=TIMEOUT_MS)
                page.get_by_text(first.text()).wait_for(timeout=TIMEOUT_MS)
                notice = page.locator(".mantine-Notification-root", has_text="Software WebGL")
                if notice.count():
                    notice.locator("button").first.click()
                page.locator("#th-phase-q").scroll_into_view_if_needed()
                review.shot("phase-labels")
                review.button("Interacting").click()
                review.wait_for(lambda: s.index >= 1, "the answer")
                pair = (first.a, first.b)
                assert any(a <= first.start and first.end <= b for a, b in s.labelled[pair])
                # Mark by hand: 22-23 s of the same pair is not an interaction.
                app.motion.set_time(22.0)
                review.button("From here").click()
                review.wait_for(
                    lambda: app.labeller.cursor.mark_from == pytest.approx(22.0), "the mark"
                )
                app.motion.set_time(23.0)
                review.button("not").click()
                review.wait_for(
                    lambda: app.labeller.cursor.mark_from is None, "the marked interval"
                )
                assert not any(a < 22.9 and b > 22.1 for a, b in s.labelled[pair])
                review.button("Save labels").click()
                saved = tmp_path / "chair.task.phases.kvg"
                review.wait_for(saved.is_file, "the label file")
            finally:
                browser.close()
    finally:
        app.stop()
    recording = tmp_path / "part.parquet"
    io.save(part, recording)
    (demo,) = _with_labels([recording], [saved])
    got = pair_intervals(demo.labels, *pair)
    np.testing.assert_allclose(got, snap_to_frames(s.labelled[pair], part.t), atol=1e-9)


def test_start_labelling_segments_outside_the_app_lock(
    chair: Any, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The segmentation (tens of seconds on a long recording) leaves the app's lock free:
    another tab's action gets it meanwhile (it held the lock throughout before)."""
    import threading

    import thirdhand.segment
    from thirdhand.review.app import ReviewApp
    from thirdhand.synth.task import truth_task
    from thirdhand.taskfile import save_task

    part = chair.slice(20.0, 30.0)
    path = tmp_path / "chair.task.json"
    save_task(truth_task(chair), path)
    app = ReviewApp(path, demos=[part], port=0, light_rendering=True)
    real = thirdhand.segment.segment_demonstration
    free: list[bool] = []

    def watched(demo: Any, *args: Any, **kwargs: Any) -> Any:
        def other_tab() -> None:
            got = app.lock.acquire(timeout=5.0)
            free.append(got)
            if got:
                app.lock.release()

        t = threading.Thread(target=other_tab)
        t.start()
        t.join()
        return real(demo, *args, **kwargs)

    monkeypatch.setattr(thirdhand.segment, "segment_demonstration", watched)
    app.start()
    try:
        app.attempt_long(app.labeller.start)
        assert free == [True]
        assert app.labeller.labelling is not None
        q = app.labeller.labelling.question  # the first question is shown, as before
        assert q is not None and app.labeller.cursor.pair == (q.a, q.b)
    finally:
        app.stop()
