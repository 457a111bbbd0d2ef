"""Segments per constraint, the primitives stage, serialisation, alignment, generalisation."""

from __future__ import annotations

import json

import numpy as np
import pytest

from thirdhand import se3
from thirdhand.primitives import PrimitiveError
from thirdhand.primitives.align import average, dtw
from thirdhand.primitives.segments import constraint_segments, group_segments
from thirdhand.primitives.serialize import (
    dmp_from_dict,
    dmp_to_dict,
    pose_dmp_from_dict,
    promp_from_dict,
)
from thirdhand.primitives.stage import (
    fit_constraint_primitive,
    generalisation_check,
    primitives_stage,
    rollout_in_world,
)
from thirdhand.synth import make_scene


@pytest.fixture(scope="module")
def chair() -> list:
    return [make_scene("chair", seed=s, sensor=None) for s in range(2)]


def test_segments_end_at_the_constraint_pose(chair: list) -> None:
    segs = constraint_segments(chair[0])
    assert [s.event.child for s in segs] == [
        e.child for e in sorted(chair[0].labels.constraints, key=lambda e: e.time)
    ]
    for s in segs:
        np.testing.assert_allclose(s.pos[-1], s.event.pos, atol=2e-3)
        assert se3.quat_angle(s.quat[-1], np.array(s.event.quat)) < np.radians(1.0)
        assert s.t[-1] <= s.event.time + 1e-9
        # the child was resting before the segment: it starts within the motion
        assert s.duration > 0.2
    starts = [s.t[0] for s in segs]
    events = [s.event.time for s in segs]
    assert all(a >= b for a, b in zip(starts[1:], events[:-1], strict=True))


def test_keyframes_argument_moves_the_start(chair: list) -> None:
    ev = sorted(chair[0].labels.constraints, key=lambda e: e.time)
    late = ev[0].time - 0.5
    segs = constraint_segments(chair[0], keyframe_times=[late, *[e.time for e in ev]])
    assert segs[0].t[0] >= late


def test_stage_block_is_json_and_rebuilds(chair: list) -> None:
    block = primitives_stage(chair, promp_weights=5)
    text = json.dumps(block.model_dump(mode="json", by_alias=True))
    back = json.loads(text)
    assert set(back["constraints"]) == {"c1", "c2", "c3", "c4", "c5"}
    c5 = back["constraints"]["c5"]
    assert c5["n_examples"] == 2 and c5["child"] == "back"
    dmp = pose_dmp_from_dict(c5["dmp"])
    _, p, _ = dmp.rollout(
        goal_pos=c5["goal"]["pos"], goal_quat=c5["goal"]["quat"], run_time=2 * dmp.position_.tau_
    )
    np.testing.assert_allclose(p[-1], c5["goal"]["pos"], atol=1e-4)
    pm = promp_from_dict(c5["promp"])
    assert pm.mean_trajectory([1.0]).shape == (1, 7)
    for c in back["constraints"].values():
        assert c["imitation_error"]["pos_m"] < 1e-3


def test_dmp_dict_round_trip_is_exact(chair: list) -> None:
    segs = group_segments([s for d in chair for s in constraint_segments(d)])
    prim = fit_constraint_primitive(segs["c5"], n_weights=20)
    for part in (prim.dmp.position_, prim.dmp.orientation_):
        again = dmp_from_dict(json.loads(json.dumps(dmp_to_dict(part))))
        np.testing.assert_array_equal(again.rollout()[1], part.rollout()[1])
    with pytest.raises(PrimitiveError, match="missing field 'weights'"):
        d = dmp_to_dict(prim.dmp.position_)
        del d["weights"]
        dmp_from_dict(d)


def test_generalisation_from_a_range_of_starts(chair: list) -> None:
    segs = group_segments([s for d in chair for s in constraint_segments(d)])
    prim = fit_constraint_primitive(segs["c3"])
    grid = np.array([[dx, 0.0, dz] for dx in (-0.2, 0.0, 0.2) for dz in (-0.2, 0.0, 0.2)])
    pe, re = generalisation_check(
        prim.dmp, goal_pos=prim.goal_pos, goal_quat=prim.goal_quat, offsets=grid, run_factor=2.0
    )
    assert pe.max() < 1e-3 and np.degrees(re.max()) < 0.1


def test_primitive_transfers_when_the_parent_moves(chair: list) -> None:
    segs = group_segments([s for d in chair for s in constraint_segments(d)])
    prim = fit_constraint_primitive(segs["c5"], n_weights=30)
    parent_p, parent_q = np.array([1.0, 2.0, 0.5]), np.array([0.0, 0.0, np.sin(0.6), np.cos(0.6)])
    start_p, start_q = parent_p + np.array([0.3, 0.2, 0.4]), np.array([0.1, 0.0, 0.0, 1.0])
    _, pw, qw = rollout_in_world(
        prim.dmp,
        parent_pos=parent_p,
        parent_quat=parent_q,
        start_pos=start_p,
        start_quat=start_q / np.linalg.norm(start_q),
        goal_pos=prim.goal_pos,
        goal_quat=prim.goal_quat,
        run_time=3 * prim.dmp.position_.tau_,
    )
    np.testing.assert_allclose(pw[0], start_p, atol=1e-12)
    gp, gq = se3.pose_compose(parent_p, parent_q, prim.goal_pos, prim.goal_quat)
    np.testing.assert_allclose(pw[-1], gp, atol=1e-4)
    assert se3.quat_angle(qw[-1], gq) < 1e-4


def test_dtw_identity_and_average() -> None:
    a = np.sin(np.linspace(0, 3, 40))
    path, cost = dtw(a, a)
    assert cost == 0.0 and np.all(path[:, 0] == path[:, 1])
    t = np.linspace(0, 1, 100)
    warped = [(t, np.sin(np.pi * t ** (1 + 0.3 * i))[:, None]) for i in range(4)]
    _, ph = average(warped, method="phase")
    _, dt = average(warped, method="dtw")
    assert dt.max() > ph.max()  # DTW keeps the peak that phase averaging blurs
    assert dt.max() == pytest.approx(1.0, abs=2e-3)


def test_average_handles_quaternion_sign_flips() -> None:
    t = np.linspace(0, 1, 50)
    q = np.stack([np.zeros(50), np.zeros(50), np.sin(t / 2), np.cos(t / 2)], axis=1)
    flipped = q.copy()
    flipped[10:20] *= -1
    _, m = average([(t, q), (t, -flipped)], quaternion_columns=slice(0, 4))
    assert se3.quat_angle(m, q).max() < 1e-9


def test_no_constraint_is_a_clear_error(chair: list) -> None:
    demo = chair[0].replace(labels=type(chair[0].labels)())
    with pytest.raises(PrimitiveError, match="no constraint event"):
        constraint_segments(demo)


def test_average_of_screwing_motions_started_far_apart() -> None:
    """Three turns about z to the same goal, starts 170° apart: the mean stays continuous."""
    from scipy.spatial.transform import Rotation

    t = np.linspace(0.0, 3.0, 301)
    s = t / t[-1]
    tracks = []
    for tilt in (0.0, np.radians(170.0)):
        turn = Rotation.from_rotvec(np.outer(6 * np.pi * (1 - s), [0, 0, 1]))
        lead = Rotation.from_rotvec(np.outer(tilt * (1 - s), [1, 0, 0]))
        q = se3.quat_make_continuous((turn * lead).as_quat())
        tracks.append((t, q))
    _, m = average(tracks, quaternion_columns=slice(0, 4))
    steps = np.degrees(se3.quat_angle(m[1:], m[:-1]))
    assert steps.max() < 5.0  # 3 turns over 300 samples are 3.6° per sample
    assert se3.quat_angle(m[-1], tracks[0][1][-1]) < 1e-9
    np.testing.assert_allclose(np.linalg.norm(m, axis=1), 1.0)


def test_noisy_tracks_with_gaps_and_sign_flips() -> None:
    """Default sensor model: 1 mm / 0.5° noise, occlusion gaps, random quaternion signs."""
    from thirdhand.synth import SensorModel

    demos = [make_scene("chair", seed=s, sensor=SensorModel()) for s in range(2)]
    block = primitives_stage(demos, promp_weights=5)
    assert set(block.constraints) == {"c1", "c2", "c3", "c4", "c5"}
    for c in block.constraints.values():
        assert c.imitation_error.pos_m < 5e-3 and c.imitation_error.rot_deg < 2.0
        assert c.raw_error.pos_m < 2e-2 and c.raw_error.rot_deg < 6.0


def test_segment_of_two_samples_is_a_clear_error(chair: list) -> None:
    demo = chair[0]
    ev = sorted(demo.labels.constraints, key=lambda e: e.time)[0]
    early = type(ev)(
        time=float(demo.t[1]), parent=ev.parent, child=ev.child, type=ev.type, symbol="c9"
    )
    with pytest.raises(PrimitiveError, match=r"constraint c9 .* at least 3 tracked samples.*got 2"):
        constraint_segments(demo, events=[early])


def test_a_constraint_made_at_the_start_is_skipped_with_its_reason(chair: list) -> None:
    # A constraint detected as made at the second frame (the parts were together
    # from the start, or the child was hidden until then) has one or two tracked
    # samples of approach: the stage learns the others and says why it left it out.
    demo = chair[0]
    evs = sorted(demo.labels.constraints, key=lambda e: e.time)
    early = type(evs[0])(
        time=float(demo.t[1]),
        parent=evs[0].parent,
        child=evs[-1].child,
        type="fixed",
        symbol="c9",
    )
    # and one whose child was hidden for its whole approach (an occluded AR tag)
    hidden = evs[1]
    valid = {b: demo.valid(b).copy() for b in demo.body_names}
    valid[hidden.child][(demo.t > evs[0].time + 1e-9) & (demo.t < hidden.time - 1e-9)] = False
    occluded = type(demo)(
        demo.t,
        demo.bodies,
        {b: demo.pos(b) for b in demo.body_names},
        {b: demo.quat(b) for b in demo.body_names},
        valid,
        labels=demo.labels,
        meta=demo.meta,
    )
    block = primitives_stage([occluded], events=[[early, *evs]], names=["chair0"])
    assert set(block.constraints) == {e.symbol for e in evs} - {hidden.symbol}
    assert len(block.skipped) == 2
    first, second = block.skipped
    assert first.startswith(f"chair0: constraint c9 {early.parent}->{early.child} at ")
    assert first.endswith("got 2 (no approach motion to learn from)")
    assert f"constraint {hidden.symbol} " in second
    assert "\n" not in first + second
    # round trip through the task-file model keeps the reasons
    again = type(block).model_validate(block.model_dump(by_alias=True))
    assert again.skipped == block.skipped
