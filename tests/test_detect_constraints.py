"""Constraint detection over time: the HMM, exact recovery on synthetic scenes, real data."""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np
import pytest

from thirdhand import se3
from thirdhand.constraints.detect import detect_constraints
from thirdhand.constraints.hmm import HMMParams, forward_backward
from thirdhand.constraints.types import ConstraintFitError
from thirdhand.errors import ThirdhandError
from thirdhand.metrics import corrections, pose_errors
from thirdhand.synth import SensorModel, make_scene


def test_forward_backward_matches_brute_force(rng: np.random.Generator) -> None:
    n_t = 5
    log_b = rng.normal(size=(2, n_t, 2))
    trans = np.array([[0.9, 0.1], [0.3, 0.7]])
    init = np.array([0.6, 0.4])
    gamma, xi, loglik = forward_backward(log_b, trans, init)
    total = 0.0
    for p in range(2):
        marg = np.zeros((n_t, 2))
        z = 0.0
        for path in itertools.product((0, 1), repeat=n_t):
            w = init[path[0]] * math.exp(log_b[p, 0, path[0]])
            for t in range(1, n_t):
                w *= trans[path[t - 1], path[t]] * math.exp(log_b[p, t, path[t]])
            z += w
            for t, s in enumerate(path):
                marg[t, s] += w
        np.testing.assert_allclose(gamma[p], marg / z, rtol=1e-10)
        total += math.log(z)
    assert loglik == pytest.approx(total, rel=1e-10)
    assert xi.sum() == pytest.approx(2 * (n_t - 1))


@pytest.mark.parametrize("scene", ["chair", "bench"])
def test_noise_free_scene_is_recovered_exactly(scene: str) -> None:
    demo = make_scene(scene, seed=0, sensor=None)
    det = detect_constraints(demo)
    truth = demo.labels.constraints
    assert det.root == "seating"
    got = [(i.parent, i.child, i.type) for i in det.instances]
    assert got == [(c.parent, c.child, c.type) for c in truth]
    for inst, ev in zip(det.instances, truth, strict=True):
        assert inst.end is None
        assert abs(inst.start - ev.time) < 0.15
        np.testing.assert_allclose(inst.pos, ev.pos, atol=1e-4)
        assert float(se3.quat_angle(inst.quat, np.asarray(ev.quat))) < math.radians(0.05)
        np.testing.assert_allclose(inst.ranges, ev.free_dofs.array(), atol=1e-12)
    assert corrections(det.instances, truth)[0] == 0


def test_default_noise_chair_within_bounds() -> None:
    demo = make_scene("chair", seed=1, sensor=SensorModel())
    det = detect_constraints(demo)
    errs = pose_errors(det.instances, demo.labels.constraints)
    assert len(errs) == 5
    assert max(e[0] for e in errs) <= 0.003
    assert max(e[1] for e in errs) <= 1.5
    wrong, total = corrections(det.instances, demo.labels.constraints)
    assert total == 30
    assert wrong <= 3


def test_one_part_is_rejected() -> None:
    demo = make_scene("chair", seed=0, sensor=None)
    with pytest.raises(ConstraintFitError, match="at least two parts"):
        detect_constraints(demo, parts=["seating"])
    with pytest.raises(ConstraintFitError, match="no body 'stool'"):
        detect_constraints(demo, parts=["seating", "stool"])
    # a position-only track (an articulation log) says why it holds no part
    track = _insertion_with_hidden_tag((0.0, 0.0)).select(["leg"])
    bodies = [dataclasses.replace(b, oriented=False) for b in track.bodies]
    flat = type(track)(track.t, bodies, {"leg": track.pos("leg")}, {"leg": track.quat("leg")}, None)
    with pytest.raises(ConstraintFitError) as info:
        detect_constraints(flat)
    assert str(info.value) == (
        "constraint detection needs at least two parts, got 0; the recording's bodies: "
        "leg (part, position only); one track of an articulated object: "
        "`thirdhand constraints fit`"
    )


def test_hmm_params_defaults_are_independent() -> None:
    a, b = HMMParams(), HMMParams()
    a.transition[0, 0] = 0.5
    assert b.transition[0, 0] != 0.5


def test_ikea_leg_goes_from_free_to_fixed(shared_data) -> None:  # type: ignore[no-untyped-def]
    from thirdhand.io import rosbag

    folder = shared_data / "niekum" / "ikea_table_leg_pos_1"
    demo = rosbag.read([folder / f"part{i}.bag" for i in range(1, 5)])
    det = detect_constraints(demo)
    assert len(det.instances) == 1
    inst = det.instances[0]
    assert {inst.parent, inst.child} == {"ar_0", "ar_13"}
    assert inst.type in ("fixed", "prismatic", "revolute")
    assert inst.end is None
    post = det.pair_posterior("ar_0", "ar_13")
    assert np.nanmax(post[det.times < inst.start - 5.0]) < 0.5
    assert 20.0 < inst.start < demo.t[-1] - 5.0


def test_lid_on_its_hinge_is_revolute_with_its_opening_range() -> None:
    demo = make_scene("lid", seed=0, sensor=None)
    (ev,) = demo.labels.constraints
    det = detect_constraints(demo)
    (inst,) = det.instances
    assert (inst.parent, inst.child, inst.type) == ("box", "lid", "revolute")
    assert inst.free_dofs.free() == ["rx"]
    assert inst.ranges[3, 0] == pytest.approx(0.0, abs=1e-6)
    # The range is the opening seen in the demonstration (at most the true 110°).
    assert math.radians(60.0) < inst.ranges[3, 1] <= ev.free_dofs["rx"][1] + 1e-6
    assert abs(inst.start - ev.time) < 0.3
    np.testing.assert_allclose(inst.pos, ev.pos, atol=1e-3)


def test_drawer_slides_in_its_rails() -> None:
    demo = make_scene("drawer", seed=0, sensor=SensorModel())
    (ev,) = demo.labels.constraints
    (inst,) = detect_constraints(demo).instances
    assert (inst.parent, inst.child, inst.type) == ("frame", "drawer", "prismatic")
    assert inst.free_dofs.free() == ["tx"]
    assert inst.ranges[0, 1] > 0.1
    np.testing.assert_allclose(inst.pos, ev.pos, atol=3e-3)
    # The drawer comes in along its rails: the slide starts at or before the rails.
    assert inst.start <= ev.time + 0.2


def test_assembly_taken_apart_and_redone() -> None:
    try:
        demo = make_scene("chair", seed=0, sensor=SensorModel(), cycles=2)
    except ThirdhandError as exc:  # the generator's repeated cycles, not this stage
        pytest.skip(f"synthetic chair with two cycles unavailable: {exc}")
    made = [e for e in demo.labels.constraints if not e.removed]
    removed = {(e.child, e.parent): e.time for e in demo.labels.constraints if e.removed}
    det = detect_constraints(demo)
    assert [(i.parent, i.child) for i in det.instances] == [(e.parent, e.child) for e in made]
    for inst, ev in zip(det.instances, made, strict=True):
        assert abs(inst.start - ev.time) < 0.3
        np.testing.assert_allclose(inst.pos, ev.pos, atol=3e-3)
        if inst.end is not None:
            assert abs(inst.end - removed[(ev.child, ev.parent)]) < 0.3
    assert sum(i.end is None for i in det.instances) == 5


def test_toolbox_boards_go_from_free_to_fixed(shared_data) -> None:  # type: ignore[no-untyped-def]
    """The whole cooperative toolbox recording (Polhemus, 19-25 % of samples lost):
    the two boards are apart, then rigidly attached to the end, once."""
    from thirdhand import io

    demo = io.load(shared_data / "3rdhand" / "toolbox_coop_4")
    boards = ["/toolbox/side_left", "/toolbox/side_front"]
    det = detect_constraints(demo, parts=boards)
    (inst,) = det.instances
    assert {inst.parent, inst.child} == set(boards)
    assert inst.type == "fixed"
    assert inst.end is None
    post = det.pair_posterior(*boards)
    t0 = float(demo.t[0])
    assert 10.0 < inst.start - t0 < float(demo.t[-1]) - t0 - 10.0
    assert np.nanmax(post[det.times < inst.start - 2.0]) < 0.5
    assert np.nanmin(post[det.times > inst.start + 2.0]) > 0.5


def test_a_free_spin_is_measured_on_the_samples_not_on_long_steps() -> None:
    """A part screwed in by 3 turns in 1 s, seen through 0.5-s steps (the length of an
    interaction phase's latent step): the step poses alias the turn (1.5 turns per step),
    the recording's samples give it, and the spin axis is the part's z."""
    from thirdhand.constraints.detect_dofs import _free_spin
    from thirdhand.constraints.detect_types import DetectOptions

    rate = 120.0
    t = np.arange(0.0, 3.0, 1.0 / rate)
    goal = np.array([0.0, 0.0, 0.1])
    # 0-1 s: down from 30 cm to the goal; 1-2 s: three turns about z there; then still
    z = np.where(t < 1.0, 0.3 - 0.2 * t, 0.1)
    p = np.column_stack([np.zeros_like(t), np.zeros_like(t), z])
    angle = 6.0 * np.pi * np.clip(t - 1.0, 0.0, 1.0)
    q = np.column_stack([np.zeros_like(t), np.zeros_like(t), np.sin(angle / 2), np.cos(angle / 2)])
    edges = np.arange(0.0, 3.0 + 1e-9, 0.5)
    centres = 0.5 * (edges[:-1] + edges[1:])
    at = np.searchsorted(t, centres)
    lo = 4  # the step starting at 2.0 s: the constraint holds from there
    opt = DetectOptions()
    _, _, stepped = _free_spin(p[at], q[at], lo, goal, q[-1], opt)
    assert stepped < 2.0 * np.pi  # aliased: under a third of the turn
    _, ranges, spin = _free_spin(p[at], q[at], lo, goal, q[-1], opt, raw=(t, p, q, edges))
    assert spin == pytest.approx(6.0 * np.pi, rel=0.02)
    np.testing.assert_allclose(ranges[5], [-np.pi, np.pi])
    assert not ranges[3:5].any() and not ranges[:3].any()


def test_a_segmented_chair_keeps_every_legs_spin() -> None:
    """Chair seed 33 learned with its interaction phases (the default): leg1's spin was
    measured on the phases' latent steps as 89 degrees and the leg learned as fixed."""
    from thirdhand.learn.run import learn_task

    task = learn_task(
        [make_scene("chair", seed=33)], primitives=False, reward=False, grasps=False
    ).task
    legs = [c for c in task.constraints if c.child.startswith("leg")]
    assert len(legs) == 4 and all(c.type == "revolute" for c in legs)


def _noisy_run(
    rng: np.random.Generator, n: int, sigma: tuple[float, float]
) -> tuple[np.ndarray, np.ndarray]:
    """``n`` steps at the identity pose with per-axis noise ``sigma`` (metres, radians)."""
    p = rng.normal(scale=sigma[0], size=(n, 3))
    q = se3.quat_from_rotvec(rng.normal(scale=sigma[1], size=(n, 3)))
    return p, q


def test_a_run_starts_where_its_parts_settle(rng: np.random.Generator) -> None:
    from thirdhand.constraints.detect_parents import SETTLED_SIGMA, _settled_start

    sigma = (0.003, math.radians(1.0))
    p, q = _noisy_run(rng, 60, sigma)
    identity = (np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]))
    # Parts held still at the pose from the run's start: it starts there.
    assert _settled_start(p, q, 0, 60, *identity, sigma, 5) == 0
    # Sliding 3 cm either way along each other for 15 steps, through the pose at
    # steps 0, 5 and 10 (where a smoother may open the run), then holding it.
    slide = p.copy()
    slide[:15, 0] += 0.03 * np.sin(np.linspace(0.0, 2.0 * np.pi, 15, endpoint=False) * 1.5)
    dev = np.linalg.norm(slide[:15], axis=1) / sigma[0]
    assert dev[0] <= SETTLED_SIGMA and np.median(dev[:5]) > SETTLED_SIGMA
    got = _settled_start(slide, q, 0, 60, *identity, sigma, 5)
    assert got == 15
    # One step of 6 noise levels within the hold neither delays nor advances it.
    bumped = p.copy()
    bumped[2, 0] += 6.0 * sigma[0]
    assert _settled_start(bumped, q, 0, 60, *identity, sigma, 5) == 0
    # Missing steps are skipped; a run that never settles starts where the HMM opened it.
    gap = p.copy()
    gap[:3] = np.nan
    assert _settled_start(gap, q, 0, 60, *identity, sigma, 5) == 3
    assert _settled_start(p + 0.05, q, 4, 60, *identity, sigma, 5) == 4


def test_a_run_pose_is_the_pose_held_not_the_mean_of_excursions(
    rng: np.random.Generator,
) -> None:
    from thirdhand.constraints.detect_runs import _run_pose

    sigma = (0.001, math.radians(0.3))
    p, q = _noisy_run(rng, 100, sigma)
    # The last 30 steps a person pushes the part 12 mm and 3° out of place.
    p[70:, 1] += 0.012
    q[70:] = se3.quat_multiply(
        se3.quat_from_rotvec(np.array([0.0, 0.0, math.radians(3.0)])), q[70:]
    )
    pos, quat = _run_pose(p, q, np.zeros(3))
    # The mean would be 3.6 mm and 0.9° off; the median of 70 held steps and 30
    # pushed ones is within the held steps' spread (a few sigma / sqrt(70)).
    assert np.linalg.norm(pos) < 0.0015
    assert math.degrees(float(se3.quat_angle(quat, np.array([0.0, 0.0, 0.0, 1.0])))) < 0.4


def _insertion_with_hidden_tag(hidden: tuple[float, float]):
    """A leg carried to a still table and inserted at 20 s, its tag hidden over ``hidden``.

    22 Hz like the AR tags of the IKEA bags; the table never moves, so only the
    approach can tell the insertion from two parts lying still side by side.
    """
    from thirdhand.demonstration import BodyInfo, Demonstration

    t = np.arange(0.0, 40.0, 1.0 / 22.0)
    table = np.tile([0.5, 0.3, -0.1], (t.size, 1))
    goal = table[0] + np.array([0.1, -0.1, 0.05])
    start = goal + np.array([0.3, 0.2, 0.15])
    s = np.clip((t - 10.0) / 10.0, 0.0, 1.0)
    s = s * s * (3.0 - 2.0 * s)  # smooth carry from 10 s to the insertion at 20 s
    leg = start + s[:, None] * (goal - start)
    quat = np.tile([0.0, 0.0, 0.0, 1.0], (t.size, 1))
    seen = ~((t >= hidden[0]) & (t < hidden[1]))
    return Demonstration(
        t,
        [BodyInfo("table"), BodyInfo("leg")],
        {"table": table, "leg": leg},
        {"table": quat, "leg": quat.copy()},
        {"table": np.ones(t.size, dtype=bool), "leg": seen},
    )


def test_an_insertion_hidden_from_the_camera_is_still_found() -> None:
    # The tag is hidden from 1 s into the carry to half a second after the insertion (a hand
    # over it), far longer than the approach window: the approach is looked for in
    # the last seconds the pair was seen, not in seconds of wall-clock time.
    demo = _insertion_with_hidden_tag((11.0, 20.5))
    det = detect_constraints(demo)
    assert [(i.parent, i.child, i.type) for i in det.instances] == [("table", "leg", "fixed")]
    inst = det.instances[0]
    assert inst.end is None  # kept to the end of the recording
    # found as the leg is seen again in place (the first latent step after 20.5 s)
    assert 20.5 - 1e-9 <= inst.start <= 20.5 + 0.1 + 1e-9
    np.testing.assert_allclose(inst.pos, [0.1, -0.1, 0.05], atol=1e-9)


def test_two_parts_lying_still_with_a_hidden_stretch_are_not_a_constraint() -> None:
    # Same scene with the leg never carried: no approach however far back one looks.
    demo = _insertion_with_hidden_tag((11.0, 20.5))
    still = type(demo)(
        demo.t,
        demo.bodies,
        {"table": demo.pos("table"), "leg": np.tile(demo.pos("leg")[0], (demo.n_frames, 1))},
        {b: demo.quat(b) for b in demo.body_names},
        {b: demo.valid(b) for b in demo.body_names},
    )
    assert detect_constraints(still).instances == []


def test_a_constraint_whose_tag_is_hidden_to_the_end_is_kept_to_the_end() -> None:
    # The leg's tag is lost 2 s after the insertion and never seen again: the
    # constraint holds to the end of the recording (the chain carries it).
    demo = _insertion_with_hidden_tag((22.0, 40.0))
    det = detect_constraints(demo)
    assert [(i.parent, i.child, i.type) for i in det.instances] == [("table", "leg", "fixed")]
    assert det.instances[0].end is None
    assert 19.0 <= det.instances[0].start <= 20.1
