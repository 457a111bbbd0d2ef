"""The shipped model and the Table I protocol on the synthetic assembly scenes.

Measured figures (held-out seeds 1000+, shipped model) are in the training
script's output and the model's ``training["held_out"]``. Labels follow the
report's meaning (a hand interacts while it moves the object), so finger-object
intervals are the moves, shorter and more numerous than the old holds. Means
over every scene (default sensor / noise-free / random sensor): finger-object
0.915 / 0.922 / 0.909, part-part 0.921 / 0.939 / 0.911, tool-part 0.987 /
0.987 / 0.868. Per case (thresholds below the measured values, so a regression
fails): chair 0.914 / part-part 0.992, bench 0.913 / 0.994, toolbox 0.962 /
0.867, drawer 0.876 / 0.852 (noisy); chair 0.951 / 0.991, toolbox 0.974 / 0.940
(noise-free). research/notes/segmentation_results.md has the tables.
"""

from __future__ import annotations

import numpy as np
import pytest

from thirdhand.segment.intervals import intervals_from_labels
from thirdhand.segment.model import default_model
from thirdhand.segment.pipeline import scores_by_kind, segment_demonstration
from thirdhand.segment.training import table_one

synth = pytest.importorskip("thirdhand.synth")


def test_default_model_loads_from_the_package() -> None:
    model = default_model()
    assert model.features.feature_names[0] == "bias"
    assert {"finger-object", "tool-part", "part-part"} <= set(model.per_kind)
    assert "held_out" in model.training


def test_tool_part_phases_on_held_out_noisy_toolbox() -> None:
    demo = synth.make_scene("toolbox", seed=1001, sensor=synth.SensorModel())
    result = segment_demonstration(demo)
    scores = scores_by_kind(result)
    assert scores["tool-part"]["frame_f1"] >= 0.97  # measured 0.984
    # Every engagement (screwdriver in the screw it drives, 2 s and more) is found
    # whole; the short pauses a resting screwdriver shares with the screw's board
    # and the other screws are what lowers the interval IoU (0.63).
    for p in result.pairs:
        if p.kind != "tool-part" or p.truth is None:
            continue
        for s, e in intervals_from_labels(p.truth, result.edges):
            if e - s >= 2.0:
                best = max(
                    (min(e, e2) - max(s, s2)) / (max(e, e2) - min(s, s2)) for s2, e2 in p.intervals
                )
                assert best >= 0.9, (p.a, p.b, s, e, best)
    # Every finger and part of the scene was paired, and the hands aggregated.
    assert {h.hand for h in result.hands} == {"lh", "rh"}
    assert all(np.isfinite(p.probability[p.evidence]).all() for p in result.pairs)


@pytest.mark.parametrize(
    ("scene", "seed", "noisy", "finger", "part"),
    [
        ("chair", 1000, True, 0.89, 0.97),
        ("bench", 1001, True, 0.89, 0.97),
        ("toolbox", 1001, True, 0.94, 0.85),
        ("drawer", 1000, True, 0.85, 0.83),
        ("chair", 1000, False, 0.93, 0.97),
        ("toolbox", 1001, False, 0.95, 0.92),
    ],
)
def test_held_out_frame_f1_per_pair_kind(
    scene: str, seed: int, noisy: bool, finger: float, part: float
) -> None:
    demo = synth.make_scene(scene, seed=seed, sensor=synth.SensorModel() if noisy else None)
    scores = scores_by_kind(segment_demonstration(demo))
    assert scores["finger-object"]["frame_f1"] >= finger
    assert scores["hand-object (aggregated)"]["frame_f1"] >= finger
    assert scores["part-part"]["frame_f1"] >= part


@pytest.mark.slow
def test_crf_beats_logistic_regression_table_one_protocol() -> None:
    demos = [synth.make_scene("chair", seed=s, sensor=synth.SensorModel()) for s in range(2)]
    tab = table_one(demos, default_model().features)
    # With the shipped features the chain beats logistic regression on both
    # hands, in NLL (measured 0.0105 vs 0.0441 per variable on the training hand,
    # 0.121 vs 0.249 on the test hand) and in frame F1 (0.993 vs 0.980, 0.901 vs
    # 0.803). With the report's four features at 10 Hz its test-hand F1 is lower
    # (0.80): see research/notes/segmentation_results.md.
    crf, lr = tab["crf"], tab["logistic"]
    assert crf["train"]["nll_per_variable"] < 0.5 * lr["train"]["nll_per_variable"]
    assert crf["test"]["nll_per_variable"] < 0.6 * lr["test"]["nll_per_variable"]
    assert crf["train"]["frame_f1"] > lr["train"]["frame_f1"]
    assert crf["test"]["frame_f1"] > lr["test"]["frame_f1"] + 0.05


@pytest.mark.slow
def test_crf_beats_logistic_regression_per_pair_kind_on_held_out_scenes() -> None:
    from thirdhand.segment.crf import PairCRF
    from thirdhand.segment.evaluate import frame_f1
    from thirdhand.segment.logistic import LogisticSegmenter
    from thirdhand.segment.training import labelled_sequences

    # As the shipped model: every scene, noisy and noise-free (smaller: one seed each).
    config = default_model().features
    scenes = ("chair", "toolbox")
    train = labelled_sequences(
        [synth.make_scene(s, seed=0, sensor=synth.SensorModel()) for s in synth.SCENES]
        + [synth.make_scene(s, seed=100, sensor=None) for s in synth.SCENES],
        config,
    )
    test = labelled_sequences(
        [synth.make_scene(s, seed=1000, sensor=synth.SensorModel()) for s in scenes], config
    )
    for kind in ("finger-object", "part-part"):
        tr = [i for i, p in enumerate(train.pairs) if p[3] == kind]
        te = [i for i, p in enumerate(test.pairs) if p[3] == kind]
        xs, ys = [train.xs[i] for i in tr], [train.ys[i] for i in tr]
        xt, yt = [test.xs[i] for i in te], [test.ys[i] for i in te]
        crf = PairCRF(l2=1.0).fit(xs, ys)
        lr = LogisticSegmenter(l2=1.0).fit(xs, ys)
        assert crf.nll(xt, yt) < lr.nll(xt, yt), kind
        assert frame_f1(yt, crf.predict(xt)) > frame_f1(yt, lr.predict(xt)), kind
