"""What the assist fetches and when: the next part, a retry after a failure, the end.

Decisions over the plan tracker (:class:`~thirdhand.live.tracker.PlanTracker`) and the
bodies as tracked now, by row of the stream: ``pos`` (n, 3) world metres, ``quat``
(n, 4) x y z w, ``valid`` (n,) seen now.

- :func:`person_started`: the assist waits for the person's first part.
- :func:`next_fetch`: the step and the part to fetch (:func:`may_retry`: a part the
  arm could not fetch, :class:`FailedFetch`, only once it or what was near it moved).
- :func:`mounting_poses`: where the part the person is mounting may go (the arm plans
  around it).
- :func:`assist_end`: whether an assist ends (a hand took a part of its kind), and how.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from thirdhand import se3
from thirdhand.arrays import BoolArray, FloatArray
from thirdhand.live.tracker import PlanTracker

#: Outcomes of a fetch the arm could not do; the assist ends at once and another part is tried.
FAILED = ("unreachable", "no path")
#: A part the arm could not fetch is tried again once it, or a hand or part that was within
#: :data:`RETRY_NEAR_M` of it, moved this far, metres (a hand working beside it, a part
#: lying against it, that blocked its grasp or its lift), and not before
#: :data:`RETRY_AFTER_S` (a hand moving about it would have it planned at every step).
RETRY_MOVED_M = 0.05
RETRY_NEAR_M = 0.3
RETRY_AFTER_S = 0.5


@dataclass(frozen=True)
class FailedFetch:
    """A part the arm could not fetch.

    Attributes
    ----------
    when_s : float
        Stream clock of the failure, seconds.
    where : ndarray, shape (3,)
        Where the part was when the fetch was decided, world metres.
    near : mapping of int to ndarray of shape (3,)
        The hands and parts (by row) within :data:`RETRY_NEAR_M` of it then, and where
        they were.
    """

    when_s: float
    where: FloatArray
    near: Mapping[int, FloatArray]


@dataclass(frozen=True)
class AssistEnd:
    """How an assist ends: the parts of its kind a hand took (comma-separated, sorted;
    empty: none is needed any more) and its outcome."""

    taken: str
    outcome: str


class Mounting(NamedTuple):
    """Where the part being mounted may go: its row, position (3,) and quaternion (4,), world."""

    row: int
    pos: FloatArray
    quat: FloatArray


def person_started(held: Collection[str], tracker: PlanTracker) -> bool:
    """Whether the person has started: a part in hand, a step in progress or one done."""
    return bool(held or tracker.current is not None or tracker.done)


def failed_fetch(
    t: float,
    where: FloatArray,
    pos: FloatArray,
    valid: BoolArray,
    rows: Sequence[int],
    part: int,
) -> FailedFetch:
    """The failure at ``t`` of the fetch of the part of row ``part`` tried where it was,
    ``where`` (3,): with the bodies of ``rows`` seen now within :data:`RETRY_NEAR_M`."""
    near = {
        i: pos[i].copy()
        for i in rows
        if i != part and valid[i] and float(np.linalg.norm(pos[i] - where)) < RETRY_NEAR_M
    }
    return FailedFetch(t, where, near)


def may_retry(
    failed: FailedFetch | None, part: int, t: float, pos: FloatArray, valid: BoolArray
) -> bool:
    """Whether the part of row ``part`` may be fetched at ``t``: never failed (``failed``
    None), or since it failed (at least :data:`RETRY_AFTER_S` ago) it or a hand or part
    that was near it (and is seen now) has moved :data:`RETRY_MOVED_M`."""
    if failed is None:
        return True
    if t - failed.when_s < RETRY_AFTER_S:
        return False
    moved = [(part, failed.where), *((i, p) for i, p in failed.near.items() if valid[i])]
    return any(float(np.linalg.norm(pos[i] - p)) > RETRY_MOVED_M for i, p in moved)


def next_fetch(
    tracker: PlanTracker,
    names: Sequence[str],
    *,
    handled: Collection[str],
    failed: Mapping[str, FailedFetch],
    t: float,
    pos: FloatArray,
    valid: BoolArray,
    base: FloatArray,
) -> tuple[int, int] | None:
    """The step and the row of the part to fetch at ``t``, or None.

    The next part the person will need: the first step not done other than the one in
    progress, that the plan allows now or once the one in progress is done (the back of
    a chair waits for its legs: fetched at once, it would be held at the hand-over for a
    minute, and the arm could fetch nothing else), with a part no hand has held yet
    (``handled``: one the person took is theirs: put down a moment while they mount it,
    it is not fetched from under their hands), seen now and not failed (:func:`may_retry`).
    Of those, the nearest (horizontally) to where the base stands, ``base`` (3,), so
    that it drives only for a part out of the arm's reach from there.
    """
    for step in tracker.coming():
        if step == tracker.current:
            continue
        cands = [c for c in tracker.candidates_for(step) if c not in handled]
        idx = [
            i
            for i in (names.index(c) for c in cands)
            if valid[i] and may_retry(failed.get(names[i]), i, t, pos, valid)
        ]
        if not idx:
            continue
        part = min(idx, key=lambda i: float(np.linalg.norm(pos[i][:2] - base[:2])))
        return step, part
    return None


def mounting_poses(
    tracker: PlanTracker,
    names: Sequence[str],
    parts: Collection[int],
    *,
    held: Collection[str],
    pos: FloatArray,
    quat: FloatArray,
    valid: BoolArray,
) -> list[Mounting]:
    """Where the part the person is mounting may go.

    While a step is in progress (:attr:`PlanTracker.current`), a part (of the rows
    ``parts``) a hand holds (``held``) that no done step uses, at the learned pose in its
    parent (as tracked now, world frame) of every step not done that it may fill and that
    may come next (:meth:`PlanTracker.coming`): an interchangeable leg may go to any free
    corner. Empty when no step is in progress.
    """
    if tracker.current is None:
        return []
    used = tracker.used_children()
    out = []
    for step in tracker.coming():
        slot = tracker.slots[step]
        for p, c in slot.candidates:
            name = names[c]
            if name in held and name not in used and valid[p] and c in parts:
                where = pos[p] + se3.quat_rotate(quat[p], slot.pos)
                out.append(Mounting(c, where, np.asarray(se3.quat_multiply(quat[p], slot.quat))))
    return out


def assist_end(
    *,
    step: int,
    part: str,
    held_at_start: Collection[str],
    ready_s: float | None,
    outcome: str,
    t: float,
    held: Collection[str],
    used: Collection[str],
    tracker: PlanTracker,
) -> AssistEnd | None:
    """How the assist fetching ``part`` for ``step`` ends at ``t``, or None: it goes on.

    Interchangeable parts: the robot's part serves whichever step of its kind comes
    next; the assist ends when a hand takes (``held``, not held when it started, not
    ``used`` by a done step) a part of that kind, or when no step not done needs the
    part. A moving assist is then ``ready`` if its part was at the hand-over by ``t``
    (``ready_s``), else ``late``; another outcome stays.
    """
    parts = set(tracker.candidates_for(step)) | {part}
    taken = (set(held) & parts) - set(held_at_start) - set(used)
    coming = [i for i in range(len(tracker.slots)) if i not in tracker.done]
    needed = any(part in tracker.candidates_for(i) for i in coming)
    if needed and not taken:
        return None
    if outcome == "moving":
        outcome = "ready" if ready_s is not None and ready_s <= t else "late"
    return AssistEnd(", ".join(sorted(taken)), outcome)


__all__ = [
    "FAILED",
    "RETRY_AFTER_S",
    "RETRY_MOVED_M",
    "RETRY_NEAR_M",
    "AssistEnd",
    "FailedFetch",
    "Mounting",
    "assist_end",
    "failed_fetch",
    "may_retry",
    "mounting_poses",
    "next_fetch",
]
