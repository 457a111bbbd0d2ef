"""The confidence is calibrated: checked on synthetic tracks the calibration never saw."""

from __future__ import annotations

import math

import pytest

from thirdhand.constraints.select import (
    CONFIDENCE_FLOOR,
    CONFIDENCE_TEMPERATURE,
    bic_weights,
    type_probabilities,
)
from thirdhand.constraints.sweep import Condition, log_loss, reliability, run_sweep


def test_type_probabilities_mix_a_floor_into_tempered_weights() -> None:
    scores = {"a": 0.0, "b": 2.0 * math.log(3.0), "c": math.inf}
    p = type_probabilities(scores, temperature=1.0, floor=0.0)
    assert p == pytest.approx(bic_weights(scores))
    p = type_probabilities(scores, temperature=2.0, floor=0.1)
    # At temperature 2 the odds of a over b are sqrt(3); 0.1 is shared by a and b.
    wa = math.sqrt(3.0) / (1.0 + math.sqrt(3.0))
    assert p["a"] == pytest.approx(0.9 * wa + 0.05)
    assert p["b"] == pytest.approx(0.9 * (1.0 - wa) + 0.05)
    assert p["c"] == 0.0
    assert sum(p.values()) == pytest.approx(1.0)


def test_confidence_is_calibrated_on_held_out_synthetic_tracks() -> None:
    """Seeds 40-42 (the shipped calibration used 0-9): white noise 1 mm and 1 cm,
    20 samples, 10 % outliers, a slowly varying error. The shipped calibration's
    expected calibration error is under 0.1 and its log loss (the score it was
    fitted to) below that of plain BIC weights."""
    conds = [
        Condition("1 mm", 1e-3),
        Condition("1 cm", 1e-2),
        Condition("20 samples", 1e-3, n=20),
        Condition("outliers", 1e-3, outliers=0.1),
        Condition("slow error", 1e-3, drift=2.0),
    ]
    trials = list(run_sweep(conds, range(40, 43)))
    assert len(trials) == 5 * 9 * 3
    _, ece = reliability(trials, temperature=CONFIDENCE_TEMPERATURE, floor=CONFIDENCE_FLOOR)
    assert ece < 0.1
    assert log_loss(trials, CONFIDENCE_TEMPERATURE, CONFIDENCE_FLOOR) < log_loss(trials, 1.0, 0.0)
    # The confidence reported is the calibrated probability of the chosen type.
    for t in trials:
        assert t.confidence == pytest.approx(t.probability()[t.predicted])
