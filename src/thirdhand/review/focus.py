"""The object a person singled out, from perception: what the clarification round asks first.

Where a person pointed or looked says which object they care about; the review
GUI's clarification round starts with that object's questions
(:func:`~thirdhand.review.clarify.clarification_queue` with ``focus=``) and says
why ("you pointed at leg3").

Two sources, in this order:

1. The task file's ``stages.perception`` block
   (:func:`thirdhand.perception.events.add_perception_events`, ``thirdhand
   gestures REC --task TASK``).
2. A loaded recording with tracked thumb, index and middle fingertips: its
   pointing gestures (:func:`thirdhand.perception.pointing.detect_pointing`,
   some 40 ms for an 80 s chair recording).

Without a time, the latest pointing event wins (latest end), else the longest
attention interval (the later one on a tie). At a time ``t`` (seconds on the
recording's time axis) the choice is :func:`thirdhand.perception.events.focus_object`'s:
the latest pointing event going on at ``t`` or ended at most ``lookback`` seconds
before, else the attention interval covering ``t``. Events naming nothing, or
an object the task does not have, are passed over.
"""

from __future__ import annotations

from dataclasses import dataclass

from thirdhand.demonstration import Demonstration
from thirdhand.perception.events import perception_events
from thirdhand.perception.pointing import detect_pointing, finger_roles
from thirdhand.task.stages import PerceptionBlock
from thirdhand.taskfile import TaskFile

#: Seconds a pointing gesture stays in focus after it ended (as ``focus_object``).
LOOKBACK = 5.0


@dataclass(frozen=True)
class Focus:
    """An object singled out by a person, and how.

    Attributes
    ----------
    object : str
        The object's name.
    t0, t1 : float, seconds
        The event's interval on the recording's time axis.
    kind : {"pointing", "attention"}
        Pointed at, or looked at.
    source : {"task", "recording"}
        Read from the task's perception block, or detected in a recording.
    """

    object: str
    t0: float
    t1: float
    kind: str
    source: str

    @property
    def reason(self) -> str:
        """Why the round starts here, for the person: ``"you pointed at leg3"``."""
        verb = "pointed at" if self.kind == "pointing" else "looked at"
        return f"you {verb} {self.object}"


def _events(block: PerceptionBlock, kind: str, known: set[str]) -> list[tuple[str, float, float]]:
    """``(object, t0, t1)`` of a block's usable events of one kind, in the block's order."""
    items = block.pointing if kind == "pointing" else block.attention
    return [
        (e.object, e.t0, e.t1)
        for e in items
        if e.object is not None and (not known or e.object in known)
    ]


def _pick(
    block: PerceptionBlock,
    known: set[str],
    t: float | None,
    source: str,
    lookback: float,
) -> Focus | None:
    """The focus among a perception block's events (module docstring), or None."""
    pointing = _events(block, "pointing", known)
    attention = _events(block, "attention", known)
    if t is not None:
        pointing = [e for e in pointing if e[1] <= t and e[2] >= t - lookback]
        attention = [a for a in attention if a[1] <= t <= a[2]]
    if pointing:
        # max keeps the first of equal keys: the block's time order, as focus_object
        return Focus(*max(pointing, key=lambda e: e[2]), kind="pointing", source=source)
    if not attention:
        return None
    if t is None:
        a = max(attention, key=lambda a: (a[2] - a[1], a[2]))
    else:
        a = attention[0]
    return Focus(*a, kind="attention", source=source)


def find_focus(
    task: TaskFile,
    demo: Demonstration | None = None,
    t: float | None = None,
    *,
    lookback: float = LOOKBACK,
) -> Focus | None:
    """The object a person singled out, how and when (module docstring), or None.

    Parameters
    ----------
    task : TaskFile
        Its ``stages.perception`` events come first.
    demo : Demonstration, optional
        A recording searched for pointing gestures when the task's events name
        no object (skipped without tracked thumb, index and middle fingertips).
    t : float, seconds, optional
        The moment asked about; None: the whole recording.
    lookback : float, seconds
        How long a pointing gesture stays in focus after it ended (with ``t``).

    Returns
    -------
    Focus or None

    """
    known = {o.name for o in task.objects}
    block = task.stages.perception
    if block is not None:
        found = _pick(block, known, t, "task", lookback)
        if found is not None:
            return found
    if demo is None or not finger_roles(demo):
        return None
    events = perception_events(pointing=detect_pointing(demo))
    return _pick(events, known, t, "recording", lookback)


def perception_focus(
    task: TaskFile, demo: Demonstration | None = None, t: float | None = None
) -> str | None:
    """The name of the object a person singled out (:func:`find_focus`), or None."""
    found = find_focus(task, demo, t)
    return None if found is None else found.object


__all__ = ["LOOKBACK", "Focus", "find_focus", "perception_focus"]
