"""Pose helpers against scipy's Rotation, with property tests near the singular cases."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from thirdhand import se3
from thirdhand.errors import ThirdhandError

unit = st.floats(-1.0, 1.0, allow_nan=False)
small = st.floats(-1e-6, 1e-6, allow_nan=False)


@st.composite
def near_identity(draw: st.DrawFn) -> np.ndarray:
    """Rotations within a micro-radian of the identity."""
    v = np.array([draw(small), draw(small), draw(small)])
    return Rotation.from_rotvec(v).as_quat()


@st.composite
def near_half_turn(draw: st.DrawFn) -> np.ndarray:
    """Rotations within a micro-radian of a 180° turn about a random axis."""
    axis = np.array([draw(unit), draw(unit), draw(unit)])
    if np.linalg.norm(axis) < 1e-3:
        axis = np.array([1.0, 0.0, 0.0])
    axis /= np.linalg.norm(axis)
    angle = np.pi + draw(small)
    return Rotation.from_rotvec(axis * angle).as_quat()


@st.composite
def any_quat(draw: st.DrawFn) -> np.ndarray:
    q = np.array([draw(unit) for _ in range(4)])
    if np.linalg.norm(q) < 1e-3:
        q = np.array([0.0, 0.0, 0.0, 1.0])
    return q / np.linalg.norm(q)


special = st.one_of(near_identity(), near_half_turn(), any_quat())


@settings(max_examples=200, deadline=None)
@given(special, special)
def test_multiply_matches_scipy(q1: np.ndarray, q2: np.ndarray) -> None:
    ref = (Rotation.from_quat(q1) * Rotation.from_quat(q2)).as_matrix()
    got = se3.matrix_from_quat(se3.quat_multiply(q1, q2))
    np.testing.assert_allclose(got, ref, atol=1e-12)


@settings(max_examples=200, deadline=None)
@given(special, st.lists(unit, min_size=3, max_size=3))
def test_rotate_matches_scipy(q: np.ndarray, v: list[float]) -> None:
    np.testing.assert_allclose(se3.quat_rotate(q, v), Rotation.from_quat(q).apply(v), atol=1e-12)


@settings(max_examples=200, deadline=None)
@given(special)
def test_matrix_round_trip(q: np.ndarray) -> None:
    back = se3.quat_from_matrix(se3.matrix_from_quat(q))
    assert se3.quat_angle(back, q) < 1e-7


@settings(max_examples=200, deadline=None)
@given(special, special, st.lists(unit, min_size=3, max_size=3))
def test_relative_pose_inverts_compose(qa: np.ndarray, qb: np.ndarray, p: list[float]) -> None:
    pa = np.asarray(p)
    pb = pa[::-1] * 0.5
    p_ab, q_ab = se3.relative_pose(pa, qa, pb, qb)
    p_back, q_back = se3.pose_compose(pa, qa, p_ab, q_ab)
    np.testing.assert_allclose(p_back, pb, atol=1e-12)
    assert se3.quat_angle(q_back, qb) < 1e-7
    p_inv, q_inv = se3.pose_invert(p_ab, q_ab)
    p_id, q_id = se3.pose_compose(p_ab, q_ab, p_inv, q_inv)
    np.testing.assert_allclose(p_id, 0.0, atol=1e-12)
    assert se3.quat_angle(q_id, [0, 0, 0, 1]) < 1e-7


@settings(max_examples=100, deadline=None)
@given(special, special, st.floats(0.0, 1.0))
def test_slerp_matches_scipy(q0: np.ndarray, q1: np.ndarray, w: float) -> None:
    from scipy.spatial.transform import Slerp

    ref = Slerp([0.0, 1.0], Rotation.from_quat([q0, q1]))([w]).as_quat()[0]
    got = se3.quat_slerp(q0, q1, w)
    # scipy takes the short path too; both are the same rotation up to sign.
    assert se3.quat_angle(got, ref) < 1e-6
    assert abs(np.linalg.norm(got) - 1.0) < 1e-12


def test_slerp_endpoints_exact(rng: np.random.Generator) -> None:
    q0, q1 = se3.random_quat(rng, 50), se3.random_quat(rng, 50)
    assert np.all(se3.quat_angle(se3.quat_slerp(q0, q1, np.zeros(50)), q0) < 1e-7)
    assert np.all(se3.quat_angle(se3.quat_slerp(q0, q1, np.ones(50)), q1) < 1e-7)


def test_make_continuous_removes_flips(rng: np.random.Generator) -> None:
    base = Rotation.from_rotvec(np.linspace(0, 3, 200)[:, None] * [0, 0, 1]).as_quat()
    flipped = base * rng.choice([-1.0, 1.0], size=(200, 1))
    fixed = se3.quat_make_continuous(flipped)
    assert np.all(np.sum(fixed[1:] * fixed[:-1], axis=1) > 0)
    assert np.allclose(np.abs(np.sum(fixed * base, axis=1)), 1.0)


def test_make_continuous_skips_invalid_frames() -> None:
    q = np.tile([0.0, 0.0, 0.0, 1.0], (5, 1))
    q[2] = np.nan
    q[3:] *= -1
    valid = np.array([True, True, False, True, True])
    fixed = se3.quat_make_continuous(q, valid)
    assert np.all(fixed[[0, 1, 3, 4], 3] == 1.0)
    assert np.all(np.isnan(fixed[2]))


def test_check_quat_errors() -> None:
    with pytest.raises(ThirdhandError, match="zero norm"):
        se3.check_quat([0, 0, 0, 0])
    with pytest.raises(ThirdhandError, match="shape"):
        se3.check_quat([0, 0, 1])
    with pytest.raises(ThirdhandError, match="unit norm"):
        se3.check_quat([0, 0, 0, 2], normalize=False)
    np.testing.assert_allclose(se3.check_quat([0, 0, 0, 2]), [0, 0, 0, 1])


def test_kabsch_exact_recovery_with_missing_markers(rng: np.random.Generator) -> None:
    ref = rng.normal(scale=0.05, size=(5, 3))
    n = 40
    q = se3.random_quat(rng, n)
    p = rng.normal(size=(n, 3))
    obs = se3.quat_rotate(q[:, None], ref[None]) + p[:, None]
    obs[::3, 1] = np.nan
    obs[::4, 4] = np.nan
    obs[7, :3] = np.nan  # only two markers left: not enough
    p_fit, q_fit, rms = se3.kabsch(ref, obs)
    ok = np.ones(n, bool)
    ok[7] = False
    np.testing.assert_allclose(p_fit[ok], p[ok], atol=1e-10)
    assert np.all(se3.quat_angle(q_fit[ok], q[ok]) < 1e-7)
    assert np.all(rms[ok] < 1e-10)
    assert np.isnan(p_fit[7]).all() and np.isnan(q_fit[7]).all()


def test_kabsch_never_returns_a_reflection(rng: np.random.Generator) -> None:
    ref = rng.normal(size=(4, 3))
    mirrored = ref * [1, 1, -1]
    _, q, _ = se3.kabsch(ref, mirrored[None])
    assert np.isclose(np.linalg.det(se3.matrix_from_quat(q[0])), 1.0)


@settings(max_examples=300, deadline=None)
@given(special)
def test_rotvec_matches_scipy_near_identity_and_half_turn(q: np.ndarray) -> None:
    rv = se3.rotvec_from_quat(q)
    assert np.linalg.norm(rv) <= np.pi + 1e-12
    # the same rotation as scipy's (whose rotation vector may be the other one at π)
    back = se3.quat_from_rotvec(rv)
    assert float(se3.quat_angle(back, q)) < 1e-9
    assert float(se3.quat_angle(se3.quat_from_rotvec(Rotation.from_quat(q).as_rotvec()), q)) < 1e-9
    if np.linalg.norm(rv) < 3.0:
        np.testing.assert_allclose(rv, Rotation.from_quat(q).as_rotvec(), atol=1e-12)
    # log/exp are the half-angle versions of the same map
    np.testing.assert_array_equal(se3.quat_log(q), 0.5 * rv)
    assert float(se3.quat_angle(se3.quat_exp(se3.quat_log(q)), q)) < 1e-9


def test_rotvec_exact_at_identity_and_sign_free() -> None:
    assert np.all(se3.rotvec_from_quat(np.array([0.0, 0.0, 0.0, -1.0])) == 0.0)
    np.testing.assert_array_equal(se3.quat_from_rotvec(np.zeros(3)), [0.0, 0.0, 0.0, 1.0])
    q = Rotation.from_rotvec([0.3, -0.2, 0.1]).as_quat()
    np.testing.assert_array_equal(se3.rotvec_from_quat(-q), se3.rotvec_from_quat(q))


def test_compiled_companions_match_numpy(rng: np.random.Generator) -> None:
    from thirdhand.se3_compiled import continuous_quat_rows, relative_pose_rows

    n = 400
    qa, qb = se3.random_quat(rng, n), se3.random_quat(rng, n)
    qa[::7] = [0.0, 0.0, 0.0, 1.0]  # identity rows
    qb[3::11] = -qb[3::11]
    pa, pb = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    valid = rng.random(n) > 0.2
    dp, dq = relative_pose_rows(pa, qa, pb, qb, valid)
    p_ref, q_ref = se3.relative_pose(pa, qa, pb, qb)
    q_ref = se3.quat_make_continuous(q_ref, valid)
    np.testing.assert_allclose(dp[valid], p_ref[valid], atol=1e-12)
    np.testing.assert_allclose(dq[valid], q_ref[valid], atol=1e-12)
    assert np.all(dp[~valid] == 0.0) and np.all(dq[~valid] == 0.0)
    qc = continuous_quat_rows(qb, valid)
    np.testing.assert_allclose(qc[valid], se3.quat_make_continuous(qb, valid)[valid], atol=0)
    np.testing.assert_array_equal(qc[~valid], qb[~valid])


@settings(max_examples=200, deadline=None)
@given(special, special)
def test_compiled_rotation_kernels_match_numpy(q1: np.ndarray, q2: np.ndarray) -> None:
    from thirdhand import se3_compiled as sc

    a = np.ascontiguousarray(q1, dtype=np.float64)
    b = np.ascontiguousarray(q2, dtype=np.float64)
    np.testing.assert_allclose(sc.qmul(*a, *b), se3.quat_multiply(a, b), atol=1e-15)
    v = np.array([0.3, -1.2, 0.7])
    np.testing.assert_allclose(sc.rotate_one(a, v), se3.quat_rotate(a, v), atol=1e-14)
    np.testing.assert_allclose(a[:3] * sc.rotvec_scale(*a), se3.rotvec_from_quat(a), atol=1e-14)
    m = np.ascontiguousarray(se3.matrix_from_quat(a))
    assert float(se3.quat_angle(sc.quat_from_frame(m), a)) < 1e-9
    # align_x: the x axis lands on the target, by the smallest turn. Within 1e-12 of
    # cos = -1 the kernel takes the exact half turn: off by at most sqrt(2e-12) rad.
    axis = se3.quat_rotate(b, np.array([1.0, 0.0, 0.0]))
    turned = sc.align_x(a, np.ascontiguousarray(axis))
    half_turn_slack = float(np.sqrt(2e-12)) + 1e-12
    np.testing.assert_allclose(
        se3.quat_rotate(turned, np.array([1.0, 0.0, 0.0])), axis, atol=half_turn_slack
    )
    x_a = se3.quat_rotate(a, np.array([1.0, 0.0, 0.0]))
    expected_turn = np.arccos(np.clip(x_a @ axis, -1.0, 1.0))
    # the same slack: arccos near -1 turns a 1e-12 cosine into sqrt(2e-12) rad
    assert abs(float(se3.quat_angle(turned, a)) - expected_turn) < half_turn_slack + 1e-9
    # frame_from_axes: x is the given axis, y the hint's perpendicular part
    hint = se3.quat_rotate(a, np.array([0.0, 1.0, 0.0]))
    f = sc.frame_from_axes(np.ascontiguousarray(axis), np.ascontiguousarray(hint))
    np.testing.assert_allclose(se3.quat_rotate(f, np.array([1.0, 0.0, 0.0])), axis, atol=1e-9)
    y = se3.quat_rotate(f, np.array([0.0, 1.0, 0.0]))
    perp = hint - (hint @ axis) * axis
    if np.linalg.norm(perp) > 1e-6:
        np.testing.assert_allclose(y, perp / np.linalg.norm(perp), atol=1e-6)


def test_euler_rotvec_and_matrix_conversions_match_scipy(rng: np.random.Generator) -> None:
    q = se3.random_quat(rng, 50).reshape(5, 10, 4)
    r = Rotation.from_quat(q.reshape(-1, 4))
    for seq in ("xyz", "XYZ", "zyx"):
        e = se3.euler_from_quat(q, seq)
        assert e.shape == (5, 10, 3)
        np.testing.assert_allclose(e.reshape(-1, 3), r.as_euler(seq), atol=1e-9)
        back = se3.quat_from_euler(e, seq)
        assert np.all(se3.quat_angle(back, q) < 1e-9)
        m = se3.matrix_from_euler(e, seq)
        np.testing.assert_allclose(m.reshape(-1, 3, 3), r.as_matrix(), atol=1e-12)
        np.testing.assert_allclose(se3.euler_from_matrix(m, seq), e, atol=1e-9)
    deg = se3.euler_from_quat(q, "xyz", degrees=True)
    np.testing.assert_allclose(np.radians(deg), se3.euler_from_quat(q, "xyz"), atol=1e-12)
    rv = r.as_rotvec().reshape(5, 10, 3)
    np.testing.assert_allclose(
        se3.matrix_from_rotvec(rv).reshape(-1, 3, 3), r.as_matrix(), atol=1e-12
    )
    np.testing.assert_allclose(se3.rotvec_from_matrix(r.as_matrix()), r.as_rotvec(), atol=1e-9)


def test_quat_mean_is_sign_blind_and_exact_on_a_symmetric_spread(rng: np.random.Generator) -> None:
    centre = se3.random_quat(rng)
    # Rotations ±θ about three axes around the centre: their mean is the centre.
    offsets = se3.quat_from_rotvec(np.concatenate([np.eye(3), -np.eye(3)]) * 0.3)
    qs = se3.quat_multiply(centre, offsets)
    qs[::2] *= -1.0  # either sign of each sample
    mean = se3.quat_mean(qs)
    assert float(se3.quat_angle(mean, centre)) < 1e-9 and mean[3] >= 0
    # Weights pull the mean to the heavier sample, as scipy's weighted mean does.
    w = np.arange(1.0, 7.0)
    ref = Rotation.from_quat(qs).mean(weights=w).as_quat()
    assert float(se3.quat_angle(se3.quat_mean(qs, w), ref)) < 1e-9


def test_transform_invert_composes_to_identity(rng: np.random.Generator) -> None:
    t = se3.matrix_from_pose(rng.normal(size=(7, 3)), se3.random_quat(rng, 7))
    inv = se3.transform_invert(t)
    np.testing.assert_allclose(inv @ t, np.broadcast_to(np.eye(4), (7, 4, 4)), atol=1e-12)
