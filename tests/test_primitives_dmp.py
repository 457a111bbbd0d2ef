"""DMPs: exact rollout, time convention, imitation, new goals, orientation DMPs, bad input."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from thirdhand import se3
from thirdhand.primitives import DMP, PoseDMP, PrimitiveError, QuaternionDMP
from thirdhand.primitives.dmp import linear_rollout
from thirdhand.primitives.quaternion_dmp import quat_exp, quat_log


def smooth_demo(n: int = 241, duration: float = 2.0) -> tuple[np.ndarray, ...]:
    """A smooth 6-DoF motion that starts and ends at rest (minimum-jerk blend)."""
    t = np.linspace(0.0, duration, n)
    s = t / duration
    blend = 10 * s**3 - 15 * s**4 + 6 * s**5
    pos = np.stack(
        [
            0.3 * blend,
            0.1 * np.sin(np.pi * blend),
            -0.2 * blend + 0.05 * np.sin(2 * np.pi * s) ** 2,
        ],
        axis=1,
    )
    rv = np.stack([1.2 * blend, 0.4 * np.sin(np.pi * blend), -0.6 * blend], axis=1)
    return t, pos, Rotation.from_rotvec(rv).as_quat()


def test_linear_rollout_matches_ode_solver() -> None:
    s = np.linspace(0.0, 1.0, 201)
    u = np.stack([np.sin(7 * s), s**2], axis=1)
    e, ed = linear_rollout(
        s, u, np.array([1.0, -1.0]), np.array([0.5, 0.0]), k=156.25, d=25.0, tau=1.0
    )

    def rhs(t: float, z: np.ndarray) -> np.ndarray:
        uu = np.array([np.interp(t, s, u[:, 0]), np.interp(t, s, u[:, 1])])
        return np.concatenate([z[2:], -156.25 * z[:2] - 25.0 * z[2:] + uu])

    sol = solve_ivp(rhs, (0, 1), [1, -1, 0.5, 0], t_eval=s, rtol=1e-11, atol=1e-12, max_step=1e-3)
    np.testing.assert_allclose(e, sol.y[:2].T, atol=1e-7)
    np.testing.assert_allclose(ed, sol.y[2:].T, atol=1e-6)


def test_time_convention_starts_at_zero_and_ends_at_tau() -> None:
    t, pos, _ = smooth_demo()
    dmp = DMP(30).fit(t + 5.0, pos)  # absolute times do not matter, only t - t0
    s, y, _ = dmp.rollout()
    assert s[0] == 0.0 and s[-1] == pytest.approx(2.0)
    assert s.size == t.size
    np.testing.assert_allclose(y[0], pos[0], atol=1e-12)


def test_imitation_reproduces_demo_below_one_millimetre() -> None:
    t, pos, _ = smooth_demo()
    _, y, _ = DMP(30).fit(t, pos).rollout()
    assert np.abs(y - pos).max() < 1e-3


def test_new_goal_and_start_reached() -> None:
    t, pos, _ = smooth_demo()
    dmp = DMP(30).fit(t, pos)
    goal = pos[-1] + np.array([0.1, -0.05, 0.2])
    start = pos[0] + np.array([-0.2, 0.1, 0.0])
    _, y, yd = dmp.rollout(start=start, goal=goal)
    np.testing.assert_allclose(y[0], start)
    assert np.linalg.norm(y[-1] - goal) < 0.02  # still settling at s = tau
    _, y, yd = dmp.rollout(start=start, goal=goal, run_time=8.0)
    assert np.linalg.norm(y[-1] - goal) < 1e-6 and np.linalg.norm(yd[-1]) < 1e-5
    _, y, _ = dmp.rollout(goal=pos[-1], run_time=8.0)
    assert np.linalg.norm(y[-1] - pos[-1]) < 1e-6


def test_temporal_scaling_keeps_the_path() -> None:
    t, pos, _ = smooth_demo()
    dmp = DMP(30).fit(t, pos)
    _, y_slow, _ = dmp.rollout(duration=4.0)
    assert y_slow.shape[0] == t.size
    assert np.abs(y_slow - pos).max() < 1e-3


@pytest.mark.parametrize("orientation", ["quaternion", "seven"])
def test_pose_dmp_imitates_six_dof_demo(orientation: str) -> None:
    t, pos, quat = smooth_demo()
    dmp = PoseDMP(30, orientation=orientation).fit(t, pos, quat)  # type: ignore[arg-type]
    _, p, q = dmp.rollout()
    assert np.abs(p - pos).max() < 1e-3
    assert np.degrees(se3.quat_angle(q, quat).max()) < 0.2
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-12)


def test_quaternion_dmp_reaches_new_goal_orientation() -> None:
    t, _, quat = smooth_demo()
    qd = QuaternionDMP(30).fit(t, quat)
    goal = Rotation.from_rotvec([0.3, -1.0, 2.0]).as_quat()
    starts = Rotation.from_rotvec(np.random.default_rng(1).normal(0, 0.5, (5, 3))).as_quat()
    _, q, _ = qd.rollout(start=starts, goal=goal, run_time=8.0)
    assert q.shape == (t.size * 4 - 3, 5, 4)
    assert np.degrees(se3.quat_angle(q[-1], goal).max()) < 1e-3


def _numpy_rk4(
    dmp: QuaternionDMP, start: np.ndarray, goal: np.ndarray, w0: np.ndarray, run_time: float
) -> tuple[np.ndarray, np.ndarray]:
    """The rollout's RK4 written with the numpy quaternion functions (the reference)."""
    from thirdhand.primitives.dmp import forcing_features, phase, tail_gate

    tau, s = dmp.time_grid(None, run_time, None, "reference")
    n, m, k, d = len(s), dmp.substeps, dmp.stiffness, dmp.alpha
    q, w = start.copy(), w0.copy()
    e0 = 2.0 * quat_log(se3.quat_multiply(goal, se3.quat_conjugate(q)))
    fine = np.linspace(0.0, float(s[-1]), 2 * m * (n - 1) + 1)
    x = phase(fine, tau, dmp.alpha_x_)
    fx = forcing_features(x, *dmp.basis()) @ dmp.weights_
    drive = tail_gate(fine, tau)[:, None, None] * (fx[:, None] - k * e0[None] * x[:, None, None])
    drive /= tau**2
    h = (s[1] - s[0]) / m

    def deriv(qq: np.ndarray, ww: np.ndarray, j: int) -> tuple[np.ndarray, np.ndarray]:
        e = 2.0 * quat_log(se3.quat_multiply(goal, se3.quat_conjugate(qq)))
        wdot = k / tau**2 * e - d / tau * ww + drive[j]
        return 0.5 * se3.quat_multiply(np.concatenate([ww, 0 * ww[:, :1]], 1), qq), wdot

    qs, ws = [q], [w]
    for i in range(1, n):
        for sub in range(m):
            j = 2 * ((i - 1) * m + sub)
            k1 = deriv(q, w, j)
            k2 = deriv(q + 0.5 * h * k1[0], w + 0.5 * h * k1[1], j + 1)
            k3 = deriv(q + 0.5 * h * k2[0], w + 0.5 * h * k2[1], j + 1)
            k4 = deriv(q + h * k3[0], w + h * k3[1], j + 2)
            q = q + h / 6.0 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
            w = w + h / 6.0 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
            q = q / np.linalg.norm(q, axis=1, keepdims=True)
        qs.append(q)
        ws.append(w)
    return np.stack(qs), np.stack(ws)


def test_compiled_quaternion_rollout_equals_the_numpy_reference() -> None:
    t, _, quat = smooth_demo()
    qd = QuaternionDMP(25).fit(t, quat)
    goal = Rotation.from_rotvec([0.3, -1.0, 2.0]).as_quat()
    rng = np.random.default_rng(4)
    starts = Rotation.from_rotvec(rng.normal(0, 1.0, (4, 3))).as_quat()
    # the goal itself (no turn left: the small-angle branch) and a start more than a
    # half turn away in quaternion sign (the shorter-turn branch)
    starts = np.vstack([starts, goal, -Rotation.from_rotvec([2.9, 0.0, 0.0]).as_quat()])
    w0 = rng.normal(0, 0.5, (starts.shape[0], 3))
    _, q, w = qd.rollout(start=starts, goal=goal, start_velocity=w0, run_time=3.0)
    q_ref, w_ref = _numpy_rk4(qd, starts, goal, w0, 3.0)
    # Same operations in another order: rounding differences of a few ulps, grown
    # over ~2,400 RK4 steps of a contracting system, stay far below 1e-10.
    np.testing.assert_allclose(q, q_ref, atol=1e-10)
    np.testing.assert_allclose(w, w_ref, atol=1e-9)


def test_sign_flips_in_quaternion_input_are_harmless() -> None:
    t, _, quat = smooth_demo()
    flipped = quat.copy()
    flipped[::7] *= -1.0
    a = QuaternionDMP(20).fit(t, quat)
    b = QuaternionDMP(20).fit(t, flipped)
    np.testing.assert_allclose(a.weights_, b.weights_, atol=1e-9)
    seven = PoseDMP(20, orientation="seven").fit(t, np.zeros((t.size, 3)), flipped)
    _, _, q = seven.rollout()
    assert np.degrees(se3.quat_angle(q, quat).max()) < 0.2


def test_quat_log_exp_round_trip() -> None:
    q = Rotation.from_rotvec(np.random.default_rng(2).normal(0, 1.0, (50, 3))).as_quat()
    back = quat_exp(quat_log(q))
    assert se3.quat_angle(back, q).max() < 1e-12
    np.testing.assert_allclose(quat_log(np.array([0, 0, 0, 1.0])), 0.0)


def test_bad_input_raises_clear_errors() -> None:
    t, pos, quat = smooth_demo()
    with pytest.raises(PrimitiveError, match="at least 3 samples, got 2"):
        DMP().fit(t[:2], pos[:2])
    bad = pos.copy()
    bad[17, 1] = np.nan
    with pytest.raises(PrimitiveError, match="sample 17 is not finite"):
        DMP().fit(t, bad, name="leg1 segment")
    with pytest.raises(PrimitiveError, match="at least 3 samples, got 0"):
        DMP().fit(np.zeros(0), np.zeros((0, 3)))
    with pytest.raises(PrimitiveError, match="increase strictly"):
        DMP().fit(np.r_[t[:5], t[4:]], np.r_[pos[:5], pos[4:]])
    q0 = quat.copy()
    q0[3] = 0.0
    with pytest.raises(PrimitiveError, match="sample 3 has zero norm"):
        QuaternionDMP().fit(t, q0)
    with pytest.raises(PrimitiveError, match="goal must be 3 finite"):
        DMP().fit(t, pos).rollout(goal=[1.0, 2.0])


def test_fft_convolution_is_the_direct_sum() -> None:
    """``dmp._convolve`` (numpy's FFT) against the direct sum, broadcast over trailing axes."""
    from thirdhand.primitives.dmp import _convolve

    rng = np.random.default_rng(4)
    for na, nb in ((1, 1), (2, 5), (17, 17), (300, 120)):
        a, b = rng.normal(size=(na, 2, 1)), rng.normal(size=(nb, 1, 3))
        want = np.empty((na + nb - 1, 2, 3))
        for i in range(2):
            for j in range(3):
                want[:, i, j] = np.convolve(a[:, i, 0], b[:, 0, j])
        # round-off of an FFT of that length: a few ulps times the sum of |terms|
        scale = np.sqrt(na * nb) * np.abs(a).max() * np.abs(b).max()
        np.testing.assert_allclose(_convolve(a, b), want, rtol=0, atol=1e-13 * scale)
