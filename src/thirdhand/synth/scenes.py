"""The scenes: who stands where, what lies on the table, and the assembly scripts.

World frame: ``z`` up, the table top at :data:`TABLE_Z`; the person stands at
``−y`` facing ``+y`` (a second person opposite, at ``+y``). Each scene has a
layout (drawn once per seed) and a script that assembles it once; repeated
cycles replay the script with a new random order after a time-reversed
disassembly (see :mod:`thirdhand.synth.build`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.demonstration import BodyInfo, FreeDofs
from thirdhand.synth import geometry as geo
from thirdhand.synth.human import Grasp, Hand, grasp_from_axes, make_hand
from thirdhand.synth.motion import Hold, ScrewPath, Sway, Tremor, axis_angle_quat
from thirdhand.synth.script import Pose, Sim, compose, offset

TABLE_Z = 0.75
X = np.array([1.0, 0.0, 0.0])
Y = np.array([0.0, 1.0, 0.0])
Z = np.array([0.0, 0.0, 1.0])
FREE_SPIN = FreeDofs(rx=(-np.pi, np.pi))


def frame_quat(x: ArrayLike, y: ArrayLike) -> FloatArray:
    """Quaternion of the frame whose axes are ``x`` and ``y`` (orthonormalised), world."""
    xa = np.asarray(x, dtype=np.float64)
    xa = xa / np.linalg.norm(xa)
    ya = np.asarray(y, dtype=np.float64)
    ya = ya - (ya @ xa) * xa
    ya = ya / np.linalg.norm(ya)
    return se3.quat_from_matrix(np.stack([xa, ya, np.cross(xa, ya)], axis=1))


def yaw(angle: float) -> FloatArray:
    """Rotation about world ``z`` by ``angle`` radians, x y z w."""
    return axis_angle_quat(Z, angle)


def world_grasp(
    obj_pose: Pose,
    point: ArrayLike,
    approach_world: ArrayLike,
    closing_hint_world: ArrayLike,
    width: float,
    *,
    axis: ArrayLike | None = None,
) -> Grasp:
    """A grasp at ``point`` (object frame) approached along a world direction.

    With ``axis`` (object frame) the object is a rod: the fingers close across it,
    perpendicular to both the rod and the approach, on the side of the hint.
    """
    inv = se3.quat_conjugate(obj_pose[1])
    approach = se3.quat_rotate(inv, np.asarray(approach_world, dtype=np.float64))
    hint = se3.quat_rotate(inv, np.asarray(closing_hint_world, dtype=np.float64))
    if axis is not None:
        a = np.asarray(axis, dtype=np.float64)
        approach = approach - (approach @ a) * a
        closing = np.cross(a, approach)
        hint = closing if closing @ hint >= 0 else -closing
    return grasp_from_axes(point, approach, hint, width)


@dataclass
class Layout:
    """Everything that stays the same across the cycles of one seed."""

    parts: list[tuple[BodyInfo, Pose, str | None]]
    hands: list[Hand]
    heads: list[tuple[str, Sway]]
    meta: dict[str, Any] = field(default_factory=dict)
    extra: dict[str, Any] = field(default_factory=dict)

    def new_sim(self, rng: np.random.Generator) -> Sim:
        """A fresh simulation with every body at its starting pose."""
        sim = Sim(rng)
        for info, pose, parent in self.parts:
            sim.add_part(info, pose, parent)
        for template in self.hands:
            hand = dataclasses.replace(template, pose=template.rest)
            sim.add_hand(hand)
        for name, sway in self.heads:
            person = name.split("_")[0] if "_" in name else "p1"
            sim.bodies[name] = BodyInfo(name, kind="head", person=person)
            sim.timeline.put(name, 0.0, sway)
        return sim


def _cast(rng: np.random.Generator, n_people: int, head: bool) -> tuple[list[Hand], list[Any]]:
    hands = []
    heads = []
    down = -Z
    for k in range(n_people):
        side = -1.0 if k == 0 else 1.0  # p1 at -y facing +y, p2 at +y facing -y
        prefix = "" if k == 0 else f"p{k + 1}_"
        person = f"p{k + 1}"
        for code, lateral in (("rh", 1.0), ("lh", -1.0)):
            x = -side * lateral * 0.22  # a person's right is +x when facing +y
            rest_p = np.array([x, side * 0.36, TABLE_Z + 0.04])
            rest_q = se3.quat_from_matrix(
                np.stack([np.cross(-side * Y, down), -side * Y, down], axis=1)
            )
            hands.append(
                make_hand(
                    prefix + code,
                    "right" if code == "rh" else "left",
                    person,
                    (rest_p, rest_q),
                    rng,
                )
            )
        if head:
            hp = np.array([0.0, side * 0.55, TABLE_Z + 0.45])
            hq = frame_quat(-side * Y * np.cos(0.7) + down * np.sin(0.7), np.cross(down, -side * Y))
            sway = Tremor.random(rng, amplitude=0.0, drift=0.01)
            heads.append((prefix + "head", Sway(hp, hq, sway, 0.08)))
    return hands, heads


def _roles(sim: Sim, n_people: int) -> tuple[Hand, Hand]:
    worker = sim.hands["rh"]
    helper = sim.hands["p2_rh"] if n_people >= 2 else sim.hands["lh"]
    return worker, helper


def _settle(sim: Sim, end: float) -> None:
    for hand in sim.hands.values():
        if hand.holding is None and hand.t_free < end:
            sim.wait(hand, end)


# ====================================================================== chair and bench
def layout_chair(rng: np.random.Generator, *, n_people: int, head: bool, bench: bool) -> Layout:
    """Seat upside down in the middle, four legs and (chair) the back lying around it."""
    seat_geo, leg_geo = (
        (geo.BENCH_SEAT, geo.BENCH_LEG) if bench else (geo.CHAIR_SEAT, geo.CHAIR_LEG)
    )
    half_t = float(seat_geo.hi[1])
    radius = float(leg_geo.hi[1])
    seat_q = se3.quat_multiply(yaw(rng.uniform(-0.25, 0.25)), frame_quat(X, Z))
    seat_p = np.array([rng.uniform(-0.03, 0.03), rng.uniform(0.0, 0.06), TABLE_Z + half_t])
    parts: list[tuple[BodyInfo, Pose, str | None]] = [
        (BodyInfo("seating", kind="part"), (seat_p, seat_q), None)
    ]
    spots = np.array([[-0.50, -0.05], [-0.46, 0.25], [0.46, 0.25], [0.50, -0.05]])
    for i, (sx, sy) in enumerate(rng.permutation(spots)):
        heading = np.pi / 2 + rng.uniform(-0.35, 0.35)
        base = frame_quat([np.cos(heading), np.sin(heading), 0.0], Z)
        q = se3.quat_multiply(base, axis_angle_quat(X, rng.uniform(-np.pi, np.pi)))
        p = np.array([sx + rng.uniform(-0.02, 0.02), sy + rng.uniform(-0.1, 0.0), TABLE_Z + radius])
        parts.append((BodyInfo(f"leg{i + 1}", kind="part"), (p, q), None))
    meta = {"seating": seat_geo.to_meta(), **{f"leg{i}": leg_geo.to_meta() for i in range(1, 5)}}
    if not bench:
        bq = se3.quat_multiply(yaw(rng.uniform(-0.2, 0.2)), frame_quat(X, -Y))
        bp = np.array([rng.uniform(-0.05, 0.05), 0.62, TABLE_Z + 0.015])
        parts.append((BodyInfo("back", kind="part"), (bp, bq), None))
        meta["back"] = geo.CHAIR_BACK.to_meta()
    hands, heads = _cast(rng, n_people, head)
    slots = geo.BENCH_SLOTS if bench else geo.CHAIR_SLOTS
    extra = {"slots": slots, "leg_length": float(leg_geo.hi[0]), "radius": radius,
             "half_t": half_t, "n_people": n_people, "back": not bench}  # fmt: skip
    return Layout(parts, hands, heads, meta, extra)


SLOT_Q = axis_angle_quat(Z, np.pi / 2)  # a leg's x along the seat's y


def script_chair(
    sim: Sim, layout: Layout, rng: np.random.Generator, *, turns: tuple[int, int] = (4, 6)
) -> float:
    """Screw the legs in a random slot order, flip the seat over, (chair) insert the back."""
    ex = layout.extra
    worker, helper = _roles(sim, ex["n_people"])
    slots: dict[str, tuple[float, float, float]] = ex["slots"]
    order = [str(s) for s in rng.permutation(list(slots))]
    legs = [str(x) for x in rng.permutation([f"leg{i}" for i in range(1, 5)])]
    t = float(rng.uniform(0.5, 1.0))
    for slot, leg in zip(order, legs, strict=True):
        t = _screw_leg(sim, rng, worker, helper, leg, slot, np.array(slots[slot]), t, ex, turns)
        t += rng.uniform(0.3, 1.2)
    t = _flip(sim, rng, worker, helper, t, ex)
    if ex["back"]:
        t = _insert_back(sim, rng, worker, helper, t + rng.uniform(0.3, 0.8), ex)
    end = t + rng.uniform(0.8, 1.5)
    # The helper steadies the chair a while after the back is in: let every hand finish.
    end = max(end, *(h.t_free + 0.2 for h in sim.hands.values()))
    _settle(sim, end)
    return end


def _screw_leg(
    sim: Sim, rng: np.random.Generator, worker: Hand, helper: Hand, leg: str, slot: str,
    slot_p: FloatArray, t0: float, ex: dict[str, Any], turns: tuple[int, int],
) -> float:  # fmt: skip
    # The helper grasps the seat's edge and turns the seat so the slot faces the worker.
    g_seat = _edge_grasp(sim, "seating", t0, helper.rest[0], 0.15, 2 * ex["half_t"])
    t_h = sim.reach(helper, "seating", g_seat, max(t0, helper.t_free), rng.uniform(0.8, 1.1))
    sp, sq = sim.pose("seating", t_h)
    slot_w = sp + se3.quat_rotate(sq, slot_p)
    cur = np.arctan2(slot_w[1] - sp[1], slot_w[0] - sp[0])
    want = np.arctan2(worker.rest[0][1] - sp[1], worker.rest[0][0] - sp[0])
    turn = float(
        np.clip((want + rng.uniform(-0.4, 0.4) - cur + np.pi) % (2 * np.pi) - np.pi, -1, 1)
    )
    target = (sp, se3.quat_multiply(yaw(turn), sq))
    t_settle = sim.carry("seating", t_h, rng.uniform(0.6, 1.0), target, tremor=helper.tremor)
    # The worker picks up the leg meanwhile and brings it above the slot.
    g = world_grasp(sim.pose(leg, t0), [rng.uniform(0.10, 0.18), 0, 0], -Z, Y, 2 * ex["radius"],
                    axis=X)  # fmt: skip
    t_g = sim.reach(worker, leg, g, max(t0 + 0.2, worker.t_free), rng.uniform(0.9, 1.3))
    proud = 0.012
    theta = float(rng.uniform(-np.pi, np.pi))
    above = ScrewPath(0, 1, slot_p, SLOT_Q, X, theta, 0.0, proud + 0.035, 0.0).end()
    inserted = ScrewPath(0, 1, slot_p, SLOT_Q, X, theta, 0.0, proud, 0.0).end()
    t_lift = t_g + 0.05
    t_c = max(t_lift + rng.uniform(1.1, 1.6), t_settle + 0.15)
    # The seat moves a little in the helper's hand: aim where it is at the end.
    above_w = compose(sim.pose("seating", t_c), above)
    sim.carry(leg, t_lift, t_c - t_lift, above_w, arc=0.06, tremor=worker.tremor)
    t_i = t_c + rng.uniform(0.4, 0.6)
    sim.carry(leg, t_c, t_i - t_c, compose(sim.pose("seating", t_i), inserted))
    sim.timeline.put(leg, t_i, _hold(inserted), "seating")
    # Screwing: each turn spins the leg about its axis and draws it in; regrasp in between.
    n = int(rng.integers(turns[0], turns[1] + 1))
    phis = rng.uniform(np.deg2rad(90), np.deg2rad(120), n)
    d = proud
    t = t_i + rng.uniform(0.1, 0.3)
    for k, phi in enumerate(phis):
        adv = proud * phi / phis.sum()
        start_hand = sim.hand_pose(worker, t)
        dur = rng.uniform(0.5, 0.75)
        path = ScrewPath(t, t + dur, slot_p, SLOT_Q, X, theta, -phi, d, -adv)
        t = sim.screw(leg, "seating", t, dur, path)
        theta, d = theta - phi, d - adv
        if k < n - 1:
            t = sim.release(worker, t + 0.05, rng.uniform(0.2, 0.3), retreat=0.02)
            g = sim.grasp_at(leg, start_hand, t, 2 * ex["radius"])
            t = sim.reach(worker, leg, g, t, rng.uniform(0.45, 0.65), approach=0.02) + 0.05
    final = (slot_p, se3.quat_multiply(SLOT_Q, axis_angle_quat(X, theta)))
    sim.timeline.put(leg, t, _hold(final), "seating")
    sim.engage("seating", leg, t_i, t)
    sim.establish("seating", leg, t, "revolute", symbol=slot, free_dofs=FREE_SPIN, pose=final)
    sim.rest(worker, sim.release(worker, t + 0.05, rng.uniform(0.25, 0.35)), rng.uniform(0.8, 1.1))
    t_hr = sim.release(helper, t + rng.uniform(0.1, 0.4), rng.uniform(0.25, 0.35))
    sim.rest(helper, t_hr, rng.uniform(0.8, 1.1))
    return t


def _flip(
    sim: Sim, rng: np.random.Generator, worker: Hand, helper: Hand, t0: float, ex: dict[str, Any]
) -> float:
    """Both hands take the seat by its sides, lift it and turn it over onto its legs."""
    sp, sq = sim.pose("seating", t0)
    width = 2 * ex["half_t"]
    gw = _edge_grasp(sim, "seating", t0, sp + 10 * X, 0.15, width)
    gh = _edge_grasp(sim, "seating", t0, sp - 10 * X, 0.15, width)
    t_w = sim.reach(worker, "seating", gw, max(t0, worker.t_free), rng.uniform(0.9, 1.2))
    t_h = sim.reach(helper, "seating", gh, max(t0 + 0.1, helper.t_free), rng.uniform(0.9, 1.2))
    t1 = max(t_w, t_h) + rng.uniform(0.1, 0.3)
    slot_y = float(next(iter(ex["slots"].values()))[1])
    target = np.array([sp[0], sp[1], TABLE_Z + slot_y + ex["leg_length"]])
    rv = se3.quat_rotate(se3.quat_conjugate(sq), -np.pi * X)
    t2 = sim.carry("seating", t1, rng.uniform(2.5, 3.2), (target, sq), arc=0.18, rotvec=rv)
    sim.rest(worker, sim.release(worker, t2 + 0.1, 0.3), rng.uniform(0.8, 1.1))
    sim.rest(helper, sim.release(helper, t2 + rng.uniform(0.1, 0.4), 0.3), rng.uniform(0.8, 1.1))
    return t2


def _insert_back(
    sim: Sim, rng: np.random.Generator, worker: Hand, helper: Hand, t0: float, ex: dict[str, Any]
) -> float:
    """The helper steadies the seat; the worker slides the back down into its groove."""
    g_seat = _edge_grasp(sim, "seating", t0, helper.rest[0], 0.15, 2 * ex["half_t"])
    t_h = sim.reach(helper, "seating", g_seat, max(t0, helper.t_free), rng.uniform(0.8, 1.1))
    g = grasp_from_axes([rng.uniform(-0.05, 0.05), -0.42, 0.0], Y, Z, 0.03)
    t_g = sim.reach(worker, "back", g, max(t0 + 0.2, worker.t_free), rng.uniform(1.1, 1.5))
    final = (np.array(geo.CHAIR_BACK_SLOT), np.array([0.0, 0.0, 0.0, 1.0]))
    above = offset(final, (0.0, -0.06, 0.0))
    t_c = max(t_g + 0.05 + rng.uniform(1.8, 2.3), t_h + 0.2)
    sim.carry("back", t_g + 0.05, t_c - t_g - 0.05, compose(sim.pose("seating", t_c), above),
              arc=0.08, tremor=worker.tremor)  # fmt: skip
    t_i = t_c + rng.uniform(0.45, 0.6)
    sim.carry("back", t_c, t_i - t_c, compose(sim.pose("seating", t_i), final))
    sim.timeline.put("back", t_i, _hold(final), "seating")
    sim.establish("seating", "back", t_i, "fixed", symbol="c5", pose=final)
    sim.rest(worker, sim.release(worker, t_i + 0.1, 0.3), rng.uniform(0.8, 1.1))
    # The helper keeps steadying the chair a moment after the back is home.
    sim.rest(helper, sim.release(helper, t_i + rng.uniform(0.6, 1.2), 0.3), rng.uniform(0.8, 1.1))
    return t_i


def _edge_grasp(
    sim: Sim, obj: str, t: float, toward: FloatArray, half: float, thickness: float
) -> Grasp:
    """Grasp a square plate (normal ``y``) at its edge facing the world point ``toward``."""
    op, oq = sim.pose(obj, t)
    d = se3.quat_rotate(se3.quat_conjugate(oq), toward - op)
    d[1] = 0.0
    point = d / np.max(np.abs(d)) * half
    return grasp_from_axes(point, -d, Y, thickness)


def _hold(pose: Pose) -> Hold:
    return Hold(np.asarray(pose[0], dtype=np.float64), np.asarray(pose[1], dtype=np.float64))
