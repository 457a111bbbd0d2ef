"""The plan tracker's view of what comes next."""

from __future__ import annotations

import numpy as np

from thirdhand.live.state import Slot
from thirdhand.live.tracker import PlanTracker, RecognisedStep


def _tracker(predecessors: list[list[int]]) -> PlanTracker:
    ident = np.array([0.0, 0.0, 0.0, 1.0])
    zero = np.zeros(3)
    slots = [
        Slot(
            i, f"c{i}", "seat", f"leg{i}", zero, ident, zero, ident, np.zeros((6, 2)), [(0, i + 1)]
        )
        for i in range(len(predecessors))
    ]
    names = ["seat"] + [f"leg{i}" for i in range(len(predecessors))]
    return PlanTracker(slots, predecessors, names)


def _done(tracker: PlanTracker, *steps: int) -> None:
    for i in steps:
        tracker.done[i] = RecognisedStep(i, f"c{i}", "seat", f"leg{i}", 1.0, 0.5, True)


def test_coming_steps_are_the_available_then_those_after_the_one_in_progress() -> None:
    """The chair's learned plan: legs 0 → 1 → 3, leg 2 free, the back (4) after 2 and 3.
    The back comes only once the legs it follows are done or in progress."""
    t = _tracker([[], [0], [], [1], [2, 3]])
    assert t.coming() == [0, 2]
    t.current = 0
    assert t.coming() == [0, 2, 1]
    _done(t, 0, 2)
    t.current = 1
    assert t.available() == [1] and t.coming() == [1, 3]
    _done(t, 1)
    t.current = 3
    assert t.coming() == [3, 4]
    t.current = None
    assert t.coming() == [3]
    _done(t, 3, 4)
    assert t.coming() == []
