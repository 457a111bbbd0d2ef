"""The assembly closure of part–part labels: brute force, no-geometry pairs, model file, scenes."""

from __future__ import annotations

import dataclasses
import itertools
import json
from pathlib import Path

import numpy as np
import pytest

from thirdhand.segment.assembly import ClosureConfig, close_pairs, touching
from thirdhand.segment.features import SegmentationError
from thirdhand.segment.model import ModelFileError, SegmentModel, default_model, load_model
from thirdhand.segment.pipeline import scores_by_kind, segment_demonstration


def _brute_force(
    names: list[str], pairs: list[tuple[str, str]], labels: np.ndarray, near: np.ndarray
) -> np.ndarray:
    """Per step, Floyd–Warshall reachability over the touching interacting pairs."""
    n, n_steps = len(names), labels.shape[1]
    idx = {x: i for i, x in enumerate(names)}
    out = np.zeros_like(labels)
    for t in range(n_steps):
        reach = np.eye(n, dtype=bool)
        for k, (a, b) in enumerate(pairs):
            if labels[k, t] and near[k, t]:
                reach[idx[a], idx[b]] = reach[idx[b], idx[a]] = True
        for m in range(n):
            reach |= reach[:, m : m + 1] & reach[m : m + 1, :]
        for k, (a, b) in enumerate(pairs):
            out[k, t] = labels[k, t] if near[k, t] else reach[idx[a], idx[b]]
    return out


@pytest.mark.parametrize("seed", range(5))
def test_closure_matches_brute_force_reachability(seed: int) -> None:
    rng = np.random.default_rng(seed)
    names = [f"p{i}" for i in range(6)]
    pairs = list(itertools.combinations(names, 2))
    n_steps = 40
    # Slowly changing random graphs, so that edge sets repeat (the unique-rows path).
    labels = (rng.random((len(pairs), 1)) < 0.3) ^ (rng.random((len(pairs), n_steps)) < 0.05)
    near = rng.random((len(pairs), n_steps)) < 0.5
    got = close_pairs(pairs, list(labels.astype(np.int64)), list(near))
    want = _brute_force(names, pairs, labels.astype(np.int64), near)
    np.testing.assert_array_equal(np.array(got), want)


def test_transitive_pair_is_joined_only_through_touching_interacting_pairs() -> None:
    # seat–leg1 and seat–leg2 touch and interact; leg1–leg2 are apart.
    pairs = [("seat", "leg1"), ("seat", "leg2"), ("leg1", "leg2")]
    labels = [np.array([1, 1, 0, 1]), np.array([1, 0, 0, 1]), np.array([0, 0, 1, 0])]
    touch = [np.ones(4, bool), np.ones(4, bool), np.zeros(4, bool)]
    out = close_pairs(pairs, labels, touch)
    np.testing.assert_array_equal(out[0], labels[0])  # touching pairs keep their label
    np.testing.assert_array_equal(out[1], labels[1])
    np.testing.assert_array_equal(out[2], [1, 0, 0, 1])  # the CRF's lone 1 at step 2 is dropped


def test_pairs_without_boxes_keep_their_label_and_join_others() -> None:
    pairs = [("a", "b"), ("b", "c"), ("a", "c")]
    labels = [np.array([1, 1, 0]), np.array([1, 0, 0]), np.array([0, 0, 0])]
    # a–b has no geometry (None); b–c touches; a–c apart.
    out = close_pairs(pairs, labels, [None, np.ones(3, bool), np.zeros(3, bool)])
    np.testing.assert_array_equal(out[0], [1, 1, 0])
    np.testing.assert_array_equal(out[2], [1, 0, 0])
    assert close_pairs([], [], []) == []


def test_touching_and_bad_input() -> None:
    cfg = ClosureConfig(0.01)
    np.testing.assert_array_equal(
        touching(np.array([0.0, 0.01, 0.02, np.nan]), cfg), [True, True, False, False]
    )
    assert touching(None, cfg) is None
    with pytest.raises(SegmentationError, match="contact_max_m"):
        ClosureConfig(-1.0)
    with pytest.raises(SegmentationError, match="one label and one contact row per pair"):
        close_pairs([("a", "b")], [], [])
    with pytest.raises(SegmentationError, match=r"has 2 labels, expected 3 steps"):
        close_pairs(
            [("a", "b"), ("b", "c")], [np.zeros(3, np.int64), np.zeros(2, np.int64)], [None, None]
        )


def test_model_file_round_trips_the_closure(tmp_path: Path) -> None:
    model = default_model()
    assert model.closure == ClosureConfig(0.01)
    model.save(tmp_path / "m.json")
    assert load_model(tmp_path / "m.json").closure == model.closure
    off = dataclasses.replace(model, closure=None)
    off.save(tmp_path / "off.json")
    assert json.loads((tmp_path / "off.json").read_text())["closure"] is None
    assert load_model(tmp_path / "off.json").closure is None
    doc = model.to_dict()
    doc["closure"] = {"contact_max_m": -2}
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    with pytest.raises(ModelFileError, match=r"bad\.json: malformed model.*contact_max_m"):
        load_model(tmp_path / "bad.json")


def _part_part_f1(model: SegmentModel, scene: str, noisy: bool) -> float:
    synth = pytest.importorskip("thirdhand.synth")
    sensor = synth.SensorModel() if noisy else None
    demo = synth.make_scene(scene, seed=1001, sensor=sensor)
    return scores_by_kind(segment_demonstration(demo, model))["part-part"]["frame_f1"]


@pytest.mark.parametrize("noisy", [True, False])
def test_closure_recovers_pairs_joined_through_the_toolbox(noisy: bool) -> None:
    # Screws on different boards are joined through the boards; at rest only the
    # closure can tell (research/notes/segmentation_results.md). Held-out seed, shipped model.
    # Measured with the shipped model (trained with geometry withheld in half the
    # scenes): 0.867 noisy / 0.940 noise-free with the closure, 0.784 / 0.803 without.
    model = default_model()
    with_closure = _part_part_f1(model, "toolbox", noisy)
    without = _part_part_f1(dataclasses.replace(model, closure=None), "toolbox", noisy)
    assert with_closure >= (0.85 if noisy else 0.92)
    assert with_closure > without + 0.05


def test_closure_leaves_a_scene_without_geometry_to_the_crf() -> None:
    synth = pytest.importorskip("thirdhand.synth")
    demo = synth.make_scene("chair", seed=1000, sensor=synth.SensorModel())
    demo = demo.replace(meta={k: v for k, v in demo.meta.items() if k != "geometry"})
    model = default_model()
    a = segment_demonstration(demo, model)
    b = segment_demonstration(demo, dataclasses.replace(model, closure=None))
    for pa, pb in zip(a.pairs, b.pairs, strict=True):
        np.testing.assert_array_equal(pa.label, pb.label)
