"""The simulated run as phases: the planned motions with the gripper's and the person's pauses.

A pure function of the plan's segments: the fingers close before the first
segment the planner carried the part in (``close``), the person fastens a part
placed by an ``insert`` segment (``fasten``), the fingers open before the hand
moves off (``open``), and after the last motion the assembly rests (``rest``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from thirdhand.simulate.plan import Span
from thirdhand.simulate.settings import SimulateSettings


@dataclass(frozen=True)
class Phase:
    """One phase of the simulated run.

    Attributes
    ----------
    kind : str
        ``move`` (track the plan from ``t_start`` to ``t_end``), ``close``, ``fasten``,
        ``open`` or ``rest`` (hold the last planned configuration ``duration`` seconds).
    step : int
        Index of the plan step it belongs to (-1: none).
    segment : str
        The planned segment's name (a move), else the kind.
    part : str or None
        The part held (a move, close) or let go (fasten, open).
    t_start, t_end : float
        Planned clock of a move, seconds (0 otherwise).
    duration : float
        Simulated seconds (a move's planned span times ``slowdown``).
    """

    kind: str
    step: int
    segment: str
    part: str | None
    t_start: float
    t_end: float
    duration: float


def schedule(spans: Sequence[Span], settings: SimulateSettings) -> list[Phase]:
    """The phases of a run of planned segments ``spans`` (in time order)."""
    out: list[Phase] = []
    held: str | None = None
    last: Span | None = None

    def hold(kind: str, step: int, part: str | None, duration: float) -> None:
        out.append(Phase(kind, step, kind, part, 0.0, 0.0, duration))

    for span in spans:
        if held is not None and span.attached != held and last is not None:
            if last.segment == "insert":
                hold("fasten", last.step, held, settings.fasten_time)
            hold("open", last.step, held, settings.open_time)
        if span.attached is not None and span.attached != held:
            hold("close", span.step, span.attached, settings.close_time)
        out.append(
            Phase("move", span.step, span.segment, span.attached, span.t_start, span.t_end,
                  max(span.t_end - span.t_start, 0.0) * settings.slowdown)
        )  # fmt: skip
        held = span.attached
        last = span
    if held is not None and last is not None:
        if last.segment == "insert":
            hold("fasten", last.step, held, settings.fasten_time)
        hold("open", last.step, held, settings.open_time)
    hold("rest", -1, None, settings.rest_time)
    return out
