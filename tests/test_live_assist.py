"""The robot assist's decisions (which part, when, from where, the grasp, the lift, the
hand-over) and the arm that acts on them (the planning itself is the execution stage's,
tested there)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from thirdhand import se3
from thirdhand.live.handover import down_quat
from thirdhand.live.state import Slot
from thirdhand.live.tracker import PlanTracker


@pytest.mark.parametrize("direction", [(1.0, 0.0), (0.0, -2.0), (-1.0, 1.0), (0.0, 0.0)])
def test_down_grasp_points_down_along_the_part(direction: tuple[float, float]) -> None:
    q = down_quat(np.array(direction))
    assert np.linalg.norm(q) == pytest.approx(1.0)
    z = se3.quat_rotate(q, np.array([0.0, 0.0, 1.0]))
    x = se3.quat_rotate(q, np.array([1.0, 0.0, 0.0]))
    np.testing.assert_allclose(z, [0.0, 0.0, -1.0], atol=1e-12)
    d = np.array([*direction, 0.0])
    want = d / np.linalg.norm(d) if np.linalg.norm(d) > 0 else np.array([1.0, 0.0, 0.0])
    np.testing.assert_allclose(x, want, atol=1e-12)


def test_handover_tries_turn_about_the_vertical_and_rise() -> None:
    from thirdhand.live.handover import HANDOVER_RAISE_M, handover_targets

    pos, quat = np.array([0.1, 0.2, 1.1]), down_quat(np.array([1.0, 0.0]))
    targets = handover_targets((pos, quat))
    assert len(targets) == 8
    np.testing.assert_array_equal(targets[0][0], pos)
    np.testing.assert_allclose(targets[0][1], quat, atol=1e-12)
    xs = []
    for k, (p, q) in enumerate(targets):
        rise = np.array([0.0, 0.0, HANDOVER_RAISE_M * (k // 4)])
        np.testing.assert_allclose(p, pos + rise, atol=1e-12)
        # still pointing down, turned about the vertical only
        np.testing.assert_allclose(se3.quat_rotate(q, [0.0, 0.0, 1.0]), [0, 0, -1.0], atol=1e-12)
        xs.append(se3.quat_rotate(q, [1.0, 0.0, 0.0]))
    np.testing.assert_allclose(xs[:4], [[1, 0, 0], [0, 1, 0], [0, -1, 0], [-1, 0, 0]], atol=1e-12)


def test_grasps_of_a_flat_part_come_from_above_and_the_first_is_kept() -> None:
    """A board lying tilted by 10°: every grasp approaches from above (cosine with straight
    down > 0.7), each tried again 1 cm less deep; the given top-down grasp first."""
    from thirdhand.live.grasp import DOWN_COS, MAX_GRASPS, SHALLOWER_M, grasp_targets, part_box
    from thirdhand.segment.contact import body_box

    meta = {
        "geometry": {"board": {"bbox_min_m": [-0.2, -0.2, -0.015], "bbox_max_m": [0.2, 0.2, 0.015]}}
    }
    centre, size = part_box(body_box(meta, "board"), 0.05)
    np.testing.assert_allclose(size, [0.4, 0.4, 0.03], atol=1e-12)
    pos = np.array([[0.3, 0.1, 0.77]])
    quat = se3.quat_from_rotvec(np.array([[np.radians(10.0), 0.0, 0.0]]))
    first = (pos[0], down_quat(np.array([1.0, 0.0])))
    targets = grasp_targets(centre, size, pos[0], quat[0], first)
    assert targets[0] is first and 2 < len(targets) <= MAX_GRASPS + 1
    for k, (p, q) in enumerate(targets[1:]):
        z = se3.quat_rotate(q, [0.0, 0.0, 1.0])
        assert -z[2] > DOWN_COS
        if k % 2:  # the shallower try of the grasp before it
            up = np.array([0.0, 0.0, SHALLOWER_M])
            np.testing.assert_allclose(p, targets[k][0] + up, atol=1e-12)
        # on the board's top face: within its half extent of its centre, near its top
        local = se3.quat_rotate(se3.quat_conjugate(quat[0]), p - pos[0])
        assert np.all(np.abs(local[:2]) <= 0.2 + 1e-9) and abs(local[2]) < 0.03


@pytest.mark.slow
def test_a_real_time_stream_plans_in_the_background_a_fast_replay_in_line(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Where the assist's planning runs: a thread of its own for a real-time source (the
    frames keep coming), the loop's thread for a replay as fast as possible (its clock
    takes the planning time); every plan has finished when the run returns."""
    import threading

    import thirdhand.live.assist
    from test_live_loop import cut, task_from_labels
    from thirdhand.live.assist import AssistOptions
    from thirdhand.live.loop import LiveLoop, LiveOptions
    from thirdhand.live.source import ReplaySource
    from thirdhand.synth import make_scene

    task = task_from_labels(make_scene("chair", seed=31))
    demo = cut(make_scene("chair", seed=32), 8.0)
    threads: list[str] = []
    plan = thirdhand.live.assist.plan_fetch

    def spy(*args: Any, **kwargs: Any) -> Any:
        threads.append(threading.current_thread().name)
        return plan(*args, **kwargs)

    monkeypatch.setattr(thirdhand.live.assist, "plan_fetch", spy)

    class RealTime:
        """The replay's frames, presented as a real-time source (speed 1, no waiting)."""

        speed = 1.0
        bodies, meta = demo.bodies, demo.meta

        def __iter__(self):  # type: ignore[no-untyped-def]
            return iter(ReplaySource(demo, 0))

    for source, where in (
        (ReplaySource(demo, 0), "MainThread"),
        (RealTime(), "thirdhand-assist-plan"),
    ):
        threads.clear()
        loop = LiveLoop(task, demo.bodies, demo.meta, options=LiveOptions(assist=AssistOptions()))
        report = loop.run(source)  # type: ignore[arg-type]
        assert threads and set(threads) == {where}
        assert loop.assist is not None and not loop.assist.planning
        # every assist planned to its end: a schedule or a reason
        for a in report.assists:
            assert a["outcome"] in ("moving", "ready", "late", "unreachable", "no path"), a
            assert a["plan_ms"] > 0


def test_an_error_in_the_background_is_raised_in_the_loops_thread() -> None:
    """The arm is set up in the background on a real-time stream: an arm that cannot be
    loaded fails there, and the error is raised by :meth:`RobotAssist.finish`, once."""
    from thirdhand.errors import ThirdhandError
    from thirdhand.live.assist import AssistOptions, RobotAssist

    box = {"bbox_min_m": [-0.1, -0.1, -0.01], "bbox_max_m": [0.1, 0.1, 0.01]}
    meta = {"geometry": {"board": box}}
    assist = RobotAssist(["board"], ["part"], meta, "board", AssistOptions(robot="no arm"))
    assert assist.background
    pos, quat = np.array([[0.0, 0.0, 0.76]]), np.array([[0.0, 0.0, 0.0, 1.0]])
    tracker = PlanTracker([], [], ["board"])
    assist.update(0.0, pos, quat, np.ones(1, dtype=bool), tracker, {})
    assert assist.planning  # the set-up runs in its own thread
    with pytest.raises(ThirdhandError, match="unknown robot 'no arm'"):
        assist.finish()
    assist.finish()  # raised once, then clear
    assert not assist.planning and assist.robot is None


def test_the_assembly_reach_composes_the_plan_poses_from_the_root() -> None:
    """A 0.2-m cube root, a 0.3-m bar on its +x face, a 0.1-m peg on the bar's end turned
    90° about z, and a step of parts no step places: the reach is the farthest box corner
    from the root's origin, worked out by hand."""
    from thirdhand.live.assist import assembly_reach
    from thirdhand.live.state import Slot

    def slot(step: int, parent: str, child: str, pos: list[float], yaw: float, rows: tuple) -> Slot:
        quat = np.array([0.0, 0.0, np.sin(yaw / 2.0), np.cos(yaw / 2.0)])
        return Slot(step, f"c{step}", parent, child, np.array(pos), quat, np.zeros(3),
                    np.array([0.0, 0.0, 0.0, 1.0]), np.zeros((6, 2)), [rows])  # fmt: skip

    geometry = {
        "base": {"bbox_min_m": [-0.1, -0.1, -0.1], "bbox_max_m": [0.1, 0.1, 0.1]},
        "bar1": {"bbox_min_m": [0.0, -0.01, -0.01], "bbox_max_m": [0.3, 0.01, 0.01]},
        "peg7": {"bbox_min_m": [0.0, -0.005, 0.0], "bbox_max_m": [0.1, 0.005, 0.02]},
    }
    names = ["base", "bar1", "peg7", "loose1", "loose2"]
    slots = [
        # the task calls them "bar" and "peg"; the stream's bodies (rows) carry the boxes
        slot(0, "base", "bar", [0.1, 0.0, 0.0], 0.0, (0, 1)),
        slot(1, "bar", "peg", [0.3, 0.0, 0.0], np.pi / 2, (1, 2)),
        slot(2, "loose", "other", [5.0, 0.0, 0.0], 0.0, (3, 4)),
    ]
    got = assembly_reach(slots, names, {"geometry": geometry}, "base")
    # the peg's far corner: (0.4, 0, 0) + Rz(90°)·(0.1, ±0.005, 0.02) = (0.4 ∓ 0.005, 0.1, 0.02)
    want = np.linalg.norm([0.405, 0.1, 0.02])
    assert got == pytest.approx(want, abs=1e-12)
    # without a box, a part counts as a cube of part_size_m; the root alone is its own box
    del geometry["peg7"]
    cube = np.linalg.norm([0.4 + 0.025, 0.025, 0.025])  # turned 90°: its x half-side on y
    assert assembly_reach(slots, names, {"geometry": geometry}, "base") == pytest.approx(cube)
    assert assembly_reach([], names, {"geometry": geometry}, "base") == pytest.approx(
        np.sqrt(3) * 0.1
    )


def test_the_hand_over_and_the_base_stand_beyond_the_assembly_reach() -> None:
    """The hand-over point is ``handover_m[0]`` beyond the finished assembly's reach from the
    root, away from the person, ``handover_m[2]`` up; the arm's base ``base_beyond_m`` past it."""
    from thirdhand.live.assist import AssistOptions, RobotAssist

    meta = {"geometry": {"seat": {"bbox_min_m": [-0.15] * 3, "bbox_max_m": [0.15] * 3}}}
    names, kinds = ["seat", "rh_index"], ["part", "finger"]
    opt = AssistOptions()
    assist = RobotAssist(names, kinds, meta, "seat", opt, reach_m=0.48)
    root = np.array([0.1, 0.2, 0.8])
    pos = np.array([root, root + np.array([0.0, -0.4, 0.1])])  # the person's hand on -y
    quat = np.tile([0.0, 0.0, 0.0, 1.0], (2, 1))
    assist.setup(pos, quat, np.ones(2, dtype=bool))
    assert assist.handover is not None
    hp = assist.handover[0]
    away = (hp - root)[:2] / np.linalg.norm((hp - root)[:2])
    assert away @ [0.0, 1.0] > 0.0  # on the far side from the person
    assert np.linalg.norm((hp - root)[:2]) == pytest.approx(0.48 + opt.handover_m[0], abs=1e-9)
    assert hp[2] == pytest.approx(root[2] + opt.handover_m[2])
    base = assist.base
    np.testing.assert_array_equal(base, assist.initial_base)
    reach = np.linalg.norm((base - root)[:2])
    assert reach == pytest.approx(0.48 + opt.handover_m[0] + opt.base_beyond_m, abs=1e-9) or (
        reach == pytest.approx(0.48 + opt.handover_m[0] + opt.base_beyond_m + 0.1, abs=1e-9)
    )
    # without a plan, the root's own box is the reach
    assert RobotAssist(names, kinds, meta, "seat").reach_m == pytest.approx(np.sqrt(3) * 0.15)


def test_a_part_the_arm_could_not_fetch_is_tried_again_once_it_or_what_was_near_moved() -> None:
    from thirdhand.live.fetch import RETRY_AFTER_S, RETRY_MOVED_M, failed_fetch, may_retry

    # rows: seat, leg1 (failed), leg2 (lying against it), a finger beside it, a far finger
    here = np.array([0.4, 0.1, 0.8])
    beside, hand = here + np.array([0.09, 0.0, 0.0]), here + np.array([0.0, 0.2, 0.0])
    pos = np.array([[0.0, 0.0, 0.8], here, beside, hand, [2.0, 0.0, 0.0]])
    valid = np.ones(5, dtype=bool)
    assert may_retry(None, 1, 0.0, pos, valid)
    # what was near leg1 when it failed: leg2 and the finger beside it (the seat is 0.41 m off)
    failed = failed_fetch(10.0, here.copy(), pos, valid, range(5), 1)
    assert failed.when_s == 10.0 and sorted(failed.near) == [2, 3]
    np.testing.assert_array_equal(failed.where, here)
    np.testing.assert_array_equal(failed.near[2], pos[2])
    np.testing.assert_array_equal(failed.near[3], pos[3])
    step = np.array([0.0, RETRY_MOVED_M, 0.0])
    later = 10.0 + RETRY_AFTER_S

    def moved(row: int, by: float) -> np.ndarray:
        out = pos.copy()
        out[row] += by * step
        return out

    assert not may_retry(failed, 1, later, pos, valid)  # nothing moved
    assert not may_retry(failed, 1, later, moved(1, 0.9), valid)
    assert may_retry(failed, 1, later, moved(1, 1.1), valid)  # the part itself
    assert may_retry(failed, 1, later, moved(3, 1.1), valid)  # the hand beside it
    assert may_retry(failed, 1, later, moved(2, 1.1), valid)  # the part against it
    assert not may_retry(failed, 1, later, moved(4, 10.0), valid)  # a hand far away
    assert not may_retry(failed, 1, later - 0.01, moved(1, 1.1), valid)  # too soon
    lost = valid.copy()
    lost[3] = False
    assert not may_retry(failed, 1, later, moved(3, 1.1), lost)  # a hand not seen now
    assert may_retry(None, 0, later, pos, valid)  # the seat never failed


@pytest.mark.parametrize("higher", [True, False])
def test_a_part_lying_against_another_is_lifted_clear_of_it(
    higher: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Two legs (28 × 8 × 8 cm boxes) lie side by side on the table, 7 cm apart and
    staggered by 22 cm along their length: their boxes' ends meet. The arm grasps leg1
    from above, lifts it straight up (touching leg2 and the table on the way is not a
    collision) until it touches nothing, 12 cm up, and brings it to the hand-over pose.
    A lift of 6 cm alone (``higher=False``, as before 2026-12-04) leaves it in leg2's box:
    no clear lift."""
    from thirdhand.live.assist import RobotAssist

    box = {"bbox_min_m": [-0.14, -0.04, -0.04], "bbox_max_m": [0.14, 0.04, 0.04]}
    seat = {"bbox_min_m": [-0.15, -0.15, -0.01], "bbox_max_m": [0.15, 0.15, 0.01]}
    meta = {"geometry": {"seat": seat, "leg1": box, "leg2": box}, "table_z_m": 0.75}
    names, kinds = ["seat", "leg1", "leg2", "rh_index"], ["part", "part", "part", "finger"]
    assist = RobotAssist(names, kinds, meta, "seat", reach_m=0.3)
    assist.background = False
    ident = [0.0, 0.0, 0.0, 1.0]
    pos = np.array([[0.0, 0.0, 0.76], [0.3, 0.15, 0.79], [0.52, 0.22, 0.79], [0.0, -0.5, 0.9]])
    quat = np.tile(ident, (4, 1))
    valid = np.ones(4, dtype=bool)
    assist.setup(pos, quat, valid)
    if not higher:
        monkeypatch.setattr("thirdhand.live.grasp.LIFT_STEPS", (1,))
    assist.start_fetch(0.0, 0, 1, pos, quat, valid)
    a = assist.active
    assert a is not None
    if not higher:
        assert (a.outcome, a.status) == ("unreachable", "no clear lift")
        return
    assert a.ready_s is not None and a.outcome == "moving", a.status
    assert a.resting == ("table", "leg2")
    lift = a.path[a.grasp_index + 1]  # the planned path goes on from the lift
    assert lift is not None
    scene = assist.plan_scene
    assert scene is not None
    grasp = a.path[a.grasp_index]
    scene.attach("leg1", grasp)
    try:
        assert scene.collisions(lift) == []  # clear of leg2 and the table, nothing allowed
        lifted = scene.object_pose("leg1", lift)[0]
        assert lifted[2] - pos[1, 2] == pytest.approx(2 * assist.options.lift_m, abs=1e-4)
    finally:
        scene.detach("leg1", grasp)


def test_the_part_being_mounted_is_planned_around_at_every_free_slot() -> None:
    """Two leg slots: at (0.1, 0.1, -0.05) in the seat, turned 180° about x, and at (-0.1,
    0.1, -0.05). The seat stands at (0.3, 0.2, 0.76) turned 90° about z. While a step is in
    progress and a hand holds leg2, the arm plans around leg2's box at each slot not done
    (world poses worked out by hand); not around leg1, held but already mounted; around
    nothing with no step in progress or the seat not tracked."""
    from thirdhand.live.fetch import mounting_poses
    from thirdhand.live.tracker import RecognisedStep

    ident = np.array([0.0, 0.0, 0.0, 1.0])
    flip = np.array([1.0, 0.0, 0.0, 0.0])  # 180° about x

    def slot(step: int, x: float) -> Slot:
        return Slot(step, f"c{step}", "seat", "leg", np.array([x, 0.1, -0.05]), flip,
                    np.zeros(3), ident, np.zeros((6, 2)), [(0, 1), (0, 2), (0, 3)])  # fmt: skip

    names = ["seat", "leg1", "leg2", "leg3", "rh_index"]
    parts = [0, 1, 2, 3]
    tracker = PlanTracker([slot(0, 0.1), slot(1, -0.1), slot(2, 0.0)], [[], [], []], names)
    tracker.done[2] = RecognisedStep(2, "c2", "seating", "leg1", 1.0, 0.5, True)
    yaw = np.array([0.0, 0.0, np.sin(np.pi / 4), np.cos(np.pi / 4)])
    pos = np.array([[0.3, 0.2, 0.76], [0.3, 0.2, 0.7], [0.5, -0.3, 0.9], [0.6, 0.4, 0.79],
                    [0.5, -0.3, 0.95]])  # fmt: skip
    quat = np.array([yaw, ident, ident, ident, ident])
    valid = np.ones(5, dtype=bool)
    held = {"seat", "leg1", "leg2"}

    def poses(held: set[str], valid: np.ndarray) -> list:
        return mounting_poses(tracker, names, parts, held=held, pos=pos, quat=quat, valid=valid)

    assert poses(held, valid) == []  # none in progress
    tracker.current = 0
    got = poses(held, valid)
    assert [row for row, _, _ in got] == [2, 2]
    # Rz(90°) (x, y) -> (-y, x); Rz(90°)·Rx(180°): x -> y, y -> x, z -> -z
    np.testing.assert_allclose(got[0][1], [0.3 - 0.1, 0.2 + 0.1, 0.76 - 0.05], atol=1e-12)
    np.testing.assert_allclose(got[1][1], [0.3 - 0.1, 0.2 - 0.1, 0.76 - 0.05], atol=1e-12)
    for _, _, turn in got:
        np.testing.assert_allclose(se3.quat_rotate(turn, [1.0, 0.0, 0.0]), [0, 1, 0], atol=1e-12)
        np.testing.assert_allclose(se3.quat_rotate(turn, [0.0, 0.0, 1.0]), [0, 0, -1], atol=1e-12)
    lost = valid.copy()
    lost[0] = False
    assert poses(held, lost) == []
    assert poses({"leg1"}, valid) == []  # mounted


def test_the_base_drives_round_a_board_on_its_track_to_a_part_out_of_reach() -> None:
    """A seat at the origin, the person's hand on -y, the track 0.52 m beyond the seat
    (reach 0.3 + hand-over 0.07 + base 0.15) along x. A 40 × 40 cm board lies across the
    track's middle: the base starts beside it. A leg lies on the board's other side, 0.8 m
    along x and 0.2 m towards the track: beyond the reach of an arm standing there (1.1 m
    and more away, its fetch unreachable), but the moving base drives back from the track
    round the board to a station near the leg and has it at the hand-over. The arm at home
    touches nothing at any point of the drive, checked in the world as tracked."""
    from thirdhand.live.assist import AssistOptions, RobotAssist

    def slot(step: int) -> Slot:
        ident = np.array([0.0, 0.0, 0.0, 1.0])
        return Slot(step, f"c{step}", "seat", "leg", np.zeros(3), ident, np.zeros(3), ident,
                    np.zeros((6, 2)), [(0, 1)])  # fmt: skip

    leg = {"bbox_min_m": [-0.14, -0.04, -0.04], "bbox_max_m": [0.14, 0.04, 0.04]}
    seat = {"bbox_min_m": [-0.15, -0.15, -0.01], "bbox_max_m": [0.15, 0.15, 0.01]}
    board = {"bbox_min_m": [-0.2, -0.2, -0.015], "bbox_max_m": [0.2, 0.2, 0.015]}
    meta = {"geometry": {"seat": seat, "leg1": leg, "back": board}, "table_z_m": 0.75}
    names, kinds = ["seat", "leg1", "back", "rh_index"], ["part", "part", "part", "finger"]
    ident = [0.0, 0.0, 0.0, 1.0]
    quat = np.tile(ident, (4, 1))
    valid = np.ones(4, dtype=bool)
    pos = np.array([[0.0, 0.0, 0.76], [0.0, 0.2, 0.79], [0.0, 0.6, 0.765], [0.0, -0.4, 0.9]])
    outcomes = {}
    for track_m in (0.0, 1.6):
        opt = AssistOptions(base_track_m=track_m)
        assist = RobotAssist(names, kinds, meta, "seat", opt, reach_m=0.3)
        assist.background = False
        assist.setup(pos, quat, valid)
        start = assist.initial_base.copy()
        if track_m:
            assert abs(start[0]) > 0.2  # beside the board, not on it
            assert start[1] == pytest.approx(0.52)
        # the leg on the far side of the board from where the base stands
        pos[1, 0] = -np.sign(start[0]) * 0.8
        assert np.linalg.norm(pos[1, :2] - start[:2]) > 1.1
        assist.start_fetch(1.0, 0, 1, pos, quat, valid)
        a = assist.active
        assert a is not None
        outcomes[track_m] = a.outcome
        if not track_m:
            continue
        assert a.outcome == "moving" and a.ready_s is not None, a.status
        route = a.base_route
        np.testing.assert_allclose(route[0], start, atol=1e-9)
        assert np.linalg.norm(route[-1][:2] - pos[1, :2]) < 0.8
        assert np.sign(route[-1][0]) == np.sign(pos[1, 0])
        # round the board: back from the track, beyond the board's far edge (y 0.8)
        assert route[:, 1].max() > 0.8
        assert a.times[0] == pytest.approx(a.base_times[-1])
        drive = np.linalg.norm(np.diff(route, axis=0), axis=1).sum()
        assert a.base_times[-1] - a.base_times[0] == pytest.approx(drive / opt.base_speed)
        assert a.to_dict()["base_travel_m"] == pytest.approx(drive, abs=1e-3)
        # the drive as the live loop checks it: every point, the world as tracked; the arm's
        # own motion waits for its end (the leg's step still needs it: the assist goes on)
        assert assist.driving is a
        tracker = PlanTracker([slot(0)], [[]], names)
        for t in a.base_times[:-1]:
            assist.update(float(t) + 1e-9, pos, quat, valid, tracker, {})
        assert assist.active is a and a.end_s is None
        assert a.checked == len(route) - 1 and a.collisions == 0
        assist.update(float(a.base_times[-1]), pos, quat, valid, tracker, {})
        assert assist.driving is None
        np.testing.assert_allclose(assist.base, route[-1], atol=1e-12)
    assert outcomes[0.0] == "unreachable"


def test_the_part_is_held_farthest_from_the_sphere_the_person_sweeps_first() -> None:
    """A 60-cm board grasped top-down at its middle, its length along the tool's x. The
    assembly reaches 0.45 m from the root at (0, 0, 0.76); the hand-over point is 0.52 m
    from the root towards the arm (+y) and 0.35 m up. The board's nearest corner is, from
    the root: turned 90° and raised 15 cm, 0.74 m; turned 90°, 0.65 m; along +y (yaw 0 or
    180°) raised, 0.54 m; along +y, 0.40 m (inside the sphere). Tried in that order."""
    from thirdhand.live.assist import RobotAssist
    from thirdhand.live.grasp import part_box
    from thirdhand.live.handover import handover_targets, targets_farthest_first
    from thirdhand.segment.contact import body_box

    board = {"bbox_min_m": [-0.3, -0.05, -0.015], "bbox_max_m": [0.3, 0.05, 0.015]}
    names, kinds = ["board", "seat", "rh_index"], ["part", "part", "finger"]
    assist = RobotAssist(names, kinds, {"geometry": {"board": board}}, "seat", reach_m=0.45)
    pos = np.array([[0.5, 0.0, 0.775], [0.0, 0.0, 0.76], [0.0, -0.4, 0.9]])
    quat = np.tile([0.0, 0.0, 0.0, 1.0], (3, 1))
    assist.setup(pos, quat, np.ones(3, dtype=bool))
    handover = assist.handover
    assert handover is not None
    np.testing.assert_allclose(handover[0], [0.0, 0.52, 1.11], atol=1e-9)
    # the part's frame in the tool's: x along the tool's x, z against the tool's (down)
    held = np.diag([1.0, -1.0, -1.0, 1.0])
    centre, size = part_box(body_box({"geometry": {"board": board}}, "board"), 0.05)
    got = targets_farthest_first(handover, centre, size, held, pos[1])  # about the seat
    want = handover_targets(handover)
    order = [
        next(k for k, w in enumerate(want) if np.allclose(w[0], g[0]) and np.allclose(w[1], g[1]))
        for g in got
    ]
    # mirror images tie (±90°, 0 and 180°): the order within each pair is the rounding's
    assert [set(order[k : k + 2]) for k in (0, 2, 4, 6)] == [{5, 6}, {1, 2}, {4, 7}, {0, 3}]
