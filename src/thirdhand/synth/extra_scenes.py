"""The toolbox (boards, screws, a screwdriver), the drawer (prismatic) and the lid (revolute).

Toolbox: ``side_front`` stands at the assembly place; ``side_left``,
``side_right``, ``side_back`` and ``handle`` lie on the table, each with two screws
started in its holes (the screws ride with their board). Per board, in random
order: the worker stands the board against the assembly, the helper holds it,
the worker takes the ``screwdriver``, engages each screw and drives it in with
several strokes (releasing and regripping the handle between strokes), then puts
the screwdriver down. The screwdriver–screw pair is rigid from engagement to
disengagement; the screw turns and advances in its board while driven and is
fixed afterwards (constraint ``s1``…``s8`` by hole); the board is fixed to
``side_front`` when its last screw is tight (``c1``…``c4`` by place).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.demonstration import BodyInfo, FreeDofs
from thirdhand.synth import geometry as geo
from thirdhand.synth.human import Hand, grasp_from_axes
from thirdhand.synth.motion import ScrewPath, axis_angle_quat
from thirdhand.synth.scenes import (
    TABLE_Z,
    Layout,
    X,
    Y,
    Z,
    _cast,
    _hold,
    _roles,
    _settle,
    frame_quat,
    world_grasp,
    yaw,
)
from thirdhand.synth.script import Pose, Sim, compose, offset

# Board poses in the assembly frame (world-aligned, origin on the table): x along the
# board, y up, z its outer face normal.
_BOARDS: dict[str, tuple[geo.PartGeometry, tuple[float, float, float], Any, Any]] = {
    "side_front": (geo.TOOLBOX_END, (0.0, -0.204, 0.06), X, -Y),
    "side_back": (geo.TOOLBOX_END, (0.0, 0.204, 0.06), -X, Y),
    "side_left": (geo.TOOLBOX_SIDE, (-0.1385, 0.0, 0.06), -Y, -X),
    "side_right": (geo.TOOLBOX_SIDE, (0.1385, 0.0, 0.06), Y, X),
    "handle": (geo.TOOLBOX_HANDLE, (0.0, 0.0, 0.09), Y, X),
}
_PLACES = {"side_left": "c1", "side_right": "c2", "side_back": "c3", "handle": "c4"}
_PROUD = 0.012
_SCREW_Q = frame_quat(-Z, Y)  # screw x into the board, from its outer face
_ENGAGED = (np.zeros(3), axis_angle_quat(Y, np.pi))  # screwdriver in the screw's frame


def _assembled(name: str) -> Pose:
    _, p, x, z = _BOARDS[name]
    y = np.cross(z, x)
    return np.array(p, dtype=np.float64), se3.quat_from_matrix(np.stack([x, y, z], axis=1))


def _holes(name: str) -> list[FloatArray]:
    g = _BOARDS[name][0]
    half_x, half_z = float(g.hi[0]), float(g.hi[2])
    return [np.array([s * (half_x - 0.03), 0.0, half_z]) for s in (-1.0, 1.0)]


def layout_toolbox(rng: np.random.Generator, *, n_people: int, head: bool) -> Layout:
    """``side_front`` standing at the assembly place, the other boards lying around."""
    origin = np.array([rng.uniform(-0.03, 0.03), rng.uniform(0.10, 0.16), TABLE_Z])
    frame = (origin, yaw(rng.uniform(-0.15, 0.15)))
    parts: list[tuple[BodyInfo, Pose, str | None]] = []
    meta: dict[str, Any] = {}
    parts.append((BodyInfo("side_front"), compose(frame, _assembled("side_front")), None))
    spots = np.array([[-0.62, 0.0], [0.62, 0.0], [-0.55, 0.42], [0.55, 0.42]])
    movable = ["side_left", "side_right", "side_back", "handle"]
    for name, (sx, sy) in zip(movable, rng.permutation(spots), strict=True):
        g = _BOARDS[name][0]
        q = se3.quat_multiply(yaw(np.pi / 2 + rng.uniform(-0.3, 0.3)), frame_quat(X, Y))
        p = np.array([sx + rng.uniform(-0.02, 0.02), sy + rng.uniform(-0.02, 0.02),
                      TABLE_Z + float(g.hi[2])])  # fmt: skip
        parts.append((BodyInfo(name), (p, q), None))
    for name, (g, *_rest) in _BOARDS.items():
        meta[name] = g.to_meta()
    holes = [(board, i) for board in movable for i in range(2)]
    screws = [f"screw{i + 1}" for i in range(len(holes))]
    preinserted = []
    hole_of: dict[tuple[str, int], tuple[str, str]] = {}
    for k, screw in enumerate(rng.permutation(screws)):
        board, i = holes[k]
        pose = ScrewPath(0, 1, _holes(board)[i], _SCREW_Q, X, rng.uniform(-np.pi, np.pi), 0.0,
                         -_PROUD, 0.0).end()  # fmt: skip
        parts.append((BodyInfo(str(screw)), pose, board))
        preinserted.append((str(screw), board))
        hole_of[(board, i)] = (str(screw), f"s{k + 1}")
        meta[str(screw)] = geo.SCREW.to_meta()
    sd_q = se3.quat_multiply(yaw(rng.uniform(-0.3, 0.3)), frame_quat(X, Y))
    sd_p = np.array([0.38 + rng.uniform(-0.02, 0.02), -0.2, TABLE_Z + 0.016])
    parts.append((BodyInfo("screwdriver", kind="tool"), (sd_p, sd_q), None))
    meta["screwdriver"] = geo.SCREWDRIVER.to_meta()
    hands, heads = _cast(rng, n_people, head)
    extra = {"n_people": n_people, "frame": frame, "preinserted": preinserted,
             "hole_of": hole_of, "movable": movable}  # fmt: skip
    return Layout(parts, hands, heads, meta, extra)


def script_toolbox(sim: Sim, layout: Layout, rng: np.random.Generator) -> float:
    """Attach the four boards to ``side_front`` in a random order, two screws each."""
    ex = layout.extra
    worker, helper = _roles(sim, ex["n_people"])
    t = float(rng.uniform(0.5, 1.0))
    for board in rng.permutation(ex["movable"]):
        t = _attach_board(sim, rng, worker, helper, str(board), t, ex) + rng.uniform(0.3, 1.0)
    end = t + rng.uniform(0.8, 1.5)
    _settle(sim, end)
    return end


def _attach_board(
    sim: Sim, rng: np.random.Generator, worker: Hand, helper: Hand, board: str, t0: float,
    ex: dict[str, Any],
) -> float:  # fmt: skip
    g = _BOARDS[board][0]
    top, thick = float(g.hi[1]), 2 * float(g.hi[2])
    gx = rng.uniform(0.05, 0.1) * float(rng.choice([-1.0, 1.0]))
    grip = grasp_from_axes([gx, top, 0.0], -Y, Z, thick)
    t_g = sim.reach(worker, board, grip, max(t0, worker.t_free), rng.uniform(1.0, 1.4))
    # The front board may have been left a few millimetres off by the helper: aim at
    # its place relative to the front board as it is.
    in_front = se3.relative_pose(*_assembled("side_front"), *_assembled(board))
    t_c = t_g + 0.05 + rng.uniform(1.3, 1.8)
    final = compose(sim.pose("side_front", t_c), in_front)
    above = (final[0] + 0.05 * Z, final[1])
    sim.carry(board, t_g + 0.05, t_c - t_g - 0.05, above, arc=0.08, tremor=worker.tremor)
    t_i = t_c + rng.uniform(0.4, 0.6)
    sim.carry(board, t_c, t_i - t_c, compose(sim.pose("side_front", t_i), in_front))
    hold = grasp_from_axes([-gx, top, 0.0], -Y, Z, thick)
    t_h = sim.reach(helper, board, hold, max(t_i - 0.6, helper.t_free), rng.uniform(0.9, 1.2))
    t_h = max(t_h, t_i)
    t = sim.release(worker, t_h + 0.1, 0.3)
    sd_rest = sim.pose("screwdriver", t)
    sd_grip = world_grasp(sd_rest, [rng.uniform(0.14, 0.18), 0, 0], -Z, Y, 0.032, axis=X)
    t = sim.reach(worker, "screwdriver", sd_grip, t, rng.uniform(0.9, 1.2))
    last = t
    for k, i in enumerate(rng.permutation(2)):
        screw, symbol = ex["hole_of"][(board, int(i))]
        last = t = _drive(sim, rng, worker, board, screw, symbol, t + 0.05)
        if k == 1:
            rel = sim.timeline.relative_at("side_front", board, last)
            sim.timeline.put(board, last, _hold(rel), "side_front")
            sim.establish("side_front", board, last, "fixed", symbol=_PLACES[board])
        sim.end_pair("screwdriver", screw, t + 0.05)
        out = offset(sim.pose("screwdriver", t + 0.05), (0.04, 0.0, 0.0))
        t = sim.carry("screwdriver", t + 0.05, 0.35, out)
    t = sim.carry("screwdriver", t, rng.uniform(1.0, 1.4), sd_rest, arc=0.06, tremor=worker.tremor)
    sim.rest(worker, sim.release(worker, t, 0.3), rng.uniform(0.8, 1.1))
    t_hr = sim.release(helper, last + rng.uniform(0.3, 0.8), 0.3)
    sim.rest(helper, t_hr, rng.uniform(0.8, 1.1))
    return max(t, t_hr)


def _drive(
    sim: Sim, rng: np.random.Generator, worker: Hand, board: str, screw: str, symbol: str,
    t0: float,
) -> float:  # fmt: skip
    """Engage the screwdriver on ``screw`` and drive it in; returns when it is tight."""
    t = t0 + rng.uniform(0.9, 1.3)
    before = offset(compose(sim.pose(screw, t), _ENGAGED), (0.04, 0.0, 0.0))
    sim.carry("screwdriver", t0, t - t0, before, arc=0.05, tremor=worker.tremor)
    t_e = t + rng.uniform(0.3, 0.45)
    # The board moves a little in the helper's hand: engage where the screw is then.
    t = sim.carry("screwdriver", t, t_e - t, compose(sim.pose(screw, t_e), _ENGAGED))
    sim.timeline.put("screwdriver", t, _hold(_ENGAGED), screw)
    sim.pair("screwdriver", screw, t)
    ref = sim.timeline.relative_at(board, screw, t)
    hole = (ref[0] - se3.quat_rotate(ref[1], [-_PROUD, 0.0, 0.0]), ref[1])
    n = int(rng.integers(4, 6))
    total = 2 * np.pi * rng.uniform(1.8, 2.2)
    theta, d = 0.0, -_PROUD
    for k in range(n):
        phi = total / n
        start_hand = sim.hand_pose(worker, t)
        dur = rng.uniform(0.45, 0.65)
        path = ScrewPath(t, t + dur, hole[0], hole[1], X, theta, phi, d, _PROUD / n)
        t = sim.screw(screw, board, t, dur, path)
        theta, d = theta + phi, d + _PROUD / n
        if k < n - 1:
            t = sim.release(worker, t + 0.05, rng.uniform(0.2, 0.3), retreat=0.015)
            g = sim.grasp_at("screwdriver", start_hand, t, 0.032)
            t = sim.reach(worker, "screwdriver", g, t, rng.uniform(0.4, 0.55), approach=0.015)
            t += 0.05
    final = (hole[0], se3.quat_multiply(hole[1], axis_angle_quat(X, theta)))
    sim.timeline.put(screw, t, _hold(final), board)
    # In its hole from the start: interacting with the board wherever it rests in it.
    sim.end_pair(board, screw, t)
    sim.establish(board, screw, t, "fixed", symbol=symbol, pose=final)
    return t


# ============================================================================ drawer
def layout_drawer(rng: np.random.Generator, *, n_people: int, head: bool) -> Layout:
    """A cabinet frame opening towards the person, the drawer lying to one side."""
    fq = yaw(-np.pi / 2 + rng.uniform(-0.15, 0.15))  # frame x (out of the opening) towards -y
    fp = np.array([rng.uniform(-0.05, 0.05), 0.25, TABLE_Z + 0.10])
    side = float(rng.choice([-1.0, 1.0]))
    dq = yaw(-np.pi / 2 + rng.uniform(-0.4, 0.4))
    dp = np.array([side * rng.uniform(0.45, 0.55), rng.uniform(-0.05, 0.1), TABLE_Z + 0.08])
    parts: list[tuple[BodyInfo, Pose, str | None]] = [
        (BodyInfo("frame"), (fp, fq), None),
        (BodyInfo("drawer"), (dp, dq), None),
    ]
    meta = {"frame": geo.DRAWER_FRAME.to_meta(), "drawer": geo.DRAWER.to_meta()}
    hands, heads = _cast(rng, n_people, head)
    return Layout(parts, hands, heads, meta, {"n_people": n_people, "travel": 0.25})


def script_drawer(sim: Sim, layout: Layout, rng: np.random.Generator) -> float:
    """Slide the drawer into the frame (prismatic along x), then open and close it."""
    travel = float(layout.extra["travel"])
    worker, helper = _roles(sim, layout.extra["n_people"])
    t0 = float(rng.uniform(0.5, 1.0))
    steady = grasp_from_axes([0.0, -0.18, 0.1], -Z, Y, 0.015)
    t_h = sim.reach(helper, "frame", steady, t0, rng.uniform(0.9, 1.2))
    handle = grasp_from_axes([0.21, 0.0, 0.03], -X, Z, 0.02)
    t_g = sim.reach(worker, "drawer", handle, t0 + 0.2, rng.uniform(1.0, 1.3))
    closed = (np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]))
    at_rails = ScrewPath(0, 1, *closed, X, 0.0, 0.0, travel, 0.0).end()
    before = ScrewPath(0, 1, *closed, X, 0.0, 0.0, travel + 0.08, 0.0).end()
    t = max(t_g + 0.05 + rng.uniform(1.2, 1.6), t_h + 0.2)
    # The frame moves a little in the helper's hand: aim where it is at each end.
    sim.carry("drawer", t_g + 0.05, t - t_g - 0.05, compose(sim.pose("frame", t), before),
              arc=0.05, tremor=worker.tremor)  # fmt: skip
    t_r = t + rng.uniform(0.5, 0.7)
    t = sim.carry("drawer", t, t_r - t, compose(sim.pose("frame", t_r), at_rails))
    sim.timeline.put("drawer", t, _hold(at_rails), "frame")
    free = FreeDofs(tx=(0.0, travel))
    sim.establish("frame", "drawer", t, "prismatic", symbol="c1", free_dofs=free, pose=closed)
    d = travel
    targets = [0.0] + [x for _ in range(2) for x in (rng.uniform(0.5, 0.9) * travel, 0.0)]
    for target in targets:
        t += rng.uniform(0.2, 0.6)
        dur = rng.uniform(0.8, 1.2)
        t = sim.screw("drawer", "frame", t, dur, ScrewPath(t, t + dur, *closed, X, 0.0, 0.0, d,
                                                            target - d))  # fmt: skip
        d = target
    sim.timeline.put("drawer", t, _hold(closed), "frame")
    sim.rest(worker, sim.release(worker, t + 0.1, 0.3), rng.uniform(0.8, 1.1))
    sim.rest(helper, sim.release(helper, t + rng.uniform(0.2, 0.5), 0.3), rng.uniform(0.8, 1.1))
    end = t + rng.uniform(1.8, 2.5)
    _settle(sim, end)
    return end


# ============================================================================ lid
_HINGE = np.array([0.0, 0.10, 0.065])  # hinge axis point in the box frame, metres
_LID_CLOSED_Q = axis_angle_quat(Z, np.pi)  # lid x = -box x, the plate along -box y


def layout_lid(rng: np.random.Generator, *, n_people: int, head: bool) -> Layout:
    """A box in front of the person, its lid lying beside it."""
    bq = yaw(rng.uniform(-0.2, 0.2))
    bp = np.array([rng.uniform(-0.05, 0.05), 0.12, TABLE_Z + 0.06])
    side = float(rng.choice([-1.0, 1.0]))
    lq = yaw(rng.uniform(-0.4, 0.4) + np.pi)
    lp = np.array([side * rng.uniform(0.40, 0.50), rng.uniform(0.05, 0.2), TABLE_Z + 0.005])
    parts: list[tuple[BodyInfo, Pose, str | None]] = [
        (BodyInfo("box"), (bp, bq), None),
        (BodyInfo("lid"), (lp, lq), None),
    ]
    meta = {"box": geo.LID_BOX.to_meta(), "lid": geo.LID.to_meta()}
    hands, heads = _cast(rng, n_people, head)
    return Layout(parts, hands, heads, meta, {"n_people": n_people, "max_open": np.deg2rad(110)})


def script_lid(sim: Sim, layout: Layout, rng: np.random.Generator) -> float:
    """Slide the open lid onto the hinge pins (revolute about x), close, open and close it."""
    max_open = float(layout.extra["max_open"])
    worker, helper = _roles(sim, layout.extra["n_people"])
    t0 = float(rng.uniform(0.5, 1.0))
    steady = grasp_from_axes([-0.145, 0.0, 0.06], -Z, X, 0.012)
    t_h = sim.reach(helper, "box", steady, t0, rng.uniform(0.9, 1.2))
    edge = grasp_from_axes([rng.uniform(-0.05, 0.05), 0.2, 0.0], -Y, Z, 0.01)
    t_g = sim.reach(worker, "lid", edge, t0 + 0.2, rng.uniform(1.0, 1.3))
    angle = float(rng.uniform(np.deg2rad(80), np.deg2rad(100)))
    closed = (_HINGE, _LID_CLOSED_Q)
    on_pins = ScrewPath(0, 1, *closed, X, angle, 0.0, 0.0, 0.0).end()
    before = ScrewPath(0, 1, *closed, X, angle, 0.0, 0.04, 0.0).end()
    t = max(t_g + 0.05 + rng.uniform(1.2, 1.6), t_h + 0.2)
    # The box moves a little in the helper's hand: aim where it is at each end.
    sim.carry("lid", t_g + 0.05, t - t_g - 0.05, compose(sim.pose("box", t), before), arc=0.08,
              tremor=worker.tremor)  # fmt: skip
    t_p = t + rng.uniform(0.5, 0.7)
    t = sim.carry("lid", t, t_p - t, compose(sim.pose("box", t_p), on_pins))
    sim.timeline.put("lid", t, _hold(on_pins), "box")
    free = FreeDofs(rx=(0.0, max_open))
    sim.establish("box", "lid", t, "revolute", symbol="c1", free_dofs=free, pose=closed)
    a = angle
    targets = [0.0] + [x for _ in range(2) for x in (rng.uniform(0.6, 1.0) * max_open, 0.0)]
    for target in targets:
        t += rng.uniform(0.2, 0.6)
        dur = rng.uniform(0.8, 1.2)
        t = sim.screw("lid", "box", t, dur, ScrewPath(t, t + dur, *closed, X, a, target - a, 0.0,
                                                      0.0))  # fmt: skip
        a = target
    sim.timeline.put("lid", t, _hold(closed), "box")
    sim.rest(worker, sim.release(worker, t + 0.1, 0.3), rng.uniform(0.8, 1.1))
    sim.rest(helper, sim.release(helper, t + rng.uniform(0.2, 0.5), 0.3), rng.uniform(0.8, 1.1))
    end = t + rng.uniform(1.8, 2.5)
    _settle(sim, end)
    return end
