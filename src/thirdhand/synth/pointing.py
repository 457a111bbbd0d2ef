"""The synthetic human points at objects: a prelude of pointing gestures before the assembly.

``make_scene(name, pointing=n)`` opens the recording with ``n`` gestures: one
hand of the first person (the right hand for a target on the right, ``x ≥ 0``)
rises from rest into the pointing posture, holds it for 0.8-1.4 s with the
index fingertip on the line from the eye to the target's centre (the finger
itself along that line, so the index ray and the eye-through-fingertip ray both
pass through the target), and returns to rest; the other hand waits. The last
gesture points at the first object the worker will grasp ("this one next").
Then the ordinary assembly follows, delayed by the prelude. Targets are chosen
among the parts and tools that no other object's centre hides within
:data:`MIN_SEPARATION_DEG` of the line of sight.

Pointing posture (fingertip nail sensors, hand frame of :mod:`thirdhand.synth.human`,
``z`` the approach axis): the index extended 7 cm along ``z``, the thumb and
middle finger curled together 1.4 cm apart at the palm, so the index ray
(from the middle of thumb and middle tip through the index tip) is the hand's
``z`` axis. An ordinary grasp never brings the index 5 cm beyond the middle
finger (they stay 2.7 cm apart), which is what tells the two apart.

Ground truth: ``demo.meta["pointing"]``, one ``{"hand", "object", "t0", "t1"}``
per gesture (``hand`` the hand body prefix, e.g. ``"rh"``; the hold, seconds).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.synth.engine import Segment
from thirdhand.synth.human import RELAXED_APERTURE, Hand, finger_offsets
from thirdhand.synth.motion import PosePath, Tremor, min_jerk, phase, quat_exp
from thirdhand.synth.scenes import TABLE_Z, Layout
from thirdhand.synth.script import Pose, Sim, movement_time

#: Fingertip sensor positions in the pointing posture, shape (3 fingers, 3), metres, hand frame.
POINT_POS = np.array([[0.006, -0.004, -0.01], [0.0, 0.0, 0.065], [-0.006, 0.004, -0.01]])
#: Their orientations: index straight, thumb and middle curled 70°, x y z w, hand frame.
POINT_QUAT = se3.quat_multiply(
    np.array([[0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 1.0]]),
    quat_exp(np.array([[-1.2, 0.0, 0.0], [0.0, 0.0, 0.0], [1.2, 0.0, 0.0]])),
)
#: Distance from the eye to the index fingertip while pointing, metres (at most).
REACH = 0.45
#: No other object's centre within this angle of a target's line of sight, degrees.
MIN_SEPARATION_DEG = 6.0
#: The eye of a person whose head is not tracked (the synthetic head's position), world.
DEFAULT_EYE = np.array([0.0, -0.55, TABLE_Z + 0.45])


def _nlerp(q0: FloatArray, q1: FloatArray, s: FloatArray) -> FloatArray:
    q1 = np.where(np.sum(q0 * q1, axis=-1, keepdims=True) < 0, -q1, q1)
    q = (1.0 - s) * q0 + s * q1
    return np.asarray(q / np.linalg.norm(q, axis=-1, keepdims=True), dtype=np.float64)


@dataclass(frozen=True)
class FingerBlend:
    """A fingertip following a hand path while the hand goes into or out of pointing.

    The posture blends from relaxed (``s = 0``, aperture
    :data:`~thirdhand.synth.human.RELAXED_APERTURE`) to pointing (``s = 1``) as
    ``s`` goes from ``s0`` to ``s1`` over ``[t0, t1]`` (minimum jerk).
    """

    hand: PosePath
    index: int
    t0: float
    t1: float
    s0: float
    s1: float
    jitter: Tremor | None = None

    def __call__(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        hp, hq = self.hand(t)
        s = (self.s0 + (self.s1 - self.s0) * min_jerk(phase(t, self.t0, self.t1)))[:, None]
        rp, rq = finger_offsets(RELAXED_APERTURE)
        off_p = (1.0 - s) * rp[0, self.index] + s * POINT_POS[self.index]
        off_q = _nlerp(rq[0, self.index][None], POINT_QUAT[self.index][None], s)
        p = hp + se3.quat_rotate(hq, off_p)
        if self.jitter is not None:
            env = np.sin(np.pi * phase(t, self.hand.t0, self.hand.t1))[:, None] ** 2
            p = p + env * self.jitter(t)
        return p, se3.quat_multiply(hq, off_q)


def _centres(sim: Sim, layout: Layout, names: list[str]) -> FloatArray:
    """World centres (n, 3) of the bodies' bounding boxes at time 0."""
    out = []
    for name in names:
        p, q = sim.pose(name, 0.0)
        geo = layout.meta.get(name, {})
        lo, hi = geo.get("bbox_min_m"), geo.get("bbox_max_m")
        local = np.zeros(3) if lo is None or hi is None else 0.5 * (np.add(lo, hi))
        out.append(p + se3.quat_rotate(q, np.asarray(local, dtype=np.float64)))
    return np.asarray(out, dtype=np.float64).reshape(-1, 3)


def _angle(u: FloatArray, v: FloatArray) -> FloatArray:
    cos = (v @ u) / np.maximum(np.linalg.norm(v, axis=-1) * np.linalg.norm(u), 1e-12)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def _pointable(eye: FloatArray, centres: FloatArray) -> list[int]:
    """Objects no other centre hides near their line of sight (from the eye and the fingertip)."""
    ok = []
    for k, c in enumerate(centres):
        u = c - eye
        dist = float(np.linalg.norm(u))
        tip = eye + u / dist * min(REACH, 0.6 * dist)
        others = np.delete(centres, k, axis=0)
        if others.size == 0 or (
            _angle(u, others - eye).min() >= MIN_SEPARATION_DEG
            and _angle(c - tip, others - tip).min() >= MIN_SEPARATION_DEG
        ):
            ok.append(k)
    return ok


def _pointing_pose(eye: FloatArray, centre: FloatArray) -> Pose:
    """Hand frame putting the index tip on the eye-target line, pointing along it."""
    u = centre - eye
    dist = float(np.linalg.norm(u))
    u = u / dist
    tip = eye + u * min(REACH, 0.6 * dist)
    down = np.array([0.0, 0.0, -1.0])
    y = down - (down @ u) * u
    y = y / np.linalg.norm(y)
    rot = np.stack([np.cross(y, u), y, u], axis=1)
    return tip - rot @ POINT_POS[1], se3.quat_from_matrix(rot)


def _blend_move(
    sim: Sim, hand: Hand, t0: float, t1: float, target: Pose, s: tuple[float, float, float, float]
) -> None:
    """Move the hand over ``[t0, t1]`` while the posture goes ``s[0] → s[1]`` over ``s[2:]``."""
    dist = float(np.linalg.norm(target[0] - hand.pose[0]))
    path = PosePath.between(
        t0, t1, hand.pose, target, bump=np.array([0.0, 0.0, min(0.12 * dist, 0.05)])
    )
    for i, name in enumerate(hand.fingers):
        sim.timeline.put(name, t0, FingerBlend(path, i, s[2], s[3], s[0], s[1], hand.jitters[i]))
    hand.pose, hand.t_free = path.end(), t1


def _hold(sim: Sim, hand: Hand, t0: float, t1: float) -> None:
    path = PosePath.between(
        t0, t1, hand.pose, hand.pose, tremor=hand.idle_shift, turn=hand.idle_turn
    )
    for i, name in enumerate(hand.fingers):
        sim.timeline.put(name, t0, FingerBlend(path, i, t0, t1, 1.0, 1.0, hand.jitters[i]))
    hand.t_free = t1


def add_pointing(
    sim: Sim, layout: Layout, rng: np.random.Generator, n: int
) -> tuple[Sim, list[dict[str, Any]]]:
    """Prefix a finished one-cycle simulation with ``n`` pointing gestures.

    Parameters
    ----------
    sim : Sim
        The assembly, after :meth:`Sim.finish`; modified in place (delayed).
    layout : Layout
    rng : numpy.random.Generator
        Draws the targets and timing (not the scene's generator, so a scene
        without pointing is unchanged).
    n : int
        Number of gestures.

    Returns
    -------
    sim : Sim
        The same simulation, every label and motion (but the heads') delayed by
        the prelude.
    events : list of dict
        ``{"hand", "object", "t0", "t1"}``: the holds, seconds.
    """
    pre = layout.new_sim(rng)
    names = [b for b, info in pre.bodies.items() if info.kind in ("part", "tool")]
    heads = [b for b, info in pre.bodies.items() if info.kind == "head" and info.person == "p1"]
    centres = _centres(pre, layout, names)
    eye = pre.pose(heads[0], 0.0)[0] if heads else DEFAULT_EYE
    candidates = _pointable(eye, centres)
    first = min(sim.grasps, key=lambda g: g[2])[1] if sim.grasps else None
    reps = -(-n // max(len(candidates), 1))
    targets = [int(k) for _ in range(reps) for k in rng.permutation(candidates)][:n]
    if first in names and names.index(first) in candidates:
        targets[-1] = names.index(first)
    hands = {h.side: h for h in pre.hands.values() if h.person == "p1"}
    events: list[dict[str, Any]] = []
    t = float(rng.uniform(0.4, 0.8))
    for k in targets:
        hand = hands["right" if centres[k][0] >= 0 else "left"]
        pose = _pointing_pose(eye, centres[k])
        sim_t0 = max(t, hand.t_free)
        pre.wait(hand, sim_t0)
        t_arrive = sim_t0 + movement_time(hand.pose, pose) + float(rng.uniform(0.1, 0.3))
        _blend_move(
            pre,
            hand,
            sim_t0,
            t_arrive,
            pose,
            (0.0, 1.0, sim_t0, sim_t0 + 0.6 * (t_arrive - sim_t0)),
        )
        t_leave = t_arrive + float(rng.uniform(0.8, 1.4))
        _hold(pre, hand, t_arrive, t_leave)
        t_back = t_leave + movement_time(hand.pose, hand.rest) + float(rng.uniform(0.1, 0.3))
        _blend_move(
            pre,
            hand,
            t_leave,
            t_back,
            hand.rest,
            (1.0, 0.0, t_leave, t_leave + 0.4 * (t_back - t_leave)),
        )
        events.append({"hand": hand.name, "object": names[k], "t0": t_arrive, "t1": t_leave})
        t = t_back + float(rng.uniform(0.3, 0.8))
    delay = t
    for hand in pre.hands.values():
        pre.wait(hand, delay)
    _delay(sim, pre, delay)
    return sim, events


def _delay(sim: Sim, pre: Sim, delay: float) -> None:
    """``sim`` starts ``delay`` seconds later; ``pre``'s motions fill the gap (heads untouched)."""
    for body, segs in sim.timeline.segments.items():
        if sim.bodies[body].kind == "head":
            continue
        early = [s for s in pre.timeline.segments[body] if s.start < delay - 1e-12]
        late = [
            Segment(s.start + delay, s.motion, s.parent, s.t_offset - s.t_sign * delay, s.t_sign)
            for s in segs
        ]
        sim.timeline.segments[body] = early + late
    sim.interactions = [
        dataclasses.replace(i, start=i.start + delay, end=i.end + delay) for i in sim.interactions
    ]
    sim.constraints = [dataclasses.replace(c, time=c.time + delay) for c in sim.constraints]
    sim.plan = [dataclasses.replace(p, time=(p.time or 0.0) + delay) for p in sim.plan]
    sim.grasps = [(f, o, a + delay, b + delay) for f, o, a, b in sim.grasps]
    sim.joins = [(t + delay, a, b) for t, a, b in sim.joins]
    sim.end += delay


__all__ = ["POINT_POS", "POINT_QUAT", "FingerBlend", "add_pointing"]
