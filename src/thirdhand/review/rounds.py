"""The question rounds of the review: clarification of constraints, labelling of phases.

A round's position is a frozen record; asking, answering and marking are pure
functions returning the next record (and the edit an answer makes). The app
keeps the current record and shows it.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

from thirdhand.demonstration import Demonstration
from thirdhand.errors import ThirdhandError
from thirdhand.review.clarify import Question, clarification_queue
from thirdhand.review.edits import Confirm
from thirdhand.review.focus import Focus, find_focus
from thirdhand.review.phase_labels import PhaseLabelling
from thirdhand.taskfile import TaskFile

Pair = tuple[str, str]


@dataclass(frozen=True)
class ClarificationRound:
    """The clarification round: its questions (the object in focus first, then least
    confident first), the one asked, and why the round starts where it does.

    Attributes
    ----------
    questions : tuple of Question
    index : int
        The question asked (``len(questions)``: the round is over).
    focus : Focus or None
        The object the person pointed at or looked at.
    """

    questions: tuple[Question, ...] = ()
    index: int = 0
    focus: Focus | None = None

    @property
    def question(self) -> Question | None:
        """The question being asked, None when the round is over."""
        if 0 <= self.index < len(self.questions):
            return self.questions[self.index]
        return None

    @property
    def focus_reason(self) -> str:
        """Why the question asked comes first (``"you pointed at leg3"``), or ``""``."""
        q = self.question
        if q is None or not q.focused or self.focus is None:
            return ""
        return self.focus.reason


def start_round(task: TaskFile, demo: Demonstration | None) -> ClarificationRound:
    """A new round over ``task``; its focus from the task's perception events, else
    from ``demo``'s pointing gestures (:func:`~thirdhand.review.focus.find_focus`)."""
    focus = find_focus(task, demo)
    queue = clarification_queue(task, focus=focus.object if focus is not None else None)
    return ClarificationRound(tuple(queue), 0, focus)


def answer_round(
    round_: ClarificationRound, yes: bool
) -> tuple[ClarificationRound, Confirm | None]:
    """Answer the question asked: yes confirms it (the edit returned); no leaves it for
    a correction (no edit). The round moves to the next question."""
    q = round_.question
    if q is None:
        raise ThirdhandError("no question to answer; start the clarification round")
    edit = Confirm(q.constraint, q.dof) if yes else None
    return replace(round_, index=round_.index + 1), edit


@dataclass(frozen=True)
class LabelCursor:
    """Where the person is in a phase labelling: the pair whose band is shown, and
    where a marked interval starts (s, None: no mark started)."""

    pair: Pair | None = None
    mark_from: float | None = None


def require_labelling(labelling: PhaseLabelling | None) -> PhaseLabelling:
    """The labelling under way; a refusal before one started."""
    if labelling is None:
        raise ThirdhandError("start labelling first")
    return labelling


def choose_pair(labelling: PhaseLabelling, cursor: LabelCursor, pair: Pair) -> LabelCursor:
    """Show the band of ``pair``."""
    if pair not in labelling.pairs:
        raise ThirdhandError(f"no pair {pair[0]} - {pair[1]} to label")
    return replace(cursor, pair=pair)


def marked_interval(cursor: LabelCursor, now: float) -> tuple[Pair, float, float]:
    """The pair and interval (s, in order) from the started mark to ``now``."""
    if cursor.mark_from is None or cursor.pair is None:
        raise ThirdhandError("mark where the interval starts first (From here)")
    a, b = sorted((cursor.mark_from, now))
    return cursor.pair, a, b


def phase_labels_path(task_path: Path) -> Path:
    """Where the phase labels of a task go: ``STEM.phases.kvg`` beside it."""
    return task_path.with_name(f"{task_path.stem}.phases.kvg")


__all__ = [
    "ClarificationRound",
    "LabelCursor",
    "answer_round",
    "choose_pair",
    "marked_interval",
    "phase_labels_path",
    "require_labelling",
    "start_round",
]
