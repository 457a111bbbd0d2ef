"""Calibrating a model to a user's rig from a few labelled intervals."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from thirdhand import io
from thirdhand.cli import main
from thirdhand.datasets.pick_place import random_pick_place_demo
from thirdhand.demonstration import Demonstration, InteractionInterval
from thirdhand.errors import DemonstrationError
from thirdhand.segment.calibrate import calibrate, labelled_pairs
from thirdhand.segment.evaluate import frame_f1
from thirdhand.segment.features import SegmentationError
from thirdhand.segment.model import SegmentModel, load_model
from thirdhand.segment.pipeline import segment_demonstration
from thirdhand.segment.training import fit_model

NOISY = {"noise_pos": 5e-4, "noise_rot": 5e-3, "missing": 0.1}


def _toys(seeds: range) -> list[Demonstration]:
    return [
        random_pick_place_demo(
            np.random.default_rng(s), n_parts=3, duration=40.0, hands=("left", "right"), **NOISY
        )
        for s in seeds
    ]


@pytest.fixture(scope="module")
def model() -> SegmentModel:
    return fit_model(_toys(range(3)), l2=1.0)


def _shifted(model: SegmentModel, delta: float) -> SegmentModel:
    """The model with the bias of every state-weight set moved by ``delta``."""
    state = model.coef_state.copy()
    state[0] += delta
    kinds = {}
    for k, (t, w) in model.per_kind.items():
        w = w.copy()
        w[0] += delta
        kinds[k] = (t, w)
    return dataclasses.replace(model, coef_state=state, per_kind=kinds)


def _f1(model: SegmentModel, demos: list[Demonstration]) -> float:
    truth, pred = [], []
    for d in demos:
        for p in segment_demonstration(d, model).pairs:
            if p.truth is not None:
                truth.append(p.truth)
                pred.append(p.label)
    return frame_f1(truth, pred)


def test_calibration_recovers_a_shifted_operating_point(model: SegmentModel) -> None:
    test = _toys(range(10, 12))
    base_f1 = _f1(model, test)
    bad = _shifted(model, 4.0)  # predicts "interacting" far too often
    assert _f1(bad, test) < base_f1 - 0.05
    fixed, report = calibrate(bad, _toys(range(20, 22)))
    r = report["finger-object"]
    # The score was shifted by +4. In a chain a constant on y = 1 can sit in the
    # state offset or in the transitions into y = 1 (only the first step tells
    # them apart): their sum takes the shift back.
    trans = np.array(r["transition"])
    base_trans = bad.per_kind["finger-object"][0]
    into_one = float(np.mean(trans[1] - base_trans[1]) - np.mean(trans[0] - base_trans[0]))
    assert -6.0 < r["offset"] + into_one < -2.0
    assert 0.6 < r["scale"] < 1.6
    assert r["nll_per_step_after"] < 0.1 * r["nll_per_step_before"]
    assert _f1(fixed, test) > base_f1 - 0.02
    assert fixed.training["calibration"]["finger-object"]["steps"] == r["steps"]


def test_calibrated_model_round_trips(model: SegmentModel, tmp_path: Path) -> None:
    fixed, _ = calibrate(model, _toys(range(30, 31)), span=(0.0, 20.0))
    fixed.save(tmp_path / "m.json")
    back = load_model(tmp_path / "m.json")
    for kind, (t, w) in fixed.per_kind.items():
        np.testing.assert_allclose(back.per_kind[kind][0], t)
        np.testing.assert_allclose(back.per_kind[kind][1], w)
    assert back.rest_gate == fixed.rest_gate


def _one_demo(tmp_path: Path) -> tuple[Demonstration, Path]:
    demo = random_pick_place_demo(
        np.random.default_rng(5), n_parts=1, duration=20.0, hands=("left",), **NOISY
    )
    path = tmp_path / "rec.parquet"
    io.save(demo.replace(labels=type(demo.labels)()), path)
    return demo, path


@pytest.mark.parametrize(
    ("label", "message"),
    [
        ("TS lh_f0 nobody { lock { from=10 to=200 } }", "not in the recording"),
        ("TS lh_f0 part0 { lock { from=10 to=99999 } }", "frame"),
    ],
)
def test_bad_labels_are_refused_and_nothing_is_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], label: str, message: str
) -> None:
    _, rec = _one_demo(tmp_path)
    ann = tmp_path / "ann.kvg"
    ann.write_text(label + "\n")
    out = tmp_path / "cal.json"
    code = main(["segment", "calibrate", str(rec), "--labels", str(ann), "-o", str(out)])
    err = capsys.readouterr().err
    assert code != 0 and not out.exists()
    assert err.startswith("thirdhand: error:") and err.count("\n") == 1
    assert message in err


def test_labels_outside_the_recording_and_no_valid_pair(tmp_path: Path) -> None:
    demo, _ = _one_demo(tmp_path)
    t0, t1 = float(demo.t[0]), float(demo.t[-1])
    # The core type refuses a label past the recording's end, whatever built it.
    with pytest.raises(DemonstrationError, match="lies outside the recording"):
        demo.replace(
            labels=dataclasses.replace(
                demo.labels,
                interactions=(InteractionInterval("lh_f0", "part0", t1 - 1.0, t1 + 5.0),),
            )
        )
    with pytest.raises(SegmentationError, match="with itself"):
        labelled_pairs(
            demo.replace(
                labels=dataclasses.replace(
                    demo.labels,
                    interactions=(InteractionInterval("part0", "part0", t0, t0 + 1.0),),
                )
            )
        )
    tracks = {n: (demo.pos(n), demo.quat(n), demo.valid(n)) for n in demo.body_names}
    tracks["part0"] = (demo.pos("part0"), demo.quat("part0"), np.zeros(demo.n_frames, bool))
    lost = demo.replace(tracks=tracks)
    with pytest.raises(SegmentationError, match="no labelled pair has tracking evidence"):
        calibrate(fit_model(_toys(range(2)), l2=1.0), [lost])
    with pytest.raises(SegmentationError, match="span"):
        calibrate(fit_model(_toys(range(2)), l2=1.0), [demo], span=(500.0, 600.0))
