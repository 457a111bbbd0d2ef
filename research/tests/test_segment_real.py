"""The shipped segmentation model on real recordings with tracking gaps.

The 3rdHand excerpt (Polhemus, ~100 Hz, 19–25 % of the samples of each sensor
lost, in short runs) and the four IKEA bags (AR tags at ~23 Hz; the table is
lost for 12–88 % of the frames, the leg for 0–100 %). None carries interaction
labels, so these tests check what the model promises about gaps
(``thirdhand.segment.pipeline``): a step has evidence only when its window
holds enough valid samples of both bodies; runs without evidence up to
``max_gap_s`` are bridged by the chain; longer ones get label 0 and probability
NaN — nothing is fabricated over them. Figures: research/notes/segmentation_results.md.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from research.segment_real import TOOLBOX_COOP_4, load_labelled, score_model
from thirdhand.demonstration import Demonstration
from thirdhand.io import load
from thirdhand.segment.design import DemoFeatures
from thirdhand.segment.intervals import runs
from thirdhand.segment.model import builtin_model, default_model
from thirdhand.segment.pipeline import SegmentationResult, segment_demonstration

IKEA = "niekum/ikea_table_leg_pos_1"


def _check_gap_rules(result: SegmentationResult, rate: float) -> None:
    max_steps = int(np.floor(default_model().max_gap_s * rate + 1e-9))
    for p in result.pairs:
        assert np.all(np.isfinite(p.probability[p.evidence])), (p.a, p.b)
        long_gap = np.zeros(len(p.label), dtype=bool)
        for lo, hi in runs((~p.evidence).astype(np.int64)):
            if hi - lo > max_steps:
                long_gap[lo:hi] = True
        np.testing.assert_array_equal(np.isnan(p.probability), long_gap)
        assert not p.label[long_gap].any(), (p.a, p.b)
        for s, e in p.intervals:
            assert result.edges[0] <= s < e <= result.edges[-1]


def test_3rdhand_excerpt_with_lost_samples(shared_data: Path) -> None:
    demo = load(shared_data / "3rdhand" / "toolbox_coop_4_excerpt")
    missing = 1.0 - np.mean([demo.track(b.name).valid.mean() for b in demo.bodies])
    assert 0.15 < missing < 0.3  # the ~20 % of lost samples the issue speaks of
    result = segment_demonstration(demo)
    # 9 fingers x 2 boards + the two boards; three hands aggregated per board.
    assert len(result.pairs) == 19
    assert {h.hand for h in result.hands} == {"/human/lh", "/human/rh", "/human/th"}
    # The losses come in runs of a few frames: every 50 ms step keeps evidence.
    assert all(p.evidence.all() for p in result.pairs)
    _check_gap_rules(result, default_model().features.latent_rate)
    # Everybody rests during this second, the right and left hands 0.8-1.2 m from
    # both boards: never interacting with them.
    for h in result.hands:
        if h.hand in ("/human/lh", "/human/rh"):
            assert not h.label.any(), (h.hand, h.object)


@pytest.mark.parametrize("part", [1, 2, 3, 4])
def test_ikea_bags_never_fill_long_gaps(shared_data: Path, part: int) -> None:
    demo = load(shared_data / IKEA / f"part{part}.bag")
    result = segment_demonstration(demo)
    (pair,) = result.pairs
    assert pair.kind == "part-part"
    _check_gap_rules(result, default_model().features.latent_rate)
    if part == 2:  # the leg's tag is never seen: a documented empty result
        assert not pair.evidence.any() and not pair.label.any() and not pair.intervals
        assert np.isnan(pair.probability).all()
    else:
        assert pair.evidence.mean() > 0.1


def test_ikea_leg_rests_in_the_table_at_the_end_of_the_insert_test(shared_data: Path) -> None:
    # Part 4 ("insert test"): the robot moves the leg in the table's hole, both
    # tags jump by centimetres (AR tracking, far noisier than the training sensor),
    # then lets go; in the last second the leg's pose in the table changes by
    # under 4 mm (from about 10 s on: 1.2 mm, then 0.4 mm of spread per second).
    # The longest interaction found is there and lasts to the end.
    result = segment_demonstration(load(shared_data / IKEA / "part4.bag"))
    (pair,) = result.pairs
    longest = max(pair.intervals, key=lambda iv: iv[1] - iv[0])
    assert longest[1] - longest[0] >= 0.5
    assert longest[0] >= result.edges[-1] - 2.5
    assert longest[1] >= result.edges[-1] - 0.1


# ---------------------------------------------------------------- labelled real recording
# toolbox_coop_4 carries the human labels of the left hand only; the others are
# kept apart, so only the left hand's pairs are scored (the others get no truth).


@pytest.fixture(scope="module")
def coop4() -> Demonstration:
    import os

    root = Path(__file__).resolve().parents[2]
    data = Path(os.environ.get("THIRDHAND_DATA", root.parent / "shared" / "data"))
    folder = data / TOOLBOX_COOP_4
    if not folder.is_dir():
        pytest.skip(f"real recording not found at {folder} (set THIRDHAND_DATA)")
    return load_labelled(folder)


def test_only_the_labelled_hand_has_ground_truth(coop4: Demonstration) -> None:
    result = segment_demonstration(coop4)
    for p in result.pairs:
        if p.kind == "finger-object":
            assert (p.truth is not None) == p.a.startswith("/human/lh/"), p.a
    assert all(h.truth is None for h in result.hands if h.hand != "/human/lh")


def test_shipped_model_finds_every_left_hand_interval(coop4: Demonstration) -> None:
    scores = score_model(default_model(), coop4)
    assert scores.intervals == 12  # 4 labelled intervals x 3 fingers
    assert scores.interval_recall == 1.0
    assert scores.frame_f1 >= 0.9


def test_synthetic_only_model_holds_on_the_real_left_hand(coop4: Demonstration) -> None:
    # No real label in its training: the realistic synthetic world is the point.
    model = builtin_model("synthetic")
    assert "toolbox_coop_4" not in model.training["data"]
    scores = score_model(model, coop4)
    assert scores.interval_recall == 1.0
    assert scores.frame_f1 >= 0.85


def test_motionless_hands_beside_the_box_do_not_interact(coop4: Demonstration) -> None:
    # A finger that shows no motion beyond its own noise floor moves no board,
    # nor does any finger move a board that is still. Decided from the tracks
    # alone (no labels are used for the right hand and the second person).
    model = default_model()
    result = segment_demonstration(coop4, model)
    feats = DemoFeatures(coop4, model.features)
    boards = ("/toolbox/side_left", "/toolbox/side_front")
    for hand in ("/human/lh", "/human/rh", "/human/th"):
        fingers = [b.name for b in coop4.bodies if b.hand_body == hand]
        still = [feats.rest(f) for f in fingers]
        assert sum(s.sum() for s in still) / model.features.latent_rate > 5.0, hand
        for f, s in zip(fingers, still, strict=True):
            for board in boards:
                p = result.pair(f, board)
                assert not p.label[s | feats.rest(board)].any(), (f, board)
                # 0, or NaN where the pair has no evidence (the start-up dropout).
                assert np.all(p.probability[s & p.evidence] == 0.0)
                assert not np.any(p.probability[s] > 0.0)
    # The left hand's labelled intervals are never cut by the gate: a hand moving
    # a board is never at rest.
    for f in [b.name for b in coop4.bodies if b.hand_body == "/human/lh"]:
        for board in boards:
            truth = result.pair(f, board).truth
            assert truth is not None
            assert not (truth.astype(bool) & (feats.rest(f) | feats.rest(board))).any()
