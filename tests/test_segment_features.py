"""Windowed variances, the latent axis, intervals and hand aggregation."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from thirdhand import se3
from thirdhand.segment.design import FeatureConfig, design_matrix
from thirdhand.segment.features import (
    SegmentationError,
    body_stats,
    latent_axis,
    pair_stats,
    windowed_variance,
)
from thirdhand.segment.hands import aggregate_hand, aggregate_hands
from thirdhand.segment.intervals import (
    intervals_from_labels,
    labels_from_intervals,
    runs,
)


def _reference_variance(x, valid, step, n_steps, window):
    half = window // 2
    out, cnt = np.zeros(n_steps), np.zeros(n_steps)
    for k in range(n_steps):
        m = valid & (step >= k - half) & (step < k - half + window)
        cnt[k] = m.sum()
        if m.any():
            out[k] = np.mean(np.sum((x[m] - x[m].mean(axis=0)) ** 2, axis=1))
    return out, cnt


@pytest.mark.parametrize("window", [1, 4, 5])
def test_windowed_variance_matches_direct_computation(
    rng: np.random.Generator, window: int
) -> None:
    t = np.sort(rng.uniform(0, 3, 400))
    x = rng.standard_normal((400, 3))
    valid = rng.random(400) > 0.3
    valid[100:180] = False
    axis = latent_axis(t, 10.0)
    var, cnt = windowed_variance(np.where(valid[:, None], x, np.nan), valid, axis, window)
    ref, ref_cnt = _reference_variance(x, valid, axis.frame_step, axis.n_steps, window)
    np.testing.assert_array_equal(cnt, ref_cnt)
    np.testing.assert_allclose(var, ref, rtol=1e-12, atol=1e-14)


def test_windowed_variance_keeps_precision_far_from_origin(rng: np.random.Generator) -> None:
    t = np.arange(600) / 120.0
    jitter = 1e-6 * rng.standard_normal((600, 3))
    axis = latent_axis(t, 10.0)
    valid = np.ones(600, bool)
    near, _ = windowed_variance(jitter, valid, axis, 5)
    far, _ = windowed_variance(1500.0 + jitter, valid, axis, 5)
    # Subtracting 1500 already costs ~1e-13 m per sample; variances are ~3e-12 m².
    np.testing.assert_allclose(far, near, rtol=1e-3)
    assert np.all(far > 0)


def test_latent_axis_steps_and_edges() -> None:
    t = np.arange(25) / 10.0  # 0 … 2.4 s
    axis = latent_axis(t, 2.0)
    assert axis.n_steps == 5
    np.testing.assert_array_equal(axis.frame_step[:6], [0, 0, 0, 0, 0, 1])
    np.testing.assert_allclose(axis.times, [0.25, 0.75, 1.25, 1.75, 2.25])
    np.testing.assert_allclose(axis.frames_per_step, 5.0)
    with pytest.raises(SegmentationError, match="1 frame"):
        latent_axis(np.array([0.0]), 10.0)
    with pytest.raises(SegmentationError, match="positive"):
        latent_axis(t, 0.0)


def test_pair_stats_rigid_pair_has_zero_relative_variance(rng: np.random.Generator) -> None:
    n = 240
    t = np.arange(n) / 120.0
    r_a = Rotation.from_rotvec(np.outer(np.sin(t), [0.3, -1.0, 0.5]))
    p_a = np.column_stack([np.cos(t), np.sin(2 * t), t]) + 1.0
    off_p, off_q = np.array([0.1, -0.05, 0.02]), se3.random_quat(rng)
    p_b = p_a + r_a.apply(off_p)
    q_a = r_a.as_quat()
    q_b = (r_a * Rotation.from_quat(off_q)).as_quat()
    q_b[::7] *= -1.0  # sign flips must not matter
    valid = np.ones(n, bool)
    axis = latent_axis(t, 10.0)
    rel = pair_stats((p_a, q_a, valid), (p_b, q_b, valid), axis, 5)
    assert rel.var_pos.max() < 1e-25 and rel.var_rot.max() < 1e-25
    solo = body_stats(p_b, q_b, valid, axis, 5)
    assert solo.var_pos.min() > 1e-6 and solo.var_rot.min() > 1e-6


def test_pair_stats_matches_se3_relative_pose(rng: np.random.Generator) -> None:
    n = 120
    t = np.arange(n) / 60.0
    p_a, p_b = rng.standard_normal((n, 3)), rng.standard_normal((n, 3))
    q_a, q_b = se3.random_quat(rng, n), se3.random_quat(rng, n)
    valid = rng.random(n) > 0.2
    axis = latent_axis(t, 5.0)
    rel = pair_stats((p_a, q_a, valid), (p_b, q_b, valid), axis, 3)
    dp, dq = se3.relative_pose(p_a, q_a, p_b, q_b)
    dq = se3.quat_make_continuous(dq, valid)
    ref_p, cnt = _reference_variance(dp, valid, axis.frame_step, axis.n_steps, 3)
    ref_q, _ = _reference_variance(dq, valid, axis.frame_step, axis.n_steps, 3)
    np.testing.assert_allclose(rel.var_pos, ref_p, rtol=1e-10)
    np.testing.assert_allclose(rel.var_rot, ref_q, rtol=1e-10)
    np.testing.assert_array_equal(rel.count, cnt)


def test_design_matrix_log_transform_and_no_evidence_rows() -> None:
    cfg = FeatureConfig(eps_pos=1e-6, eps_rot=1e-5, distance=True, eps_dist=0.01)
    raw = np.array([[0.0, 0.0, 0.0, 0.0], [1.0, 2.0, 3.0, 4.0]])
    dist = np.array([0.0, 0.5])
    x = design_matrix(raw, np.array([True, False]), cfg, dist)
    ref = [1.0, np.log(1e-6), np.log(1e-5), np.log(1e-6), np.log(1e-5), np.log(0.01)]
    np.testing.assert_allclose(x[0], ref)
    np.testing.assert_array_equal(x[1], 0.0)
    report = FeatureConfig(transform="linear", distance=False)
    lin = design_matrix(raw, np.array([True, True]), report)
    np.testing.assert_array_equal(lin[1], [1, 1, 2, 3, 4])
    assert report.feature_names == ["bias", "nu_pos", "nu_rot", "zeta_pos", "zeta_rot"]
    with pytest.raises(SegmentationError, match="needs the pair distance"):
        design_matrix(raw, np.array([True, True]), cfg)
    with pytest.raises(SegmentationError, match="transform"):
        FeatureConfig(transform="sqrt")


def test_intervals_round_trip(rng: np.random.Generator) -> None:
    y = (rng.random(200) > 0.6).astype(np.int64)
    y[:3] = 1
    y[-2:] = 1
    edges = 5.0 + np.arange(201) / 10.0
    centres = 0.5 * (edges[1:] + edges[:-1])
    ints = intervals_from_labels(y, edges)
    np.testing.assert_array_equal(labels_from_intervals(ints, centres), y)
    assert ints[0][0] == 5.0 and ints[-1][1] == edges[-1]
    assert len(ints) == len(runs(y))
    assert intervals_from_labels(np.zeros(4, np.int64), edges[:5]) == []


def test_hand_aggregation_needs_two_fingers() -> None:
    f = [np.array([1, 1, 0, 0]), np.array([1, 0, 1, 0]), np.array([0, 0, 1, 0])]
    np.testing.assert_array_equal(aggregate_hand(f, min_fingers=2), [1, 0, 1, 0])
    np.testing.assert_array_equal(aggregate_hand(f, min_fingers=1), [1, 1, 1, 0])
    np.testing.assert_array_equal(aggregate_hand(f[:1], min_fingers=2), f[0])
    labels = {("t", "box"): f[0], ("i", "box"): f[1], ("t", "lid"): f[2]}
    out = aggregate_hands(labels, {"rh": ["t", "i"]}, min_fingers=2)
    np.testing.assert_array_equal(out[("rh", "box")], [1, 0, 0, 0])
    np.testing.assert_array_equal(out[("rh", "lid")], f[2])


def test_long_window_appends_the_same_features_over_a_longer_window(
    rng: np.random.Generator,
) -> None:
    from thirdhand.demonstration import BodyInfo, Demonstration
    from thirdhand.segment.design import DemoFeatures

    t = np.arange(600) / 120.0
    pos = {"a": rng.normal(0, 1e-3, (600, 3)), "b": np.cumsum(rng.normal(0, 1e-3, (600, 3)), 0)}
    quat = {k: np.tile([0.0, 0.0, 0.0, 1.0], (600, 1)) for k in pos}
    valid = {k: np.ones(600, dtype=bool) for k in pos}
    demo = Demonstration(t, [BodyInfo("a"), BodyInfo("b")], pos, quat, valid)
    short = FeatureConfig(latent_rate=20.0, window=5)
    both = FeatureConfig(latent_rate=20.0, window=5, long_window=10)
    long_only = FeatureConfig(latent_rate=20.0, window=10)
    xs, _ = DemoFeatures(demo, short).pair("a", "b")
    xb, _ = DemoFeatures(demo, both).pair("a", "b")
    xl, _ = DemoFeatures(demo, long_only).pair("a", "b")
    assert xb.shape == (xs.shape[0], 9) and len(both.feature_names) == 9
    np.testing.assert_allclose(xb[:, :5], xs, rtol=1e-12)
    np.testing.assert_allclose(xb[:, 5:], xl[:, 1:], rtol=1e-12)
    with pytest.raises(SegmentationError, match="long_window"):
        FeatureConfig(long_window=-1)


@pytest.mark.parametrize("window", [3, 4, 5])
def test_double_window_shortcut_matches_direct_merge(rng: np.random.Generator, window: int) -> None:
    from thirdhand.segment.features import (
        _moments_multi,  # the shortcut for (w, 2w)
        windowed_moments,
    )

    t = np.arange(3000) / 120.0
    x = 1.5 + np.cumsum(rng.normal(0, 1e-4, (3000, 3)), axis=0)
    valid = rng.random(3000) > 0.3
    valid[1000:1400] = False  # a long gap: empty windows
    axis = latent_axis(t, 20.0)
    short, long = _moments_multi(x, valid, axis, (window, 2 * window))
    for got, want in zip(long, windowed_moments(x, valid, axis, 2 * window), strict=True):
        np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-18)
    for got, want in zip(short, windowed_moments(x, valid, axis, window), strict=True):
        np.testing.assert_array_equal(got, want)
