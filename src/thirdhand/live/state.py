"""Online constraint state: which of the plan's constraints hold now, decided causally.

A constraint of the task (``parent``, ``child``, the child's pose ``T_s`` in the
parent, a constraint frame ``F`` in the child and free-DOF ranges) *holds* for
a pair of stream bodies (``P``, ``C``) when, over the last ``window_s`` of
frames,

- **near**: the mean pose of ``C`` in ``P`` deviates from ``T_s`` by at most
  ``pos_tol`` / ``rot_tol`` outside the free DOFs: the deviation
  ``E = (T_s F)⁻¹ (T F)`` is taken in the constraint frame, each translation
  beyond its free range counts, and a free rotation (a leg's spin) is removed
  by a swing–twist split about its axis;
- **stable**: the means of the window's two halves differ by at most
  ``stable_pos`` / ``stable_rot`` (a leg still turning in its thread is near but
  not stable);

and both stayed true for ``dwell_s``. It is then *formed* at the current
frame's time. A formed constraint *breaks* (the step is undone) when its
deviation exceeds ``break_factor`` times the tolerances, and the offline
detection's same-pose bounds (``break_pos_min`` / ``break_rot_min``: two runs
within them are one constraint offline), for ``break_s``.
Missing samples never form nor break anything: the counters stop.

The tolerances follow the task: ``tol_sigma`` times the constraint-state noise
the offline HMM learned for the task's recordings (``stages.constraints``
``hmm.sigma_pos_m`` / ``sigma_rot_deg``; the largest over its recordings), not
below ``pos_tol_min`` / ``rot_tol_min``.

Interchangeable parts: a constraint may be made by any stream body
interchangeable with its child (and with its parent): same mesh, or same
bounding box, or the same name up to trailing digits; each body holds one slot
at a time, as offline where a symbol is a slot whichever part fills it.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numba
import numpy as np

from thirdhand import se3
from thirdhand.arrays import BoolArray, FloatArray
from thirdhand.constraints.detect_types import DetectOptions
from thirdhand.errors import ThirdhandError
from thirdhand.taskfile import TaskFile


class LiveTaskError(ThirdhandError, ValueError):
    """A task or a stream the live loop cannot follow (no plan, bodies not matching)."""


@dataclass(frozen=True)
class StateOptions:
    """How constraints are recognised online (defaults: the measured best).

    Attributes
    ----------
    window_s : float
        Seconds of frames averaged into the current relative pose.
    dwell_s : float
        Seconds ``near`` and ``stable`` must hold before a constraint is formed.
    tol_sigma : float
        Tolerances in units of the task's learned constraint noise.
    pos_tol_min, rot_tol_min : float
        Lower bounds of the tolerances, metres and radians.
    stable_pos, stable_rot : float
        Largest change between the window's half means, metres and radians.
    break_factor : float
        A formed constraint breaks beyond this many tolerances ...
    break_s : float
        ... sustained this long, seconds.
    break_pos_min, break_rot_min : float
        ... and never within these bounds, metres and radians: the offline
        detection's same-pose bounds (``DetectOptions.same_pose``), within which
        it joins two runs as one constraint (a person handling an assembled
        toolbox pushes its joined boards 2 cm out of place for a second).
    min_samples : int
        Frames with both bodies valid needed in a window.
    """

    window_s: float = 0.4
    dwell_s: float = 0.2
    tol_sigma: float = 1.4
    pos_tol_min: float = 1e-3
    rot_tol_min: float = math.radians(0.5)
    stable_pos: float = 3e-3
    stable_rot: float = math.radians(2.0)
    break_factor: float = 4.0
    break_s: float = 0.5
    break_pos_min: float = DetectOptions().same_pose[0]
    break_rot_min: float = DetectOptions().same_pose[1]
    min_samples: int = 4


@dataclass
class Slot:
    """One plan step's constraint and the stream body pairs that may make it.

    Attributes
    ----------
    step : int
        Index of the plan step.
    constraint : str
        Constraint id.
    parent, child : str
        The task's bodies.
    pos, quat : ndarray, shape (3,) and (4,)
        The child's pose in the parent, metres and x y z w.
    frame_pos, frame_quat : ndarray, shape (3,) and (4,)
        The constraint frame in the child's frame.
    ranges : ndarray, shape (6, 2)
        Free-DOF ranges (tx, ty, tz metres; rx, ry, rz radians) in the constraint frame.
    candidates : list of (int, int)
        (parent, child) rows of the stream's bodies.
    """

    step: int
    constraint: str
    parent: str
    child: str
    pos: FloatArray
    quat: FloatArray
    frame_pos: FloatArray
    frame_quat: FloatArray
    ranges: FloatArray
    candidates: list[tuple[int, int]] = field(default_factory=list)


@dataclass(frozen=True)
class StateEvent:
    """A constraint formed or broken.

    Attributes
    ----------
    kind : {"formed", "broken"}
    time : float
        Stream clock, seconds (the frame at which the loop decided).
    since : float
        Stream time from which the pose was continuously near (formed) or far (broken).
    step : int
    constraint : str
    parent, child : str
        The stream's bodies that made (or unmade) it.
    """

    kind: str
    time: float
    since: float
    step: int
    constraint: str
    parent: str
    child: str


def _stem(name: str) -> str:
    return re.sub(r"[\s_\-]*\d+$", "", name)


def interchangeable(task: TaskFile, stream_meta: Mapping[str, Any]) -> dict[str, set[str]]:
    """For each task object, the task objects that may stand in for it (itself included)."""
    geometry = stream_meta.get("geometry") if isinstance(stream_meta, Mapping) else None
    geometry = geometry if isinstance(geometry, Mapping) else {}

    def key(o: Any) -> tuple[object, ...]:
        if o.mesh is not None:
            return ("mesh", o.mesh, o.scale)
        if o.bbox_min is not None and o.bbox_max is not None:
            return ("box", tuple(np.round(o.bbox_min, 3)), tuple(np.round(o.bbox_max, 3)))
        g = geometry.get(o.name)
        if isinstance(g, Mapping) and g.get("mesh"):
            return ("mesh", g.get("mesh"), None)
        return ("name", _stem(o.name))

    keys = {o.name: key(o) for o in task.objects if o.kind in ("part", "tool")}
    return {n: {m for m, km in keys.items() if km == k} for n, k in keys.items()}


def task_tolerances(task: TaskFile, options: StateOptions) -> tuple[float, float]:
    """Position (m) and rotation (rad) tolerances from the task's learned constraint noise."""
    sp, sr = 0.0, 0.0
    block = task.stages.constraints
    for demo in block.demos if block is not None else []:
        if demo.hmm is not None:
            sp = max(sp, float(demo.hmm.sigma_pos_m))
            sr = max(sr, math.radians(float(demo.hmm.sigma_rot_deg)))
    return (
        max(options.pos_tol_min, options.tol_sigma * sp),
        max(options.rot_tol_min, options.tol_sigma * sr),
    )


def plan_slots(task: TaskFile, names: Sequence[str], meta: Mapping[str, Any]) -> list[Slot]:
    """The plan's steps as slots with their candidate stream body pairs.

    Raises
    ------
    LiveTaskError
        A task without a plan, or a step naming a constraint the task lacks.
    """
    if not task.plan:
        raise LiveTaskError(
            "the task has no plan: learn one first (thirdhand learn RECORDINGS -o TASK.json)"
        )
    index = {n: i for i, n in enumerate(names)}
    alike = interchangeable(task, meta)
    slots = []
    for i, step in enumerate(task.plan):
        cid = step.constraint or step.symbol
        try:
            c = task.constraint_by_id(cid) if cid is not None else None
        except KeyError:
            c = None
        if c is None:
            raise LiveTaskError(
                f"plan step {i + 1} ({step.parent} -> {step.child}) names no constraint of the "
                f"task ({cid!r})"
            )
        ranges = np.array(
            [list(getattr(c.free_dofs, d)) for d in ("tx", "ty", "tz", "rx", "ry", "rz")]
        )
        parents = sorted(alike.get(c.parent, {c.parent}) & set(index))
        children = sorted(alike.get(c.child, {c.child}) & set(index))
        slots.append(
            Slot(
                step=i,
                constraint=c.id,
                parent=c.parent,
                child=c.child,
                pos=np.asarray(c.pos, np.float64),
                quat=se3.check_quat(np.asarray(c.quat, np.float64)),
                frame_pos=np.asarray(c.frame.pos, np.float64),
                frame_quat=se3.check_quat(np.asarray(c.frame.quat, np.float64)),
                ranges=ranges,
                candidates=[(index[p], index[ch]) for p in parents for ch in children if p != ch],
            )
        )
    return slots


def slot_deviation(slot: Slot, pos: FloatArray, quat: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Deviation of relative poses from a slot outside its free DOFs.

    Parameters
    ----------
    slot : Slot
    pos : ndarray, shape (n, 3), metres
        The child's position in the parent.
    quat : ndarray, shape (n, 4), x y z w

    Returns
    -------
    pos_dev : ndarray, shape (n,), metres
        Length of the translation beyond the free ranges, in the constraint frame.
    rot_dev : ndarray, shape (n,), radians
        Rotation outside the free rotation (the swing about a single free axis;
        the whole rotation when none is free), plus any twist beyond its range.
    """
    n = len(pos)
    return _deviation(
        np.ascontiguousarray(pos, np.float64),
        np.ascontiguousarray(quat, np.float64),
        np.tile(slot.pos, (n, 1)),
        np.tile(slot.quat, (n, 1)),
        np.tile(slot.frame_pos, (n, 1)),
        np.tile(slot.frame_quat, (n, 1)),
        np.ascontiguousarray(np.broadcast_to(slot.ranges, (n, 6, 2))),
    )


@numba.njit(cache=True, nogil=True)
def _qmul(a: FloatArray, b: FloatArray) -> FloatArray:  # pragma: no cover - compiled
    ax, ay, az, aw = a[0], a[1], a[2], a[3]
    bx, by, bz, bw = b[0], b[1], b[2], b[3]
    return np.array(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ]
    )


@numba.njit(cache=True, nogil=True)
def _qrot(q: FloatArray, v: FloatArray) -> FloatArray:  # pragma: no cover - compiled
    u = q[:3]
    w = q[3]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


@numba.njit(cache=True, nogil=True)
def _deviation(  # pragma: no cover - compiled
    pos: FloatArray,
    quat: FloatArray,
    s_pos: FloatArray,
    s_quat: FloatArray,
    f_pos: FloatArray,
    f_quat: FloatArray,
    ranges: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """Row-wise :func:`slot_deviation`, each row with its own slot."""
    n = pos.shape[0]
    pdev = np.zeros(n)
    rdev = np.zeros(n)
    conj = np.array([-1.0, -1.0, -1.0, 1.0])
    for i in range(n):
        fq = _qmul(s_quat[i], f_quat[i])
        fp = s_pos[i] + _qrot(s_quat[i], f_pos[i])
        gq = _qmul(quat[i], f_quat[i])
        gp = pos[i] + _qrot(quat[i], f_pos[i])
        inv = fq * conj
        et = _qrot(inv, gp - fp)
        eq = _qmul(inv, gq)
        if eq[3] < 0:
            eq = -eq
        acc = 0.0
        for k in range(3):
            e = max(max(ranges[i, k, 0] - et[k], et[k] - ranges[i, k, 1]), 0.0)
            acc += e * e
        pdev[i] = np.sqrt(acc)
        n_free = 0
        kf = -1
        for k in range(3):
            if ranges[i, 3 + k, 1] > ranges[i, 3 + k, 0]:
                n_free += 1
                kf = k
        if n_free == 0:
            rdev[i] = 2.0 * np.arccos(min(abs(eq[3]), 1.0))
        elif n_free == 1:
            tw = np.zeros(4)
            tw[kf] = eq[kf]
            tw[3] = eq[3]
            nt = np.sqrt(tw[kf] ** 2 + tw[3] ** 2)
            if nt > 1e-12:
                tw = tw / nt
            else:
                tw[:] = 0.0
                tw[3] = 1.0
            swing = _qmul(eq, tw * conj)
            dev = 2.0 * np.arccos(min(abs(swing[3]), 1.0))
            lo, hi = ranges[i, 3 + kf, 0], ranges[i, 3 + kf, 1]
            if hi - lo < 2.0 * np.pi - 1e-6:
                ang = 2.0 * np.arctan2(tw[kf], tw[3])
                ang = (ang + np.pi) % (2.0 * np.pi) - np.pi
                dev += max(max(lo - ang, ang - hi), 0.0)
            rdev[i] = dev
        else:
            # Several free rotations: the rotation vector's locked components.
            s = np.sqrt(eq[0] ** 2 + eq[1] ** 2 + eq[2] ** 2)
            scale = 2.0 * np.arctan2(s, eq[3]) / s if s > 1e-12 else 2.0
            acc = 0.0
            for k in range(3):
                if not ranges[i, 3 + k, 1] > ranges[i, 3 + k, 0]:
                    acc += (eq[k] * scale) ** 2
            rdev[i] = np.sqrt(acc)
    return pdev, rdev


class ConstraintState:
    """Which of the plan's constraints hold, updated causally frame by frame.

    Parameters
    ----------
    slots : list of Slot
    names : sequence of str
        The stream's body names, in the order of its frames' rows.
    tolerances : (float, float)
        Position (m) and rotation (rad) tolerances (:func:`task_tolerances`).
    options : StateOptions
    rate_hz : float
        Nominal frame rate, Hz (sizes the window buffer).
    """

    def __init__(
        self,
        slots: list[Slot],
        names: Sequence[str],
        tolerances: tuple[float, float],
        options: StateOptions | None = None,
        *,
        rate_hz: float = 120.0,
    ) -> None:
        self.slots = slots
        self.names = list(names)
        self.options = StateOptions() if options is None else options
        self.pos_tol, self.rot_tol = tolerances
        self._cand = [(s, p, c) for s in range(len(slots)) for p, c in slots[s].candidates]
        bodies = sorted({b for _, p, c in self._cand for b in (p, c)})
        self._bodies = np.array(bodies, dtype=np.int64)
        self._col = {b: i for i, b in enumerate(bodies)}
        cap = max(8, math.ceil(self.options.window_s * rate_hz * 4))
        self._t = np.full(cap, -np.inf)
        self._pos = np.zeros((cap, len(bodies), 3))
        self._quat = np.zeros((cap, len(bodies), 4))
        self._valid = np.zeros((cap, len(bodies)), dtype=bool)
        self._n = 0
        n = len(self._cand)
        self._near_since = np.full(n, np.nan)
        self._far_since = np.full(n, np.nan)
        #: For each slot, the candidate index holding it (-1: not formed).
        self.holder = np.full(len(slots), -1, dtype=np.int64)
        #: Stream bodies (rows) currently holding a slot as its child.
        self._busy: set[int] = set()
        self._pa = np.array([self._col[p] for _, p, _ in self._cand], dtype=np.int64)
        self._pc = np.array([self._col[c] for _, _, c in self._cand], dtype=np.int64)
        self._slot_of = np.array([s for s, _, _ in self._cand], dtype=np.int64)
        of = self._slot_of
        self._slot_params = (
            np.array([slots[s].pos for s in of]).reshape(-1, 3),
            np.array([slots[s].quat for s in of]).reshape(-1, 4),
            np.array([slots[s].frame_pos for s in of]).reshape(-1, 3),
            np.array([slots[s].frame_quat for s in of]).reshape(-1, 4),
            np.array([slots[s].ranges for s in of]).reshape(-1, 6, 2),
        )

    def restart(self) -> None:
        """Forget the buffered frames and the dwell counters (after a dropped stream).

        Formed constraints stay formed: nothing is known about the gap, so nothing
        is decided about it; the next frames must show a pose for ``dwell_s`` again.
        """
        self._t[:] = -np.inf
        self._valid[:] = False
        self._near_since[:] = np.nan
        self._far_since[:] = np.nan

    def candidate(self, k: int) -> tuple[int, int, int]:
        """(slot, parent row, child row) of candidate ``k``."""
        return self._cand[k]

    def push(self, t: float, pos: FloatArray, quat: FloatArray, valid: BoolArray) -> None:
        """Store one frame (only the bodies of the plan)."""
        i = self._n % self._t.size
        b = self._bodies
        self._t[i] = t
        self._pos[i] = pos[b]
        self._quat[i] = quat[b]
        self._valid[i] = valid[b]
        self._n += 1

    def evaluate(self, now: float) -> list[StateEvent]:
        """Update the states at stream time ``now`` from the buffered frames; events in order."""
        opt = self.options
        if not self._cand:
            return []
        inwin = self._t > now - opt.window_s
        idx = np.flatnonzero(inwin)
        idx = idx[np.argsort(self._t[idx])]
        events: list[StateEvent] = []
        if idx.size < 2:
            return events
        t = self._t[idx]
        first = t < now - 0.5 * opt.window_s
        va = self._valid[idx][:, self._pa] & self._valid[idx][:, self._pc]  # (n, K)
        rp, rq = se3.relative_pose(
            self._pos[idx][:, self._pa],
            self._quat[idx][:, self._pa],
            self._pos[idx][:, self._pc],
            self._quat[idx][:, self._pc],
        )  # (n, K, 3) and (n, K, 4)
        w1 = (va & first[:, None]).astype(np.float64)
        w2 = (va & ~first[:, None]).astype(np.float64)
        n1, n2 = w1.sum(axis=0), w2.sum(axis=0)
        known = (n1 + n2 >= opt.min_samples) & (n1 > 0) & (n2 > 0)
        # Sign-align every quaternion with the candidate's first valid one.
        ref = rq[np.argmax(va, axis=0), np.arange(va.shape[1])]  # (K, 4)
        rq = rq * np.where(np.einsum("nkj,kj->nk", rq, ref) < 0, -1.0, 1.0)[..., None]
        rp = np.where(va[..., None], rp, 0.0)
        rq = np.where(va[..., None], rq, 0.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            p1 = np.einsum("nk,nkj->kj", w1, rp) / n1[:, None]
            p2 = np.einsum("nk,nkj->kj", w2, rp) / n2[:, None]
            q1 = np.einsum("nk,nkj->kj", w1, rq)
            q2 = np.einsum("nk,nkj->kj", w2, rq)
            mp = (p1 * n1[:, None] + p2 * n2[:, None]) / (n1 + n2)[:, None]
            mq = q1 + q2
            mq = mq / np.linalg.norm(mq, axis=1, keepdims=True)
            q1 = q1 / np.linalg.norm(q1, axis=1, keepdims=True)
            q2 = q2 / np.linalg.norm(q2, axis=1, keepdims=True)
        mp = np.where(known[:, None], mp, 0.0)
        mq = np.where(known[:, None], mq, [0.0, 0.0, 0.0, 1.0])
        dpos = np.where(known, np.linalg.norm(np.nan_to_num(p1 - p2), axis=1), np.inf)
        dot = np.abs(np.einsum("kj,kj->k", np.nan_to_num(q1), np.nan_to_num(q2)))
        drot = np.where(known, 2.0 * np.arccos(np.clip(dot, 0.0, 1.0)), np.inf)
        pdev, rdev = _deviation(mp, mq, *self._slot_params)
        near = (
            (pdev <= self.pos_tol)
            & (rdev <= self.rot_tol)
            & (dpos <= opt.stable_pos)
            & (drot <= opt.stable_rot)
        )
        far = (pdev > max(opt.break_factor * self.pos_tol, opt.break_pos_min)) | (
            rdev > max(opt.break_factor * self.rot_tol, opt.break_rot_min)
        )
        self._near_since = np.where(
            known & near, np.where(np.isnan(self._near_since), now, self._near_since), np.nan
        )
        self._far_since = np.where(
            known & far, np.where(np.isnan(self._far_since), now, self._far_since), np.nan
        )
        # Unknown (missing samples): keep the counters as they were, neither form nor break.
        for s in range(len(self.slots)):
            h = int(self.holder[s])
            if h >= 0:
                if known[h] and far[h] and now - self._far_since[h] >= opt.break_s:
                    c = self._cand[h][2]
                    self.holder[s] = -1
                    self._busy.discard(c)
                    events.append(self._event("broken", now, self._far_since[h], s, h))
                continue
            best = -1
            for k in np.flatnonzero(self._slot_of == s):
                c = self._cand[k][2]
                if c in self._busy or not known[k] or not near[k]:
                    continue
                if now - self._near_since[k] >= opt.dwell_s and (
                    best < 0 or self._near_since[k] < self._near_since[best]
                ):
                    best = int(k)
            if best >= 0:
                self.holder[s] = best
                self._busy.add(self._cand[best][2])
                events.append(self._event("formed", now, self._near_since[best], s, best))
        return events

    def _event(self, kind: str, now: float, since: float, s: int, k: int) -> StateEvent:
        slot = self.slots[s]
        _, p, c = self._cand[k]
        return StateEvent(kind, now, float(since), s, slot.constraint, self.names[p], self.names[c])


__all__ = [
    "ConstraintState",
    "LiveTaskError",
    "Slot",
    "StateEvent",
    "StateOptions",
    "interchangeable",
    "plan_slots",
    "slot_deviation",
    "task_tolerances",
]
