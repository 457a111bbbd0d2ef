"""Plan tracking: which steps are done, which one the person is in, what comes next.

Fed the constraint events of :class:`~thirdhand.live.state.ConstraintState`
and the hands of :class:`~thirdhand.live.filter.OnlinePhases`:

- a step is **done** when its constraint forms, whichever interchangeable
  parts made it (the stream's ``parent`` and ``child`` are recorded), and in
  whatever order: a step done before one of its predecessors is recorded with
  ``in_order: false``, never ignored;
- a step is **undone** when its constraint breaks (the part was taken out):
  it is no longer done and becomes available again;
- **available** (next) steps: not done, every predecessor of the plan's
  partial order done;
- the **current** step: the available step whose child (or a part
  interchangeable with it, not already used) a hand is holding, else none;
- a **dropped stream** (no frame for ``drop_s`` seconds of the stream's clock)
  is recorded as an interval; constraint dwell counters restart after it, so
  nothing is recognised from before the gap.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from thirdhand.live.state import Slot, StateEvent


@dataclass
class RecognisedStep:
    """One recognition of a plan step.

    Attributes
    ----------
    step : int
        Plan step index.
    constraint : str
    parent, child : str
        The stream's bodies that made it.
    recognised_s : float
        Stream time at which the loop recognised it.
    since_s : float
        Stream time from which the pose was continuously near the constraint.
    in_order : bool
        Whether every predecessor of the plan was done at that moment.
    undone_s : float or None
        When its constraint broke again, if it did.
    """

    step: int
    constraint: str
    parent: str
    child: str
    recognised_s: float
    since_s: float
    in_order: bool
    undone_s: float | None = None


@dataclass
class PlanTracker:
    """Progress through a plan, updated by constraint events.

    Parameters
    ----------
    slots : list of Slot
    predecessors : list of list of int
        Per step, the steps it must follow (``TaskFile.predecessors()``).
    names : sequence of str
        The stream's body names (rows).
    """

    slots: list[Slot]
    predecessors: list[list[int]]
    names: Sequence[str]
    done: dict[int, RecognisedStep] = field(default_factory=dict)
    history: list[RecognisedStep] = field(default_factory=list)
    current: int | None = None

    def apply(self, event: StateEvent) -> RecognisedStep | None:
        """Record a formed or broken constraint; return the step recognised or undone."""
        if event.kind == "formed":
            in_order = all(p in self.done for p in self.predecessors[event.step])
            rec = RecognisedStep(
                event.step,
                event.constraint,
                event.parent,
                event.child,
                event.time,
                event.since,
                in_order,
            )
            self.done[event.step] = rec
            self.history.append(rec)
            return rec
        if event.kind == "broken" and event.step in self.done:
            rec = self.done.pop(event.step)
            rec.undone_s = event.time
            return rec
        return None

    def available(self) -> list[int]:
        """Steps not done whose predecessors are all done (what may come next)."""
        return [
            i
            for i in range(len(self.slots))
            if i not in self.done and all(p in self.done for p in self.predecessors[i])
        ]

    def coming(self) -> list[int]:
        """Steps not done that may come next: the available ones (plan order), then those
        whose predecessors are done or the step in progress (:attr:`current`)."""
        after = [
            i
            for i in range(len(self.slots))
            if i not in self.done
            and all(p in self.done or p == self.current for p in self.predecessors[i])
        ]
        return list(dict.fromkeys(self.available() + after))

    def used_children(self) -> set[str]:
        """Stream bodies already in a done step's slot."""
        return {r.child for r in self.done.values()}

    def candidates_for(self, step: int) -> list[str]:
        """Stream bodies that could make ``step`` now (interchangeable, not used)."""
        used = self.used_children()
        out = []
        for _, c in self.slots[step].candidates:
            name = self.names[c]
            if name not in used and name not in out:
                out.append(name)
        return out

    def update_current(self, holding: dict[tuple[str, str], bool]) -> int | None:
        """The available step whose part a hand holds (first in plan order), else None."""
        held = {obj for (_, obj), h in holding.items() if h}
        self.current = None
        for i in self.available():
            if any(c in held for c in self.candidates_for(i)):
                self.current = i
                break
        return self.current


__all__ = ["PlanTracker", "RecognisedStep"]
