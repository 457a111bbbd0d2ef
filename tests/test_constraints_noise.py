"""Noise estimated from the track, the degenerate-turn guard, artefacts and bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest

from thirdhand import se3
from thirdhand.constraints import ConstraintFitError, NoiseModel, fit_constraint
from thirdhand.constraints import geometry as g
from thirdhand.constraints.noise import (
    CEILING_FACTOR,
    FLOOR_FACTOR,
    MAX_POS_NOISE,
    MIN_POS_CEILING,
    ROT_FLOOR_FACTOR,
    _filter,
    _rot_residual_pair,
    estimate_noise,
)
from thirdhand.constraints.robust import prepare_track
from thirdhand.constraints.select import MIN_TURN
from thirdhand.datasets.joint_tracks import random_joint_track

KINDS = ("fixed", "prismatic", "revolute", "cylindrical", "free")


def _estimate(track_pos: np.ndarray, track_quat: np.ndarray | None) -> tuple[float, float]:
    p, q = prepare_track(track_pos, track_quat)
    e = estimate_noise(p, q)
    return e.sigma_pos, e.sigma_rot


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("sigma", [1e-5, 1e-3, 1e-2])
def test_estimate_recovers_white_noise(kind: str, sigma: float) -> None:
    """200 samples: about 580 residuals per level, a median's relative error of ~5 %."""
    rot = math.radians(0.5) * sigma / 1e-3
    for seed in range(5):
        t = random_joint_track(kind, np.random.default_rng(seed), pos_noise=sigma, rot_noise=rot)
        sp, sr = _estimate(t.pos, t.quat)
        # A free wander's third derivative leaves a few micrometres in a 7-sample quadratic.
        assert sp == pytest.approx(sigma, rel=0.2, abs=5e-6 if kind == "free" else 0.0)
        assert sr == pytest.approx(rot, rel=0.2, abs=5e-5 if kind == "free" else 0.0)


@pytest.mark.parametrize("kind", KINDS)
def test_estimate_ignores_gross_outliers(kind: str) -> None:
    """10 % of samples 10-50 cm away spoil half the 7-sample windows; they are left out."""
    for seed in range(5):
        t = random_joint_track(
            kind,
            np.random.default_rng(seed),
            pos_noise=1e-3,
            rot_noise=math.radians(0.5),
            outliers=0.1,
        )
        sp, sr = _estimate(t.pos, t.quat)
        assert sp == pytest.approx(1e-3, rel=0.35)
        assert sr == pytest.approx(math.radians(0.5), rel=0.35)


def test_noise_free_track_estimates_next_to_nothing() -> None:
    """A quadratic fits 7 samples of a smooth joint path to well under a micrometre."""
    for kind in ("fixed", "prismatic", "revolute", "cylindrical"):
        t = random_joint_track(kind, np.random.default_rng(3))
        sp, sr = _estimate(t.pos, t.quat)
        assert sp < 1e-6
        assert sr < 1e-6


def test_rotation_estimate_does_not_wrap_through_pi() -> None:
    """A 350° turn: rotation vectors are taken relative to each window's centre."""
    from scipy.spatial.transform import Rotation

    n = 300
    theta = np.linspace(0.0, math.radians(350.0), n)
    rng = np.random.default_rng(1)
    q = g.quat_axis_angle(np.array([0.0, 0.0, 1.0]), theta)
    sigma = math.radians(0.5)
    noise = Rotation.from_rotvec(sigma * rng.standard_normal((n, 3))).as_quat()
    q = se3.quat_multiply(np.ascontiguousarray(noise), q)
    e = estimate_noise(np.zeros((n, 3)), q)
    assert e.sigma_rot == pytest.approx(sigma, rel=0.15)


def test_estimate_is_capped_and_turned_into_bounds() -> None:
    rng = np.random.default_rng(0)
    e = estimate_noise(rng.uniform(-1.0, 1.0, (40, 3)))
    assert e.sigma_pos == MAX_POS_NOISE
    assert math.isnan(e.sigma_rot)
    nm = e.noise_model()
    assert nm.pos_floor == pytest.approx(FLOOR_FACTOR * MAX_POS_NOISE)
    assert nm.pos_ceiling >= nm.pos_floor
    t = random_joint_track("fixed", rng, pos_noise=1e-3, rot_noise=math.radians(0.5))
    p, q = prepare_track(t.pos, t.quat)
    est = estimate_noise(p, q)
    nm = est.noise_model()
    assert nm.pos_floor == pytest.approx(FLOOR_FACTOR * est.sigma_pos)
    assert nm.rot_floor == pytest.approx(ROT_FLOOR_FACTOR * est.sigma_rot)
    assert nm.pos_ceiling == max(MIN_POS_CEILING, CEILING_FACTOR * nm.pos_floor)
    assert est.to_dict()["window"] == 7


def test_estimate_rejects_bad_input() -> None:
    with pytest.raises(ConstraintFitError, match="at least 5 samples, got 4"):
        estimate_noise(np.zeros((4, 3)))
    with pytest.raises(ConstraintFitError, match="odd window"):
        estimate_noise(np.zeros((10, 3)), window=6)


def test_fit_reports_the_estimate_and_the_override() -> None:
    t = random_joint_track(
        "revolute", np.random.default_rng(2), pos_noise=2e-3, rot_noise=math.radians(1.0)
    )
    c = fit_constraint(t.pos, t.quat)
    assert c.type == "revolute"
    assert c.noise_source == "estimated"
    assert c.noise_pos == pytest.approx(2e-3, rel=0.2)
    assert c.noise_rot == pytest.approx(math.radians(1.0), rel=0.2)
    assert c.sigma_pos >= FLOOR_FACTOR * c.noise_pos * (1 - 1e-12)
    d = c.to_dict()
    assert d["noise"]["source"] == "estimated"
    given = fit_constraint(t.pos, t.quat, noise=NoiseModel.camera())
    assert given.noise_source == "given"
    assert given.sigma_pos >= 0.01


@pytest.mark.parametrize("kind", ("fixed", "prismatic", "revolute", "cylindrical"))
def test_short_tracks(kind: str) -> None:
    """20 samples, 1 mm / 0.5°: the joint type is still right."""
    for seed in range(10):
        t = random_joint_track(
            kind, np.random.default_rng(seed), n=20, pos_noise=1e-3, rot_noise=math.radians(0.5)
        )
        assert fit_constraint(t.pos, t.quat).type == kind, seed


def test_partial_opening_needs_orientations() -> None:
    """A door opened by 10°: orientations resolve the turn; positions alone do not.

    Its path bows by tan(10°/4)/2 = 2.2 % of its chord, under the 3 % that a
    tracker's systematic error may reach: position-only, it is called prismatic
    (with a note saying why when the revolute scored better).
    """
    for seed in range(10):
        t = random_joint_track(
            "revolute",
            np.random.default_rng(seed),
            pos_noise=1e-3,
            rot_noise=math.radians(0.5),
            span=math.radians(10.0),
        )
        c = fit_constraint(t.pos, t.quat)
        assert c.type == "revolute", seed
        assert np.degrees(np.ptp(c.ranges[3])) == pytest.approx(10.0, abs=2.0)
        assert fit_constraint(t.pos).type == "prismatic", seed


def test_degenerate_radius_is_prismatic() -> None:
    """A 2.5 m radius over a 45 cm stroke (a camera-bent drawer): prismatic.

    The arc turns 10.3° and bows by 2.3 % of its chord: with orientations that
    resolve the turn (0.2° noise) it is a revolute; with orientations that do not
    turn (a drawer) or none, prismatic. A 5 m radius (5.2°) is prismatic even with
    such orientations: under :data:`MIN_TURN` (7°) a turn is within a tracker's
    systematic orientation error.
    """
    n = 100
    rng = np.random.default_rng(0)
    still = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
    for radius, oriented_type in ((2.5, "revolute"), (5.0, "prismatic")):
        theta = np.linspace(0.0, 0.45 / radius, n)
        pos = np.column_stack([radius * np.sin(theta), radius * (1.0 - np.cos(theta)), np.zeros(n)])
        pos = pos + 1e-3 * rng.standard_normal(pos.shape)
        flat = fit_constraint(pos)
        assert flat.type == "prismatic"
        assert flat.notes and "revolute not chosen" in flat.notes[0]
        assert fit_constraint(pos, still).type == "prismatic"
        turning = g.quat_axis_angle(np.array([0.0, 0.0, 1.0]), theta)
        noise = g.quat_axis_angle(
            np.array([1.0, 0.0, 0.0]), math.radians(0.2) * rng.standard_normal(n)
        )
        assert fit_constraint(pos, se3.quat_multiply(noise, turning)).type == oriented_type
        assert (theta[-1] >= MIN_TURN) == (oriented_type == "revolute")


def test_bad_input_is_a_clear_error_or_a_documented_fit() -> None:
    """Fewer than 5 valid samples, all NaN, a constant track, mixed rows."""
    p = np.tile([0.1, 0.2, 0.3], (50, 1))
    q = np.tile([0.0, 0.0, 0.0, 1.0], (50, 1))
    with pytest.raises(ConstraintFitError, match="4 valid sample"):
        fit_constraint(p[:4], q[:4])
    with pytest.raises(ConstraintFitError, match="0 valid sample"):
        fit_constraint(np.full((30, 3), np.nan))
    # A constant track is fixed, at its pose exactly.
    for quat in (q, None):
        c = fit_constraint(p, quat)
        assert c.type == "fixed"
        np.testing.assert_allclose(c.pos, p[0], atol=1e-12)
        assert c.noise_pos < 1e-12
    # Mixed rows: those without an orientation are dropped ...
    rng = np.random.default_rng(0)
    line = np.column_stack([np.linspace(0.0, 0.3, 50), np.zeros(50), np.zeros(50)])
    line = line + 1e-3 * rng.standard_normal(line.shape)
    half = q.copy()
    half[::2] = np.nan
    c = fit_constraint(line, half)
    assert c.type == "prismatic"
    assert c.n_samples == 25
    # ... and when too few keep one, the error says how to fit positions only.
    few = q.copy()
    few[3:] = np.nan
    with pytest.raises(ConstraintFitError, match="47 more have a position but no orientation"):
        fit_constraint(line, few)


def test_rotation_residuals_of_two_windows_match_a_brute_force_sum() -> None:
    """One pass for windows 5 and 7 gives the filtered rotation vectors of each window."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(4)
    q = Rotation.from_rotvec(np.cumsum(0.2 * rng.standard_normal((30, 3)), axis=0)).as_quat()
    short, long_ = _rot_residual_pair(q, 5, 7)
    for w, res in ((5, short), (7, long_)):
        h = w // 2
        brute = np.array(
            [
                _filter(w)
                @ (
                    Rotation.from_quat(q[c]).inv() * Rotation.from_quat(q[c - h : c + h + 1])
                ).as_rotvec()
                for c in range(h, 30 - h)
            ]
        )
        np.testing.assert_allclose(res, brute, atol=1e-12)


def test_pose_bias_is_constant_on_a_still_part_and_bends_a_moving_one() -> None:
    """A pose-dependent error offsets a fixed track rigidly; a moving track's path bends."""
    fixed = random_joint_track("fixed", np.random.default_rng(2), bias=0.01, rot_bias=0.02)
    np.testing.assert_allclose(fixed.pos, np.tile(fixed.pos[0], (fixed.pos.shape[0], 1)))
    clean = random_joint_track("prismatic", np.random.default_rng(2))
    bent = random_joint_track("prismatic", np.random.default_rng(2), bias=0.01)
    dev = bent.pos - clean.pos
    assert 1e-4 < np.ptp(dev, axis=0).max() < 0.1
    # The draws of the rest of the track are unchanged by the bias's own generator.
    np.testing.assert_array_equal(bent.outliers, clean.outliers)


def test_coloured_noise_hides_from_a_short_window() -> None:
    """Noise correlated over 2 samples is under-read by 7-sample fits, less so by 15."""
    kw = {"pos_noise": 1e-3, "colour": 3e-3, "n": 1000}
    track = random_joint_track("prismatic", np.random.default_rng(3), **kw)
    p, _ = prepare_track(track.pos, None)
    short = estimate_noise(p).sigma_pos
    long_ = estimate_noise(p, window=15).sigma_pos
    assert short < 0.6 * math.hypot(1e-3, 3e-3)
    assert long_ > 1.2 * short
