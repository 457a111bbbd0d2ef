"""Scripting a demonstration: hand and object primitives that record exact labels.

A :class:`Sim` holds the timeline of every body and the state of every hand.
Primitives (reach and grasp, release, carry, screw, hold still) append motion
segments and, at the same moments, the ground-truth labels, so the labels are
exactly what was simulated:

- a finger–object interaction is the report's "the hand is actively
  manipulating the object": while the fingers hold the object (from the
  instant they close on it to the instant they start to open) **and** the
  object is being moved — carried, turned, slid, directly or through a chain
  of rigidly attached parts — beyond the small wobble of a holding hand
  (:meth:`Sim.moving_spans`). A static hold, a hand steadying a part while the
  other hand works on it, and fingers resting on a still part are not
  interactions; when the fingers hold the object is kept in :attr:`Sim.grasps`;
- a tool–part interaction (screwdriver–screw) runs from engagement to
  disengagement, the tool's pose being constant in the screw's frame;
- a part–part interaction holds while the two parts are connected by a chain
  of *links*, each at rest in its joint (the child's pose in the parent
  constant): a constraint from the instant it is established (see
  :meth:`Sim.establish`) to the end of the recording, a part seated in its
  joint before the constraint is established (:meth:`Sim.engage`: a leg in its
  thread between two screwing strokes), a screw resting in its hole. A leg or
  screw being turned, a drawer sliding and a lid turning break their link for
  as long as they move.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.demonstration import (
    BodyInfo,
    ConstraintEvent,
    FreeDofs,
    InteractionInterval,
    PlanStep,
)
from thirdhand.synth.engine import Timeline
from thirdhand.synth.human import (
    PREGRASP_OPENING,
    RELAXED_APERTURE,
    FingerOnHand,
    Grasp,
    Hand,
    finger_pose_in_hand,
)
from thirdhand.synth.motion import (
    Flex,
    Hold,
    PosePath,
    Push,
    ScrewPath,
    Sway,
    Tremor,
    Wobble,
)

Pose = tuple[FloatArray, FloatArray]

UP = np.array([0.0, 0.0, 1.0])


def compose(a: Pose, b: Pose) -> Pose:
    """Pose ``a ∘ b`` of single poses: (3,), (4,)."""
    return se3.pose_compose(a[0], a[1], b[0], b[1])


def offset(pose: Pose, local: ArrayLike) -> Pose:
    """``pose`` moved by ``local`` (3,) metres expressed in its own frame."""
    return pose[0] + se3.quat_rotate(pose[1], np.asarray(local, dtype=np.float64)), pose[1]


@dataclass
class Sim:
    """Timeline, hands and labels of one scripted demonstration (one assembly cycle)."""

    rng: np.random.Generator
    timeline: Timeline = field(default_factory=Timeline)
    bodies: dict[str, BodyInfo] = field(default_factory=dict)
    hands: dict[str, Hand] = field(default_factory=dict)
    interactions: list[InteractionInterval] = field(default_factory=list)
    constraints: list[ConstraintEvent] = field(default_factory=list)
    plan: list[PlanStep] = field(default_factory=list)
    joins: list[tuple[float, str, str]] = field(default_factory=list)
    engaged: list[tuple[str, str, float, float]] = field(default_factory=list)
    open_pairs: dict[tuple[str, str], float] = field(default_factory=dict)
    grasps: list[tuple[str, str, float, float]] = field(default_factory=list)
    end: float = 0.0

    # ------------------------------------------------------------ bodies
    def add_part(self, info: BodyInfo, pose: Pose, parent: str | None = None) -> None:
        """Add a part or tool resting at ``pose`` (world, or in ``parent``) from time 0."""
        self.bodies[info.name] = info
        self.timeline.put(info.name, 0.0, Hold(*_arrays(pose)), parent)

    def add_hand(self, hand: Hand) -> None:
        """Add a hand's fingers, at rest from time 0."""
        self.hands[hand.name] = hand
        for info in hand.body_infos():
            self.bodies[info.name] = info
        self._free(hand, 0.0, 0.0, hand.pose, hand.aperture)

    def add_head(self, name: str, person: str, pose: Pose) -> None:
        """A tracked head swaying slowly around ``pose``."""
        self.bodies[name] = BodyInfo(name, kind="head", person=person)
        sway = Tremor.random(self.rng, amplitude=0.0, drift=0.01)
        self.timeline.put(name, 0.0, Sway(*_arrays(pose), sway, 0.08))

    def pose(self, body: str, t: float) -> Pose:
        """World pose of ``body`` at ``t`` seconds: (3,), (4,)."""
        return self.timeline.pose_at(body, t)

    # ------------------------------------------------------------ hand motion
    def _free(
        self,
        hand: Hand,
        t0: float,
        t1: float,
        target: Pose,
        aperture: float,
        *,
        bump: ArrayLike = (0.0, 0.0, 0.0),
        close: tuple[float, float] | None = None,
        idle: bool = False,
    ) -> None:
        if hand.holding is not None:
            raise RuntimeError(f"hand {hand.name} moves freely while holding {hand.holding}")
        if t0 > hand.t_free + 1e-9:
            self._free(hand, hand.t_free, t0, hand.pose, hand.aperture, idle=True)
        if idle:
            tremor, turn = hand.idle_shift, hand.idle_turn
        else:
            tremor, turn = hand.tremor, None
        path = PosePath.between(t0, t1, hand.pose, target, bump=bump, tremor=tremor, turn=turn)
        ta, tb = close if close is not None else (t0, t1)
        for i, name in enumerate(hand.fingers):
            motion = FingerOnHand(path, i, ta, tb, hand.aperture, aperture, hand.jitters[i])
            self.timeline.put(name, t0, motion)
        hand.pose = path.end()
        hand.aperture = aperture
        hand.t_free = t1

    def move_hand(
        self, hand: Hand, t0: float, dur: float, target: Pose, aperture: float | None = None
    ) -> float:
        """Minimum-jerk move of a free hand to ``target`` along a low arc; returns the end time.

        ``dur`` is stretched, if needed, to :func:`movement_time` of the move.
        """
        target = _arrays(target)
        dist = float(np.linalg.norm(target[0] - hand.pose[0]))
        dur = max(dur, movement_time(hand.pose, target))
        bump = UP * min(0.12 * dist, 0.05)
        a = hand.aperture if aperture is None else aperture
        self._free(hand, t0, t0 + dur, target, a, bump=bump)
        return t0 + dur

    def wait(self, hand: Hand, t1: float) -> None:
        """A free hand waits where it is until ``t1``, moving only by its idle sway."""
        if t1 > hand.t_free:
            self._free(hand, hand.t_free, t1, hand.pose, hand.aperture, idle=True)

    def rest(self, hand: Hand, t0: float, dur: float) -> float:
        """Return a free hand to its resting pose, relaxing the fingers."""
        return self.move_hand(hand, t0, dur, hand.rest, RELAXED_APERTURE)

    def reach(
        self, hand: Hand, obj: str, grasp: Grasp, t0: float, dur: float, *, approach: float = 0.04
    ) -> float:
        """Reach ``obj`` and close the fingers on it; returns the grasp time.

        The hand moves to a pre-grasp pose ``approach`` metres back along its
        approach axis with the fingers open, then moves in and closes. The object
        must not move during the reach.
        """
        hg = compose(self.pose(obj, t0 + dur), (grasp.pos, grasp.quat))
        pre = offset(hg, (0.0, 0.0, -approach))
        d_app = min(0.35, 0.4 * dur)
        t_g = t0 + max(dur, d_app + movement_time(hand.pose, pre))
        t_a = t_g - d_app
        # A held object moves a little: close exactly where it is at the grasp time.
        hg = compose(self.pose(obj, t_g), (grasp.pos, grasp.quat))
        pre = offset(hg, (0.0, 0.0, -approach))
        dist = float(np.linalg.norm(pre[0] - hand.pose[0]))
        bump = UP * min(0.12 * dist, 0.05)
        opened = grasp.width + PREGRASP_OPENING
        self._free(hand, t0, t_a, pre, opened, bump=bump)
        self._free(hand, t_a, t_g, hg, grasp.width, close=(t_a + 0.3 * d_app, t_g))
        self.attach_hand(hand, obj, grasp, t_g)
        return t_g

    def attach_hand(self, hand: Hand, obj: str, grasp: Grasp, t: float) -> None:
        """From ``t`` the fingers ride on ``obj`` at ``grasp`` (rigidly, or flexing a little).

        With ``hand.grip`` set (:class:`~thirdhand.synth.human.HumanModel`), each
        fingertip moves by that small motion in the object's frame (:class:`Flex`).
        """
        for i, name in enumerate(hand.fingers):
            rel = compose((grasp.pos, grasp.quat), finger_pose_in_hand(i, grasp.width))
            grip = hand.grip[i] if hand.grip else None
            motion = Hold(*rel) if grip is None else Flex(rel[0], rel[1], grip, t)
            self.timeline.put(name, t, motion, obj)
        hand.holding, hand.grasp, hand.grasp_time, hand.t_free = obj, grasp, t, t
        self._steady(hand, t)

    def release(self, hand: Hand, t0: float, dur: float = 0.3, *, retreat: float = 0.03) -> float:
        """Open the fingers and back off along the approach axis; returns the end time."""
        obj, grasp = hand.holding, hand.grasp
        if obj is None or grasp is None:
            raise RuntimeError(f"hand {hand.name} releases nothing")
        t0 = max(t0, hand.t_free)
        for name in hand.fingers:
            flex = self.timeline.segment_at(name, t0).motion
            if isinstance(flex, Flex):
                flex.t_end = t0
            self.interactions.append(InteractionInterval(name, obj, hand.grasp_time, t0))
            self.grasps.append((name, obj, hand.grasp_time, t0))
        hr = compose(self.pose(obj, t0), (grasp.pos, grasp.quat))
        hand.holding, hand.grasp = None, None
        self._let_go(obj, t0)
        hand.pose, hand.aperture, hand.t_free = hr, grasp.width, t0
        self._free(hand, t0, t0 + dur, offset(hr, (0.0, 0.0, -retreat)), grasp.width + 0.035)
        return t0 + dur

    def grasp_at(self, obj: str, world_hand: Pose, t: float, width: float) -> Grasp:
        """The grasp on ``obj`` that puts the hand frame at ``world_hand`` at time ``t``."""
        op, oq = self.pose(obj, t)
        p, q = se3.relative_pose(op, oq, world_hand[0], world_hand[1])
        return Grasp(p, q, width)

    def hand_pose(self, hand: Hand, t: float) -> Pose:
        """World pose of the hand frame at ``t`` (held or free at ``t_free``)."""
        if hand.holding is None or hand.grasp is None:
            return hand.pose
        return compose(self.pose(hand.holding, t), (hand.grasp.pos, hand.grasp.quat))

    # ------------------------------------------------------------ held objects
    def root(self, body: str, t: float) -> str:
        """The body at the top of ``body``'s parent chain at time ``t``."""
        for _ in range(64):
            parent = self.timeline.segment_at(body, t).parent
            if parent is None:
                return body
            body = parent
        raise RuntimeError(f"parent chain of {body} loops")

    def _steady(self, hand: Hand, t: float) -> None:
        """The object ``hand`` holds (its whole assembly) follows the hand's small motion.

        Applies when the assembly's root rests in the world at ``t`` and nothing is
        scripted for it after ``t``; a carry that ends in the hand calls it again.
        """
        if hand.holding is None or hand.hold_shift is None or hand.hold_turn is None:
            return
        root = self.root(hand.holding, t)
        segs = self.timeline.segments[root]
        seg = self.timeline.segment_at(root, t)
        if seg.parent is not None or isinstance(seg.motion, Wobble) or segs[-1].start > t:
            return
        if isinstance(seg.motion, PosePath) and t < seg.motion.t1 - 1e-9:
            return  # being carried; the carry's end starts the wobble
        if not isinstance(seg.motion, Hold | PosePath):
            return
        p, q = self.pose(root, t)
        pivot = self.hand_pose(hand, t)[0]
        self.timeline.put(root, t, Wobble(p, q, pivot, hand.hold_shift, hand.hold_turn, t))

    def _holders(self, root: str, t: float) -> list[Hand]:
        return [
            h
            for h in self.hands.values()
            if h.holding is not None and self.root(h.holding, t) == root
        ]

    def _let_go(self, obj: str, t: float) -> None:
        """After a release at ``t``: a wobbling assembly nobody holds stays where it is."""
        root = self.root(obj, t)
        seg = self.timeline.segment_at(root, t)
        if not isinstance(seg.motion, Wobble) or self.timeline.segments[root][-1] is not seg:
            return
        holders = self._holders(root, t)
        if holders:
            return
        self.timeline.put(root, t, Hold(*self.pose(root, t)))

    def _push(self, obj: str, parent: str, t0: float, t1: float, path: ScrewPath) -> None:
        """The reaction of a held assembly to a turn or push of ``obj`` in ``parent``."""
        root = self.root(parent, t0)
        seg = self.timeline.segment_at(root, t0)
        if not isinstance(seg.motion, Wobble):
            return
        axis = se3.quat_rotate(self.pose(obj, t0)[1], path.axis)
        twist = -np.sign(path.dtheta) * self.rng.uniform(0.5, 1.5) * np.deg2rad(1.0) * axis
        shove = np.sign(path.dd) * self.rng.uniform(1.0, 3.0) * 1e-3 * axis
        shove = shove + self.rng.normal(0.0, 1e-3, 3)
        seg.motion.pushes.append(Push(t0, t1, shove, twist))

    # ------------------------------------------------------------ object motion
    def carry(
        self,
        obj: str,
        t0: float,
        dur: float,
        target: Pose,
        *,
        arc: float = 0.0,
        rotvec: ArrayLike | None = None,
        tremor: Tremor | None = None,
    ) -> float:
        """Move ``obj`` (world frame) from its pose at ``t0`` to ``target``; returns the end time.

        ``arc`` lifts the middle of the path by that many metres; ``rotvec`` (radians,
        object frame) replaces the shortest rotation, e.g. for a half turn.
        """
        start = self.pose(obj, t0)
        t1 = t0 + dur
        if rotvec is None:
            path = PosePath.between(t0, t1, start, _arrays(target), bump=UP * arc, tremor=tremor)
        else:
            path = PosePath(
                t0, t1, start[0], start[1], np.asarray(target[0]) - start[0],
                np.asarray(rotvec, dtype=np.float64), UP * arc, tremor,
            )  # fmt: skip
        self.timeline.put(obj, t0, path)
        for hand in self._holders(obj, t1):
            self._steady(hand, t1)
            break
        return t1

    def screw(self, obj: str, parent: str, t0: float, dur: float, path: ScrewPath) -> float:
        """Move ``obj`` along a screw/revolute/prismatic path in ``parent``'s frame.

        A held parent assembly reacts with a small push and twist (see :class:`Push`).
        """
        self.timeline.put(obj, t0, path, parent)
        self._push(obj, parent, t0, t0 + dur, path)
        return t0 + dur

    def fix_to(self, obj: str, parent: str, t: float) -> None:
        """From ``t``, ``obj`` keeps its current pose in ``parent``'s frame."""
        self.timeline.put(obj, t, Hold(*self.timeline.relative_at(parent, obj, t)), parent)

    # ------------------------------------------------------------ labels
    def pair(self, a: str, b: str, start: float, end: float | None = None) -> None:
        """Label an interaction of ``a`` and ``b``; ``end=None`` opens it until :meth:`close`."""
        if end is None:
            self.open_pairs[(a, b)] = start
        else:
            self.interactions.append(InteractionInterval(a, b, start, end))

    def end_pair(self, a: str, b: str, end: float) -> None:
        """Close an interaction opened by :meth:`pair` with ``end=None``."""
        start = self.open_pairs.pop((a, b))
        self.interactions.append(InteractionInterval(a, b, start, end))

    def engage(self, parent: str, child: str, t0: float, t1: float) -> None:
        """``child`` sits in its joint in ``parent`` from ``t0`` to ``t1``, not yet established.

        The two interact wherever the child is at rest in the parent meanwhile (a
        leg in its thread between two screwing strokes), as a drawer or a lid
        does between two motions of an established joint.
        """
        self.engaged.append((parent, child, t0, t1))

    def establish(
        self,
        parent: str,
        child: str,
        t: float,
        kind: str,
        *,
        symbol: str,
        free_dofs: FreeDofs | None = None,
        pose: Pose | None = None,
        plan: bool = True,
    ) -> None:
        """Record a constraint established at ``t`` and join the two parts from then on.

        ``pose`` is the child's reference pose in the parent (default: its pose at ``t``).
        """
        p, q = self.timeline.relative_at(parent, child, t) if pose is None else pose
        self.constraints.append(
            ConstraintEvent(
                time=t,
                parent=parent,
                child=child,
                type=kind,
                pos=(float(p[0]), float(p[1]), float(p[2])),
                quat=(float(q[0]), float(q[1]), float(q[2]), float(q[3])),
                free_dofs=FreeDofs() if free_dofs is None else free_dofs,
                symbol=symbol,
            )
        )
        if plan:
            self.plan.append(PlanStep(parent, child, symbol, t))
        self.joins.append((t, parent, child))
        for hand in self.hands.values():
            self._steady(hand, t)

    def finish(self, end: float) -> None:
        """Close every open label at ``end`` and label the part–part and tool–part pairs.

        Both follow the links (:meth:`_connected`): a screwdriver engaged in a screw
        resting in its board moves with the board as rigidly as the screw does.
        """
        self.end = end
        for (a, b), start in sorted(self.open_pairs.items(), key=lambda kv: kv[1]):
            self.interactions.append(InteractionInterval(a, b, start, end))
        self.open_pairs.clear()
        kinds = {name: info.kind for name, info in self.bodies.items()}
        solid = ("part", "tool")
        links = list(self.engaged) + [(a, b, t, end) for t, a, b in self.joins]
        others = []
        for i in self.interactions:
            if kinds[i.a] in solid and kinds[i.b] in solid:
                links.append((i.a, i.b, i.start, i.end))
            else:
                others.append(i)
        self.interactions = others
        self.interactions += self._connected(links)
        self.interactions += self._carried_along()
        self.interactions = self._manipulating(self.interactions)
        self.interactions.sort(key=lambda i: (i.start, i.a, i.b))

    def _manipulating(self, intervals: list[InteractionInterval]) -> list[InteractionInterval]:
        """Cut every hand/finger–object interval to the spans where the object moves.

        Part–part and tool–part intervals (attachment) are returned unchanged.
        """
        out: list[InteractionInterval] = []
        cache: dict[str, list[tuple[float, float]]] = {}
        for i in intervals:
            ka, kb = self.bodies[i.a].kind, self.bodies[i.b].kind
            if ka in ("finger", "hand") and kb in ("part", "tool"):
                obj = i.b
            elif kb in ("finger", "hand") and ka in ("part", "tool"):
                obj = i.a
            else:
                out.append(i)
                continue
            if obj not in cache:
                cache[obj] = self.moving_spans(obj, 0.0, self.end)
            for s, e in cache[obj]:
                lo, hi = max(s, i.start), min(e, i.end)
                if hi > lo:
                    out.append(InteractionInterval(i.a, i.b, lo, hi))
        return out

    def moving_spans(self, body: str, t0: float, t1: float) -> list[tuple[float, float]]:
        """Where ``body`` is moved in the world during ``[t0, t1]``, seconds, merged.

        A body is moved while its own motion or that of a body up its parent
        chain is a scripted move (:class:`PosePath` with a displacement or turn,
        :class:`ScrewPath` with a spin or slide) inside its active interval. A
        :class:`Wobble` (a held body at rest following the hand's small motion,
        pushes included), a :class:`Hold` and an idle hand's sway are not moves.
        """
        return _merge(_moving(self.timeline, body, t0, t1, 0))

    def _connected(
        self, links: list[tuple[str, str, float, float]], step: float = 1.0 / 960.0
    ) -> list[InteractionInterval]:
        """Part and tool pairs joined by a chain of links, each at rest in its joint.

        Every link ``(parent, child, t0, t1)`` is cut to the spans where the child's
        pose in the parent is constant (``step``-second grid); between consecutive
        span ends the links at rest are fixed, so the connected pairs are too.
        A chain of rigid links is rigid, so every labelled pair is.
        """
        spans = [
            (a, b, s, e)
            for a, b, t0, t1 in links
            for s, e in rigid_spans(self.timeline, a, b, t0, t1, step)
        ]
        order = {name: i for i, name in enumerate(self.bodies)}
        cuts = sorted({s for *_, s, _ in spans} | {e for *_, e in spans})
        open_at: dict[tuple[str, str], float] = {}
        out: list[InteractionInterval] = []
        for lo, hi in itertools.pairwise(cuts):
            mid = 0.5 * (lo + hi)
            root: dict[str, str] = {}
            for a, b, s, e in spans:
                if s <= mid <= e:
                    root[_find(root, a)] = _find(root, b)
            groups: dict[str, list[str]] = {}
            for x in list(root):
                groups.setdefault(_find(root, x), []).append(x)
            now = {
                (u, v) if order[u] < order[v] else (v, u)
                for g in groups.values()
                for k, u in enumerate(g)
                for v in g[k + 1 :]
            }
            for pair in [p for p in open_at if p not in now]:
                out.append(InteractionInterval(*pair, open_at.pop(pair), lo))
            for pair in now:
                open_at.setdefault(pair, lo)
        for pair, start in open_at.items():
            out.append(InteractionInterval(*pair, start, cuts[-1]))
        return out

    def _carried_along(self, step: float = 1.0 / 960.0) -> list[InteractionInterval]:
        """Finger–object interactions through a held object (the transitive rule).

        A finger holding ``Q`` interacts with ``P`` while ``Q`` and ``P`` interact
        (a labelled part–part or tool–part interval: established constraints,
        directly or through others, a screw started in its board, a screwdriver
        engaged in a screw) **and** ``P``'s pose in ``Q``'s frame does not change
        (a drawer sliding in its rails, a lid turning on its hinge move relative to
        the holder). Rigidity is checked on a ``step``-second grid, so these
        boundaries are exact to ``step`` where a joint starts or stops moving.
        """
        links: dict[str, list[tuple[str, float, float]]] = {}
        for i in self.interactions:
            if self.bodies[i.a].kind in ("part", "tool") and self.bodies[i.b].kind in (
                "part",
                "tool",
            ):
                links.setdefault(i.a, []).append((i.b, i.start, i.end))
                links.setdefault(i.b, []).append((i.a, i.start, i.end))
        out: list[InteractionInterval] = []
        rigid_cache: dict[tuple[str, str, float, float], list[tuple[float, float]]] = {}
        for finger, q, g0, g1 in self.grasps:
            for p, l0, l1 in links.get(q, []):
                a, b = max(g0, l0), min(g1, l1)
                if b <= a:
                    continue
                key = (q, p, a, b)
                if key not in rigid_cache:
                    rigid_cache[key] = rigid_spans(self.timeline, q, p, a, b, step)
                out += [InteractionInterval(finger, p, s, e) for s, e in rigid_cache[key]]
        return out


def rigid_spans(
    timeline: Timeline, parent: str, child: str, t0: float, t1: float, step: float
) -> list[tuple[float, float]]:
    """Sub-intervals of ``[t0, t1]`` (seconds) where ``child`` is still in ``parent``'s frame,
    checked on a ``step``-second grid."""
    n = max(int(np.ceil((t1 - t0) / step)), 1) + 1
    t = np.linspace(t0, t1, n)
    poses = timeline.evaluate(t, [parent, child])
    rp, rq = se3.relative_pose(*poses[parent], *poses[child])
    rq = rq * np.where(np.sum(rq * rq[:1], axis=1) < 0, -1.0, 1.0)[:, None]
    jump = np.maximum(
        np.linalg.norm(np.diff(rp, axis=0), axis=1), np.linalg.norm(np.diff(rq, axis=0), axis=1)
    )
    moving = jump > 1e-9
    still = np.ones(n, dtype=bool)
    still[:-1] &= ~moving
    still[1:] &= ~moving
    spans = []
    edges = np.flatnonzero(np.diff(np.concatenate([[0], still.astype(np.int8), [0]])))
    for lo, hi in zip(edges[::2], edges[1::2], strict=True):
        if hi - lo >= 2:
            spans.append((float(t[lo]), float(t[hi - 1])))
    return spans


def _moving(
    timeline: Timeline, body: str, t0: float, t1: float, depth: int
) -> list[tuple[float, float]]:
    if depth > 64:
        raise RuntimeError(f"parent chain of {body} loops")
    segs = timeline.segments[body]
    out: list[tuple[float, float]] = []
    for k, seg in enumerate(segs):
        lo = max(t0, seg.start if k else -np.inf)
        hi = min(t1, segs[k + 1].start if k + 1 < len(segs) else np.inf)
        if hi <= lo:
            continue
        active = _driven(seg.motion)
        if active is not None:
            ends = [(u - seg.t_offset) / seg.t_sign for u in active]
            a, b = min(ends), max(ends)
            if min(b, hi) > max(a, lo):
                out.append((max(a, lo), min(b, hi)))
        if seg.parent is not None:
            out += _moving(timeline, seg.parent, lo, hi, depth + 1)
    return out


def _driven(motion: object) -> tuple[float, float] | None:
    """Active interval (the motion's own time, seconds) of a scripted move, else None."""
    if isinstance(motion, PosePath) and (
        np.any(motion.dp != 0.0) or np.any(motion.rotvec != 0.0) or np.any(motion.bump != 0.0)
    ):
        return motion.t0, motion.t1
    if isinstance(motion, ScrewPath) and (motion.dtheta != 0.0 or motion.dd != 0.0):
        return motion.t0, motion.t1
    return None


def _merge(spans: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """Union of intervals, sorted, touching ones joined."""
    out: list[tuple[float, float]] = []
    for s, e in sorted(spans):
        if out and s <= out[-1][1]:
            out[-1] = (out[-1][0], max(out[-1][1], e))
        else:
            out.append((s, e))
    return out


def _find(root: dict[str, str], x: str) -> str:
    """Union–find root of ``x`` (added as its own root when new)."""
    while root.setdefault(x, x) != x:
        x = root[x]
    return x


def movement_time(start: Pose, end: Pose) -> float:
    """Shortest natural duration of a hand move, seconds: grows with distance and turn.

    Keeps the minimum-jerk peak speed near 1.2 m/s for long reaches and the wrist
    below about 8 rad/s.
    """
    dist = float(np.linalg.norm(np.asarray(end[0]) - np.asarray(start[0])))
    angle = float(se3.quat_angle(start[1], end[1]))
    return max(0.3 + 1.3 * dist, 0.2 + 0.25 * angle)


def _arrays(pose: Pose) -> Pose:
    return np.asarray(pose[0], dtype=np.float64), np.asarray(pose[1], dtype=np.float64)
