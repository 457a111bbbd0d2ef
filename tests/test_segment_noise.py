"""The recording's own noise floor and the rest gate (thirdhand.segment.noise)."""

from __future__ import annotations

import numpy as np
import pytest

from thirdhand import se3
from thirdhand.segment.features import body_stats, latent_axis
from thirdhand.segment.noise import REST_FACTOR, at_rest, noise_floor
from thirdhand.synth.motion import quat_exp


def _track(
    rng: np.random.Generator, n: int, sigma: float, rot_sigma: float, motion: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    t = np.arange(n) / 100.0
    pos = np.tile([0.4, -0.2, 0.9], (n, 1))
    rv = np.zeros((n, 3))
    if motion:  # slow reaching, 10 cm at 0.2 Hz, and a turn
        pos = pos + 0.1 * np.sin(2 * np.pi * 0.2 * t)[:, None] * np.array([1.0, 0.5, 0.2])
        rv[:, 2] = 0.5 * np.sin(2 * np.pi * 0.1 * t)
    q = quat_exp(rv)
    pos = pos + rng.normal(0.0, sigma, (n, 3))
    q = se3.quat_multiply(q, quat_exp(rng.normal(0.0, rot_sigma, (n, 3))))
    return t, pos, q, np.ones(n, dtype=bool)


@pytest.mark.parametrize("sigma", [1e-5, 1e-4, 1e-3])
@pytest.mark.parametrize("motion", [False, True])
def test_the_floor_is_the_sensor_noise(sigma: float, motion: bool) -> None:
    rng = np.random.default_rng(7)
    t, pos, q, valid = _track(rng, 12_000, sigma, sigma * 20.0, motion)
    valid[rng.random(t.size) < 0.2] = False  # lost samples, as on a Polhemus
    f = noise_floor(pos, q, valid)
    # The median of ~6 000 chi-square(3) values: relative error ~ 2 %, plus the
    # motion's second difference (0.1 m at 0.2 Hz: 4e-7 m per step², far below 10 µm).
    assert f.pos_sigma_m == pytest.approx(sigma, rel=0.08)
    # Quaternion components carry half the rotation-vector noise each.
    assert np.sqrt(f.rot / 3.0) == pytest.approx(sigma * 20.0 / 2.0, rel=0.1)
    assert f.n > 4000


def test_rest_is_decided_from_the_floor_not_a_guess() -> None:
    rng = np.random.default_rng(3)
    n = 6000
    t, pos, q, valid = _track(rng, n, 2e-5, 2e-4, False)
    moving = (t > 20) & (t < 30)
    pos[moving] += (t[moving] - 20)[:, None] * np.array([0.02, 0.0, 0.0])  # 2 cm/s slide
    axis = latent_axis(t, 20.0)
    st = body_stats(pos, q, valid, axis, 5)
    rest = at_rest(st.var_pos, st.var_rot, noise_floor(pos, q, valid))
    centre = axis.times
    inside = (centre > 20.2) & (centre < 29.8)
    outside = (centre < 19.8) | (centre > 30.2)
    assert not rest[inside].any()
    # A 0.25 s window of a still body: its variance stays under 3x the floor
    # except with a probability of order 1e-4 per step.
    assert rest[outside].mean() > 0.99
    assert REST_FACTOR == 3.0


def test_an_unknown_floor_is_never_at_rest() -> None:
    n = 50
    pos = np.zeros((n, 3))
    q = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
    valid = np.zeros(n, dtype=bool)
    valid[::3] = True  # never three valid frames in a row
    f = noise_floor(pos, q, valid)
    assert f.n == 0 and np.isnan(f.pos)
    assert not at_rest(np.zeros(5), np.zeros(5), f).any()


def test_static_gaps_are_filled_and_moved_ones_are_not() -> None:
    from thirdhand.segment.static_fill import fill_static_gaps

    rng = np.random.default_rng(11)
    n = 2000
    t, pos, q, valid = _track(rng, n, 1e-4, 1e-3, False)
    floor = noise_floor(pos, q, valid)
    valid[500:700] = False  # 2 s hidden, the body did not move
    valid[1000:1100] = False  # 1 s hidden, and it moved by 5 cm meanwhile
    pos[1100:] += np.array([0.05, 0.0, 0.0])
    valid[1500:1900] = False  # 4 s: longer than allowed
    p2, q2, v2, filled = fill_static_gaps(t, pos, q, valid, floor, max_gap_s=3.0)
    assert filled == 200
    assert v2[500:700].all() and not v2[1000:1100].any() and not v2[1500:1900].any()
    # The filled pose is the mean of the two sides (5 frames each), within their noise.
    np.testing.assert_allclose(
        p2[600], pos[[495, 496, 497, 498, 499, 700, 701, 702, 703, 704]].mean(0)
    )
    assert np.linalg.norm(p2[600] - np.array([0.4, -0.2, 0.9])) < 5 * 1e-4 / np.sqrt(10) * 3
    np.testing.assert_allclose(np.linalg.norm(q2[v2], axis=1), 1.0)
    # The inputs are untouched.
    assert not valid[500:700].any()
