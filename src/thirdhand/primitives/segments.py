"""Segments per constraint: the motion that makes each constraint, in the parent's frame.

For each constraint event, the child's pose relative to the parent between the
previous keyframe (or, later, the moment the child starts moving) and the
event time. One demonstration may hold several examples of a kind of motion
(the four legs of a chair); grouping is up to the caller (:func:`group_segments`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import uniform_filter1d

from thirdhand.arrays import FloatArray
from thirdhand.demonstration import ConstraintEvent, Demonstration
from thirdhand.primitives.checks import PrimitiveError


@dataclass(frozen=True)
class ConstraintSegment:
    """The child's motion in the parent's frame up to the moment a constraint is made.

    Attributes
    ----------
    event : ConstraintEvent
        The constraint (parent, child, type, symbol, pose in the parent frame).
    t : ndarray, shape (n,)
        Seconds on the demonstration's time axis (valid samples only).
    pos : ndarray, shape (n, 3)
        Child origin in the parent frame, metres.
    quat : ndarray, shape (n, 4)
        Child orientation in the parent frame, x y z w, sign-continuous.
    source : str
        Where it came from (the demonstration's ``meta["source"]`` or ``"demo"``).
    n_missing : int
        Samples dropped in the interval because a body was not tracked.
    """

    event: ConstraintEvent
    t: FloatArray
    pos: FloatArray
    quat: FloatArray
    source: str = "demo"
    n_missing: int = 0

    @property
    def key(self) -> str:
        """The constraint's symbol, or ``parent->child`` when it has none."""
        return self.event.symbol or f"{self.event.parent}->{self.event.child}"

    @property
    def duration(self) -> float:
        """Seconds from first to last sample."""
        return float(self.t[-1] - self.t[0])


def motion_start(
    demo: Demonstration, body: str, t0: float, t1: float, *, speed: float = 0.02, window: int = 9
) -> float:
    """First time in ``[t0, t1]`` the body moves faster than ``speed`` m/s (world frame).

    The speed is smoothed by a moving average of ``window`` samples; if the body
    never moves in the interval, ``t0`` is returned.
    """
    sel = (demo.t >= t0) & (demo.t <= t1)
    idx = np.flatnonzero(sel)
    if idx.size < 3:
        return t0
    p = demo.pos(body)[idx]
    ok = np.isfinite(p).all(axis=1)
    if ok.sum() < 3:
        return t0
    tt = demo.t[idx][ok]
    v = np.linalg.norm(np.gradient(p[ok], tt, axis=0), axis=1)
    v = uniform_filter1d(v, size=window, mode="nearest")
    moving = np.flatnonzero(v > speed)
    if moving.size == 0:
        return t0
    k = max(int(moving[0]) - 1, 0)
    return float(tt[k])


def split_segments(
    demo: Demonstration,
    *,
    keyframe_times: Sequence[float] | None = None,
    events: Sequence[ConstraintEvent] | None = None,
    speed: float = 0.02,
    min_samples: int = 3,
) -> tuple[list[ConstraintSegment], list[str]]:
    """One segment per constraint event, and why the events without one have none.

    A constraint made before its child was tracked moving towards it (made at
    the very start of the recording, or while a tag was hidden) has fewer than
    ``min_samples`` valid samples of approach: there is no motion to learn from,
    so it is left out with a one-line reason instead of ending the stage.
    Parameters as :func:`constraint_segments`.

    Returns
    -------
    segments : list of ConstraintSegment, in event order
    skipped : list of str
        One line per event left out: the constraint, the interval and the count.

    Raises
    ------
    PrimitiveError
        If there is no constraint event.
    """
    evs = [e for e in (demo.labels.constraints if events is None else events) if not e.removed]
    if not evs:
        raise PrimitiveError("constraint segments: the demonstration has no constraint event")
    evs.sort(key=lambda e: e.time)
    keys = sorted(e.time for e in evs) if keyframe_times is None else sorted(keyframe_times)
    source = str(demo.meta.get("source", "demo"))
    out = []
    skipped = []
    for ev in evs:
        before = [k for k in keys if k < ev.time - 1e-9]
        t_prev = before[-1] if before else float(demo.t[0])
        t_start = motion_start(demo, ev.child, t_prev, ev.time, speed=speed)
        pos, quat, valid = demo.relative_pose(ev.parent, ev.child)
        sel = (demo.t >= t_start) & (demo.t <= ev.time + 1e-9)
        ok = sel & valid
        name = f"constraint {ev.symbol or ''} {ev.parent}->{ev.child} at {ev.time:.3f} s"
        if ok.sum() < min_samples:
            skipped.append(
                f"{source}: {name}: expected at least {min_samples} tracked samples in "
                f"[{t_start:.3f}, {ev.time:.3f}] s, got {int(ok.sum())} (no approach motion "
                "to learn from)"
            )
            continue
        out.append(
            ConstraintSegment(ev, demo.t[ok], pos[ok], quat[ok], source, int(sel.sum() - ok.sum()))
        )
    return out, skipped


def constraint_segments(
    demo: Demonstration,
    *,
    keyframe_times: Sequence[float] | None = None,
    events: Sequence[ConstraintEvent] | None = None,
    speed: float = 0.02,
    min_samples: int = 3,
) -> list[ConstraintSegment]:
    """Extract one segment per constraint event.

    Parameters
    ----------
    demo : Demonstration
    keyframe_times : sequence of float, optional
        Keyframe times, seconds; default the times of the constraint events (the
        ground truth). A segment starts at the latest keyframe before its event,
        or later, when the child starts moving (``speed``, m/s).
    events : sequence of ConstraintEvent, optional
        Constraint events; default ``demo.labels.constraints`` (removals skipped).
    speed : float
        Speed threshold of :func:`motion_start`, m/s.
    min_samples : int
        Fewest valid samples a segment must have.

    Returns
    -------
    list of ConstraintSegment, in event order

    Raises
    ------
    PrimitiveError
        If there is no constraint event, or a segment has fewer than
        ``min_samples`` valid samples (naming the constraint and the interval);
        :func:`split_segments` leaves such a segment out instead.
    """
    out, skipped = split_segments(
        demo, keyframe_times=keyframe_times, events=events, speed=speed, min_samples=min_samples
    )
    if skipped:
        raise PrimitiveError(skipped[0].removesuffix(" (no approach motion to learn from)"))
    return out


def group_segments(
    segments: Sequence[ConstraintSegment],
    key: Callable[[ConstraintSegment], str] | None = None,
) -> dict[str, list[ConstraintSegment]]:
    """Group segments (e.g. of several demonstrations) by symbol, or by ``key(segment)``."""
    groups: dict[str, list[ConstraintSegment]] = {}
    for s in segments:
        groups.setdefault(s.key if key is None else key(s), []).append(s)
    return groups
