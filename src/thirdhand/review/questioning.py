"""The question rounds in the app: thin shells keeping the round's record
(:mod:`~thirdhand.review.rounds`) and asking through a narrow host (the app)."""

from __future__ import annotations

import threading
from collections.abc import Iterable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Protocol

from thirdhand.demonstration import Demonstration
from thirdhand.errors import ThirdhandError
from thirdhand.review.clarify import Question
from thirdhand.review.edits import Edit
from thirdhand.review.motion import Motion
from thirdhand.review.phase_labels import PhaseLabelling, PhaseQuestion
from thirdhand.review.rounds import (
    ClarificationRound,
    LabelCursor,
    answer_round,
    choose_pair,
    marked_interval,
    phase_labels_path,
    require_labelling,
    start_round,
)
from thirdhand.review.view import ReviewView
from thirdhand.task.geometry import DOF_NAMES
from thirdhand.taskfile import TaskFile


class RoundHost(Protocol):
    """What a question round needs of the app."""

    lock: threading.RLock
    view: ReviewView
    demos: list[Demonstration]
    motion: Motion
    task_path: Path

    @property
    def task(self) -> TaskFile: ...

    def notify(self, text: str, *, error: bool = False) -> None: ...

    def say(self, text: str) -> None: ...

    def refresh(self) -> None: ...

    def apply(self, edit: Edit, *, operation: str | None = None) -> None: ...

    def animate_dofs(
        self, constraint_id: str | None = None, dofs: Iterable[str] = DOF_NAMES
    ) -> None: ...


class Clarifier:
    """The clarification round: each question selects its object and animates its DOFs.

    Attributes
    ----------
    round : ClarificationRound
    """

    def __init__(self, host: RoundHost) -> None:
        self.host = host
        self.round = ClarificationRound()

    @property
    def question(self) -> Question | None:
        """The question being asked, None when the round is over."""
        return self.round.question

    def start(self) -> Question | None:
        """Build the question queue (the object in focus, then least confident first); ask."""
        host = self.host
        with host.lock:
            demo = demo_of(host.demos, host.motion.demo_index)
            self.round = start_round(host.task, demo)
            return self._ask()

    def answer(self, yes: bool) -> Question | None:
        """Answer the current question: yes confirms it; no leaves it for a correction.

        Returns the next question (None when the round is over).
        """
        host = self.host
        with host.lock:
            q = self.round.question
            self.round, edit = answer_round(self.round, yes)
            if edit is not None:
                host.apply(edit, operation="confirm")
            elif q is not None:
                host.notify(f"Correct {q.constraint} in the Correct panel, then go on")
            return self._ask()

    def _ask(self) -> Question | None:
        host = self.host
        q = self.round.question
        if q is None:
            host.notify("Clarification done: every question answered")
            host.refresh()
            return None
        c = host.task.constraint_by_id(q.constraint)
        host.view = replace(host.view, selected=c.child)
        host.refresh()
        host.animate_dofs(c.id, [q.dof] if q.dof is not None else list(DOF_NAMES))
        return q


class Labeller:
    """Phase labelling of the recording shown, for calibration (``segment train``).

    Attributes
    ----------
    labelling : PhaseLabelling or None
        None until started.
    cursor : LabelCursor
        The pair whose band is shown and where a marked interval starts.
    """

    def __init__(self, host: RoundHost) -> None:
        self.host = host
        self.labelling: PhaseLabelling | None = None
        self.cursor = LabelCursor()

    def start(self) -> PhaseQuestion | None:
        """Segment the recording shown and ask about its most uncertain intervals first.

        The segmentation (tens of seconds on a long recording) runs outside the
        app's lock, so the other panels and tabs stay responsive meanwhile.
        """
        host = self.host
        with host.lock:
            i = host.motion.demo_index
            if i >= len(host.demos):
                raise ThirdhandError("phases are labelled on a recording of the person (--demo)")
            demo = host.demos[i]
            host.say("labelling: segmenting the recording…")
        from thirdhand.segment import segment_demonstration

        labelling = PhaseLabelling.from_segmentation(demo, segment_demonstration(demo))
        with host.lock:
            self.labelling = labelling
            self.cursor = LabelCursor(labelling.pairs[0], None)
            return self._ask()

    def _ask(self) -> PhaseQuestion | None:
        host = self.host
        q = require_labelling(self.labelling).question
        if q is None:
            host.notify("Labelling: every uncertain interval answered")
        else:
            self.cursor = replace(self.cursor, pair=(q.a, q.b))
            host.motion.set_time(q.start)
        host.refresh()
        return q

    def answer(self, yes: bool) -> PhaseQuestion | None:
        """Answer the phase question: its interval is (``yes``) or is not an interaction."""
        with self.host.lock:
            require_labelling(self.labelling).answer(yes)
            return self._ask()

    def choose_pair(self, pair: tuple[str, str]) -> None:
        """Show the band of ``pair`` (its marginal and labels)."""
        with self.host.lock:
            self.cursor = choose_pair(require_labelling(self.labelling), self.cursor, pair)
            self.host.refresh()

    def mark_from_here(self) -> None:
        """The marked interval starts at the playback time."""
        host = self.host
        with host.lock:
            require_labelling(self.labelling)
            t = host.motion.time
            self.cursor = replace(self.cursor, mark_from=t)
            host.say(f"labelling: from {t:.2f} s; play on, then mark to here")
            host.refresh()

    def mark_to_here(self, value: bool) -> None:
        """Mark the shown pair interacting (``value``) or not from the mark to the playback time."""
        host = self.host
        with host.lock:
            labelling = require_labelling(self.labelling)
            pair, a, b = marked_interval(self.cursor, host.motion.time)
            labelling.mark(pair, a, b, value)
            what = "interacting" if value else "not interacting"
            host.say(f"labelling: {pair[0]} - {pair[1]} {what} {a:.2f}-{b:.2f} s")
            self.cursor = replace(self.cursor, mark_from=None)
            host.refresh()

    def save(self) -> Path:
        """Write the labels next to the task (``STEM.phases.kvg``; the previous one kept as
        a numbered backup): ``thirdhand segment train/calibrate --labels`` reads it."""
        host = self.host
        with host.lock:
            path = phase_labels_path(host.task_path)
            out = require_labelling(self.labelling).write(path, force=True)
            host.notify(f"Saved the phase labels in {out.name}")
            return out


def demo_of(demos: Sequence[Demonstration], index: int) -> Demonstration | None:
    """The recording of the person at ``index`` (the first when it is a replay)."""
    if not demos:
        return None
    return demos[index if index < len(demos) else 0]


__all__ = ["Clarifier", "Labeller", "RoundHost", "demo_of"]
