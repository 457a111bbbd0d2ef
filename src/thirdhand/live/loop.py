"""The live loop: one update per frame, with its latency measured.

Per frame: the causal CRF (:class:`~thirdhand.live.filter.OnlinePhases`) takes
the frame and, when a latent step completes, filters the new rows; the
constraint state stores the frame and, once per latent step (on a frame where
the CRF did no work, so the two costs do not add up), is evaluated; its events
move the plan tracker. The wall-clock cost of each frame's update is measured
(``time.perf_counter``), with its CPU time (``time.thread_time``) and how late
the frame's processing finished after the frame arrived.
"""

from __future__ import annotations

import gc
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from thirdhand.demonstration import BodyInfo
from thirdhand.live.assist import AssistOptions, RobotAssist
from thirdhand.live.filter import SMOOTHER_LAG, OnlinePhases
from thirdhand.live.handover import assembly_reach
from thirdhand.live.source import Frame, FrameSource
from thirdhand.live.state import (
    ConstraintState,
    LiveTaskError,
    Slot,
    StateEvent,
    StateOptions,
    plan_slots,
    task_tolerances,
)
from thirdhand.live.tracker import PlanTracker
from thirdhand.segment.model import SegmentModel
from thirdhand.taskfile import TaskFile

#: Seconds without a frame after which the stream counts as dropped.
DROP_S = 2.0


@dataclass(frozen=True)
class LiveOptions:
    """Options of the live loop (defaults: the measured best).

    Attributes
    ----------
    state : StateOptions
        How constraints are recognised.
    smoother_lag : int
        Fixed-lag smoother lag of the CRF, latent steps.
    drop_s : float
        A gap of the stream's clock longer than this is a dropped stream, seconds.
    assist : AssistOptions or None
        Run the robot assist (:mod:`thirdhand.live.assist`) with these options; None: off.
    rate_hz : float
        Nominal frame rate, Hz (buffer sizes only).
    """

    state: StateOptions = field(default_factory=StateOptions)
    smoother_lag: int = SMOOTHER_LAG
    drop_s: float = DROP_S
    assist: AssistOptions | None = None
    rate_hz: float = 120.0


def check_bodies(task: TaskFile, bodies: Sequence[BodyInfo], source: str) -> None:
    """Every part and tool of the task must be a body of the stream.

    Raises
    ------
    LiveTaskError
        One line naming the missing objects and the stream's bodies.
    """
    have = {b.name for b in bodies}
    want = [o.name for o in task.objects if o.kind in ("part", "tool")]
    missing = [n for n in want if n not in have]
    if missing:
        parts = sorted(b.name for b in bodies if b.kind in ("part", "tool")) or sorted(have)
        raise LiveTaskError(
            f"{source}: the recording's bodies do not match the task's objects: missing "
            f"{', '.join(missing)} (the recording has {', '.join(parts)})"
        )


def _stats(values: Sequence[float]) -> dict[str, float | None]:
    if not values:
        return {"median": None, "p99": None, "max": None}
    a = np.asarray(values, dtype=np.float64) * 1e3
    return {
        "median": round(float(np.median(a)), 4),
        "p99": round(float(np.percentile(a, 99)), 4),
        "max": round(float(a.max()), 4),
    }


@dataclass
class LiveReport:
    """What a live run saw and did.

    Attributes
    ----------
    frames : int
    t0, t1 : float
        First and last frame times, stream clock, seconds.
    latency : list of float
        Wall-clock seconds of each frame's update.
    cpu : list of float
        CPU seconds of each frame's update.
    late : list of float
        Seconds from each frame's arrival to the end of its processing.
    tracker : PlanTracker
    events : list of StateEvent
    dropped : list of (float, float)
        Stream-clock intervals without any frame longer than ``drop_s``.
    current : list of (float, int or None)
        Changes of the current step (time, step).
    lags : dict
        Documented lags, seconds (features, smoother, constraint window and dwell).
    assists : list of dict
        The robot's assists (part, start, end, outcome).
    """

    frames: int = 0
    t0: float = float("nan")
    t1: float = float("nan")
    latency: list[float] = field(default_factory=list)
    cpu: list[float] = field(default_factory=list)
    late: list[float] = field(default_factory=list)
    tracker: PlanTracker | None = None
    events: list[StateEvent] = field(default_factory=list)
    dropped: list[tuple[float, float]] = field(default_factory=list)
    current: list[tuple[float, int | None]] = field(default_factory=list)
    lags: dict[str, float] = field(default_factory=dict)
    assists: list[dict[str, Any]] = field(default_factory=list)
    assist_time: list[float] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        """The ``--json`` document (``"format": "thirdhand.live/1"``)."""
        tr = self.tracker
        steps = []
        if tr is not None:
            for r in tr.history:
                steps.append(
                    {
                        "step": r.step + 1,
                        "constraint": r.constraint,
                        "parent": r.parent,
                        "child": r.child,
                        "recognised_s": round(r.recognised_s, 4),
                        "since_s": round(r.since_s, 4),
                        "in_order": r.in_order,
                        "undone_s": None if r.undone_s is None else round(r.undone_s, 4),
                    }
                )
        return {
            "format": "thirdhand.live/1",
            "frames": self.frames,
            "stream_s": [round(self.t0, 4), round(self.t1, 4)],
            "latency_ms": _stats(self.latency),
            "cpu_ms": _stats(self.cpu),
            "late_ms": _stats(self.late),
            "lags_s": self.lags,
            "steps": steps,
            "done": [] if tr is None else sorted(i + 1 for i in tr.done),
            "next": [] if tr is None else [i + 1 for i in tr.available()],
            "dropped": [{"start_s": round(a, 4), "end_s": round(b, 4)} for a, b in self.dropped],
            "current": [
                {"time_s": round(t, 4), "step": None if s is None else s + 1}
                for t, s in self.current
            ],
            "assists": [self._served(a) for a in self.assists],
            "assist_ms": _stats(self.assist_time),
        }

    def _served(self, assist: dict[str, Any]) -> dict[str, Any]:
        """``assist`` with ``served_step``: the plan step the part taken went into.

        An assist ends when a hand takes a part of its kind (``taken``); the first
        step recognised afterwards with that part as its child is the slot the
        robot's part served (with interchangeable legs, not necessarily the step
        it was fetched for, ``step``). None when no such step was recognised.
        """
        taken = {p.strip() for p in str(assist.get("taken") or "").split(",") if p.strip()}
        end = assist.get("end")
        served = None
        if taken and end is not None and self.tracker is not None:
            after = [r for r in self.tracker.history if r.child in taken and r.recognised_s >= end]
            if after:
                served = min(after, key=lambda r: r.recognised_s).step + 1
        return {**assist, "served_step": served}


class LiveLoop:
    """Follow a person through a task's plan from a stream of frames.

    Parameters
    ----------
    task : TaskFile
    bodies : sequence of BodyInfo
        The stream's bodies (rows of its frames).
    meta : mapping
        The stream's metadata.
    model : SegmentModel, optional
        The segmentation model (default: the shipped one).
    options : LiveOptions, optional
    source_name : str
        For error messages.

    Raises
    ------
    LiveTaskError
        A task without a plan, or stream bodies not matching the task's objects.
    """

    def __init__(
        self,
        task: TaskFile,
        bodies: Sequence[BodyInfo],
        meta: Mapping[str, Any],
        model: SegmentModel | None = None,
        options: LiveOptions | None = None,
        *,
        source_name: str = "the stream",
    ) -> None:
        self.options = LiveOptions() if options is None else options
        names = [b.name for b in bodies]
        if not task.plan:
            plan_slots(task, names, meta)  # raises the one-line error
        check_bodies(task, bodies, source_name)
        self.names = names
        slots = plan_slots(task, names, meta)
        opt = self.options
        self.phases = OnlinePhases(bodies, meta, model, lag=opt.smoother_lag)
        self.state = ConstraintState(
            slots,
            names,
            task_tolerances(task, opt.state),
            opt.state,
            rate_hz=opt.rate_hz,
        )
        self.tracker = PlanTracker(slots, task.predecessors(), names)
        self.report = LiveReport(tracker=self.tracker)
        rate = self.phases.model.features.latent_rate
        self.report.lags = {
            "features": round(self.phases.feature_lag / rate, 4),
            "latent_step": round(1.0 / rate, 4),
            "smoother": round(opt.smoother_lag / rate, 4),
            "constraint_window": opt.state.window_s,
            "constraint_dwell": opt.state.dwell_s,
        }
        self._rate = rate
        self.assist: RobotAssist | None = None
        if opt.assist is not None:
            block = task.stages.constraints
            root = str((block.root if block is not None else None) or task.plan[0].parent)
            self.assist = RobotAssist(
                names,
                [b.kind for b in bodies],
                meta,
                self.state.slots[0].parent if root not in names else root,
                opt.assist,
                reach_m=assembly_reach(self.state.slots, names, meta, root, opt.assist.part_size_m),
            )
        self._assist_step = -1
        self._warm_up(bodies, meta, model, slots, task)
        self._last_t: float | None = None
        self._eval_step = -1
        self.holding: dict[tuple[str, str], bool] = {}

    def _warm_up(
        self,
        bodies: Sequence[BodyInfo],
        meta: Mapping[str, Any],
        model: SegmentModel | None,
        slots: list[Slot],
        task: TaskFile,
    ) -> None:
        """Compile every kernel before the stream starts (a throwaway copy, 1 s of frames).

        With the assist, the execution stage's collision and IK kernels too: compiled
        inside the stream (a fresh install), the first fetch's planning ran out of time.
        """
        if self.assist is not None:
            from thirdhand.execute.collision_check import warm_up

            warm_up()
        n = len(bodies)
        phases = OnlinePhases(bodies, meta, model, lag=self.options.smoother_lag)
        state = ConstraintState(
            slots, self.names, task_tolerances(task, self.options.state), self.options.state
        )
        rng = np.random.default_rng(0)
        quat = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
        for k in range(int(self._rate * 6) * 2):
            t = k / 120.0
            pos = rng.normal(scale=1e-3, size=(n, 3)) + np.arange(n)[:, None] * 0.1
            valid = np.ones(n, dtype=bool)
            phases.push(t, pos, quat, valid)
            state.push(t, pos, quat, valid)
            if k % 6 == 3:
                state.evaluate(t)
        phases.flush()

    def process(self, frame: Frame) -> list[StateEvent]:
        """Update everything with one frame; return the constraint events it caused."""
        t = frame.t
        rep = self.report
        if self._last_t is not None and t - self._last_t > self.options.drop_s:
            rep.dropped.append((self._last_t, t))
            self.state.restart()
        if self._last_t is None:
            rep.t0 = t
        self._last_t = t
        rep.t1 = t
        rep.frames += 1
        updates = self.phases.push(t, frame.pos, frame.quat, frame.valid)
        if updates:
            self.holding = updates[-1].holding
        self.state.push(t, frame.pos, frame.quat, frame.valid)
        events: list[StateEvent] = []
        step = int(np.floor((t - rep.t0) * self._rate + 1e-9))
        if not updates and step != self._eval_step:
            self._eval_step = step
            events = self.state.evaluate(t)
            for e in events:
                self.tracker.apply(e)
            rep.events += events
            before = self.tracker.current
            now = self.tracker.update_current(self.holding)
            if now != before:
                rep.current.append((t, now))
        return events

    def run(
        self,
        source: FrameSource,
        on_events: Callable[[float, list[StateEvent]], None] | None = None,
    ) -> LiveReport:
        """Process every frame of ``source``; measure each update's latency.

        The assist plans in a background thread, so frames keep being processed
        while the arm's motion is planned, unless ``source`` is a replay as fast as
        possible (``speed`` 0), whose clock the planning time is added to instead.
        """
        rep = self.report
        if self.assist is not None:
            self.assist.background = getattr(source, "speed", 1.0) != 0
        # Everything built so far (modules, model, task, scene) lives as long as the
        # loop: move it out of the collector's reach, or a full collection during the
        # stream traverses it all (27-80 ms pauses on the real toolbox from the CLI).
        gc.collect()
        gc.freeze()
        try:
            self._run(source, on_events, rep)
        finally:
            gc.unfreeze()
        return rep

    def _run(
        self,
        source: FrameSource,
        on_events: Callable[[float, list[StateEvent]], None] | None,
        rep: LiveReport,
    ) -> None:
        """The frame loop of :meth:`run`."""
        try:
            self._frames(source, on_events, rep)
        finally:
            # Also when the stream is interrupted: the report ends where it stopped.
            self.phases.flush()
            if self.assist is not None:
                self.assist.finish()
                rep.assists = [a.to_dict() for a in self.assist.assists]

    def _frames(
        self,
        source: FrameSource,
        on_events: Callable[[float, list[StateEvent]], None] | None,
        rep: LiveReport,
    ) -> None:
        clock, cpu = time.perf_counter, time.thread_time
        for frame in source:
            w0, c0 = clock(), cpu()
            events = self.process(frame)
            w1, c1 = clock(), cpu()
            rep.latency.append(w1 - w0)
            rep.cpu.append(c1 - c0)
            rep.late.append(w1 - frame.arrived)
            if events and on_events is not None:
                on_events(frame.t, events)
            if self.assist is not None and self._eval_step != self._assist_step:
                # Once per latent step, after the frame's update (its time is reported apart).
                self._assist_step = self._eval_step
                a0 = clock()
                self.assist.update(
                    frame.t, frame.pos, frame.quat, frame.valid, self.tracker, self.holding
                )
                rep.assist_time.append(clock() - a0)


__all__ = ["DROP_S", "LiveLoop", "LiveOptions", "LiveReport", "check_bodies"]
