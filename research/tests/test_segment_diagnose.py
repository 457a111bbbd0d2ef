"""Error breakdown, tolerant F1, contact distance and the extra feature windows."""

from __future__ import annotations

import numpy as np
import pytest

from research.segment_diagnose import (
    ERROR_CLASSES,
    boundary_collar,
    breakdown_many,
    error_breakdown,
)
from thirdhand import se3
from thirdhand.segment.contact import body_box, box_gap
from thirdhand.segment.design import DemoFeatures, FeatureConfig
from thirdhand.segment.features import SegmentationError
from thirdhand.segment.model import SegmentModel


def _y(s: str) -> np.ndarray:
    return np.array([int(c) for c in s], dtype=np.int64)


@pytest.mark.parametrize(
    ("truth", "pred", "expected"),
    [
        ("0011110000", "0001110000", {"boundary": 1}),  # late start by one step
        ("0011110000", "0111111000", {"boundary": 2}),  # early start, late end
        ("0011110000", "0000000000", {"missed": 4}),
        ("0000000000", "0000001100", {"extra": 2}),
        ("0110110000", "0111110000", {"other": 1}),  # bridged gap
        ("0111111000", "0110111000", {"other": 1}),  # hole
        ("0011110000", "0000011100", {"other": 5}),  # shifts by more than k
    ],
)
def test_error_classes_of_hand_made_sequences(truth: str, pred: str, expected: dict) -> None:
    b = error_breakdown(_y(truth), _y(pred), k=1)
    assert b.errors == {c: expected.get(c, 0) for c in ERROR_CLASSES}
    assert sum(b.errors.values()) == b.false_pos + b.false_neg


def test_boundary_shift_of_k_steps_scores_one_with_the_collar() -> None:
    truth = _y("000111111000011100")
    pred = _y("001111110000111110")
    b = error_breakdown(truth, pred, k=1)
    assert b.f1 < 1.0
    assert b.collar_f1 == 1.0
    assert b.errors["boundary"] == b.false_pos + b.false_neg
    assert error_breakdown(truth, pred, k=0).collar_f1 == pytest.approx(b.f1)


def test_collar_and_counts_against_brute_force() -> None:
    rng = np.random.default_rng(3)
    truths = [(rng.random(60) < 0.5).astype(np.int64) for _ in range(30)]
    preds = [(rng.random(60) < 0.5).astype(np.int64) for _ in range(30)]
    total = breakdown_many(truths, preds, k=2)
    tp = fp = fn = 0
    for t, p in zip(truths, preds, strict=True):
        for i in range(t.size):
            near = any(t[j] != t[j - 1] and i - 2 < j <= i + 2 for j in range(1, t.size))
            if near:
                continue
            tp += int(t[i] and p[i])
            fp += int(not t[i] and p[i])
            fn += int(t[i] and not p[i])
        assert boundary_collar(t, 0).sum() == 0
    assert (total.collar_tp, total.collar_fp, total.collar_fn) == (tp, fp, fn)
    assert sum(total.errors.values()) == total.false_pos + total.false_neg


def _random_quat(rng: np.random.Generator, n: int) -> np.ndarray:
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def _box_points(lo: np.ndarray, hi: np.ndarray, m: int = 9) -> np.ndarray:
    g = np.linspace(0.0, 1.0, m)
    u = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)
    return lo + u * (hi - lo)


def test_box_gap_bounds_the_sampled_distance_and_is_exact_for_points() -> None:
    rng = np.random.default_rng(0)
    box_a = (np.array([-0.1, -0.05, -0.02]), np.array([0.1, 0.05, 0.02]))
    box_b = (np.array([0.0, -0.01, -0.01]), np.array([0.2, 0.01, 0.01]))
    pa = _box_points(*box_a)
    pb = _box_points(*box_b)
    pos = rng.uniform(-0.4, 0.4, size=(40, 3))
    quat = _random_quat(rng, 40)
    gap = box_gap(pos, quat, box_a, box_b)
    for i in range(40):
        b_in_a = pos[i] + se3.quat_rotate(quat[i], pb)
        sampled = np.min(np.linalg.norm(b_in_a[:, None, :] - pa[None, :, :], axis=2))
        # The sampled distance is an upper bound of the true one; the corner
        # approximation too, and it is never below the true distance.
        true_lower = (
            sampled
            - np.linalg.norm((box_a[1] - box_a[0]) / 8)
            - np.linalg.norm((box_b[1] - box_b[0]) / 8)
        )
        assert gap[i] >= true_lower - 1e-12
    # A point (no box) against a box: exact distance to the box.
    p = np.array([[0.3, 0.0, 0.0], [0.0, 0.0, 0.0], [0.2, 0.15, 0.0]])
    q = np.tile([0.0, 0.0, 0.0, 1.0], (3, 1))
    assert np.allclose(box_gap(p, q, box_a, None), [0.2, 0.0, np.hypot(0.1, 0.1)])
    # Neither has a box: the distance between the origins.
    assert np.allclose(box_gap(pos, quat, None, None), np.linalg.norm(pos, axis=1))


def test_box_gap_is_zero_for_boxes_resting_face_to_face() -> None:
    box = (np.array([-0.1, -0.1, -0.01]), np.array([0.1, 0.1, 0.01]))
    pos = np.array([[0.05, 0.02, 0.02], [0.05, 0.02, 0.025]])
    q = np.tile([0.0, 0.0, 0.0, 1.0], (2, 1))
    assert np.allclose(box_gap(pos, q, box, box), [0.0, 0.005])


def test_body_box_reads_geometry_and_rejects_a_malformed_box() -> None:
    meta = {"geometry": {"a": {"bbox_min_m": [0, 0, 0], "bbox_max_m": [1, 2, 3]}, "b": {}}}
    _, hi = body_box(meta, "a")  # type: ignore[misc]
    assert hi.tolist() == [1.0, 2.0, 3.0]
    assert body_box(meta, "b") is None and body_box({}, "a") is None
    bad = {"geometry": {"a": {"bbox_min_m": [0, 0, 5], "bbox_max_m": [1, 2, 3]}}}
    with pytest.raises(SegmentationError, match=r"geometry.*'a'"):
        body_box(bad, "a")


def test_extra_window_columns_equal_a_single_window_config_and_round_trip() -> None:
    synth = pytest.importorskip("thirdhand.synth")
    demo = synth.make_scene("lid", seed=5, sensor=synth.SensorModel())
    cfg = FeatureConfig(latent_rate=20.0, window=5, long_window=10, extra_windows=(2,))
    one = FeatureConfig(latent_rate=20.0, window=2)
    a, b = "lh_thumb", "lid"
    x, ev = DemoFeatures(demo, cfg).pair(a, b)
    x2, ev2 = DemoFeatures(demo, one).pair(a, b)
    cols = [i for i, n in enumerate(cfg.feature_names) if n.startswith("log_eps_w2_")]
    assert len(cols) == 4 and x.shape[1] == len(cfg.feature_names)
    both = ev & ev2
    assert np.allclose(x[both][:, cols], x2[both][:, 1:5])
    model = SegmentModel(cfg, np.zeros((2, 2)), np.zeros(len(cfg.feature_names)))
    back = SegmentModel.from_dict(model.to_dict())
    assert back.features == cfg
    with pytest.raises(SegmentationError, match="extra windows"):
        FeatureConfig(extra_windows=(0,))


def test_contact_column_falls_back_to_the_origin_distance_without_geometry() -> None:
    synth = pytest.importorskip("thirdhand.synth")
    demo = synth.make_scene("lid", seed=5, sensor=None)
    cfg = FeatureConfig(latent_rate=20.0, window=5, contact=True)
    bare = demo.replace(meta={k: v for k, v in demo.meta.items() if k != "geometry"})
    feats = DemoFeatures(bare, cfg)
    x, ev = feats.pair("box", "lid")
    from thirdhand.segment.features import pair_stats_multi

    s = pair_stats_multi(feats.body_track("box"), feats.body_track("lid"), feats.axis, (5,))[0]
    assert s.mean_pos is not None
    origin = np.linalg.norm(s.mean_pos, axis=1)
    assert np.allclose(x[ev, -1], np.log(cfg.eps_contact + origin[ev]))
    # With geometry the box and its lid touch: the gap is far below the origin distance.
    xg, _ = DemoFeatures(demo, cfg).pair("box", "lid")
    assert np.median(np.exp(xg[ev, -1]) - cfg.eps_contact) < 0.5 * np.median(origin[ev])


def test_kinematic_audit_finds_held_objects_rigid_and_moving() -> None:
    synth = pytest.importorskip("thirdhand.synth")
    from research.segment_diagnose import kinematic_classes
    from thirdhand.segment.features import latent_axis
    from thirdhand.segment.intervals import labels_from_intervals, pair_intervals

    demo = synth.make_scene("lid", seed=5, sensor=None)
    axis = latent_axis(demo.t, 20.0)
    held = 0
    for a in ("lh_thumb", "rh_thumb"):
        for b in ("box", "lid"):
            y = labels_from_intervals(pair_intervals(demo.labels, a, b), axis.times)
            inner = (y == 1) & (np.roll(y, 1) == 1) & (np.roll(y, -1) == 1)
            cls = kinematic_classes(demo, a, b, axis)
            # A finger's pose in an object it holds is exactly constant.
            assert np.all(cls[inner] != 0), (a, b)
            held += int(np.sum(inner & (cls == 1)))
            # Away from any interaction the finger moves relative to the object somewhere.
            assert np.any(cls[y == 0] == 0), (a, b)
    assert held > 0
