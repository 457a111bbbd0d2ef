"""Segmenting whole demonstrations: recovery on toy scenes, JSON, corrupt input, CLI."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from thirdhand import io
from thirdhand.datasets.pick_place import random_pick_place_demo
from thirdhand.demonstration import BodyInfo, Demonstration, DemonstrationError
from thirdhand.errors import ThirdhandError
from thirdhand.segment.cli import app
from thirdhand.segment.design import FeatureConfig
from thirdhand.segment.evaluate import frame_f1
from thirdhand.segment.features import SegmentationError
from thirdhand.segment.model import ModelFileError, SegmentModel, load_model
from thirdhand.segment.pipeline import segment_demonstration
from thirdhand.segment.training import fit_model, labelled_sequences, table_one

NOISY = {"noise_pos": 5e-4, "noise_rot": 5e-3, "missing": 0.2}


def _toys(seeds: range, **kw: object) -> list[Demonstration]:
    return [
        random_pick_place_demo(
            np.random.default_rng(s), n_parts=3, duration=40.0, hands=("left", "right"), **kw
        )
        for s in seeds
    ]


@pytest.fixture(scope="module")
def clean_model() -> SegmentModel:
    return fit_model(_toys(range(3)), l2=1.0)


def test_noise_free_intervals_are_recovered(clean_model: SegmentModel) -> None:
    # A step straddling a boundary is ambiguous; picks of 2-4 s keep it to a few %.
    demo = _toys(range(50, 51), pick_length=(2.0, 4.0))[0]
    result = segment_demonstration(demo, clean_model)
    fingers = [p for p in result.pairs if p.kind == "finger-object"]
    truth = [p.truth for p in fingers]
    assert all(t is not None for t in truth)
    assert frame_f1(truth, [p.label for p in fingers]) >= 0.98  # type: ignore[arg-type]
    hands = result.hands
    assert {h.hand for h in hands} == {"lh", "rh"}
    assert frame_f1([h.truth for h in hands], [h.label for h in hands]) >= 0.98  # type: ignore[misc]
    # Part-part pairs carry no label in these scenes: no ground truth is invented.
    assert all(p.truth is None for p in result.pairs if p.kind == "part-part")


def test_crf_beats_logistic_on_noisy_scenes() -> None:
    tab = table_one(_toys(range(3), **NOISY), l2=1.0)
    crf, lr = tab["crf"]["test"], tab["logistic"]["test"]
    assert crf["nll_per_variable"] < lr["nll_per_variable"]
    assert crf["frame_f1"] > lr["frame_f1"]
    assert crf["frame_f1"] >= 0.9


def test_hand_split_with_one_hand_labelled_says_what_to_do() -> None:
    # toolbox_coop_4 carries the left hand's labels only: --split hand cannot test.
    left_only = [
        random_pick_place_demo(np.random.default_rng(1), n_parts=2, duration=20.0, hands=("left",))
    ]
    with pytest.raises(SegmentationError, match=r"right hand.*--split object or --split time"):
        table_one(left_only, l2=1.0)


def test_result_json_and_model_round_trip(clean_model: SegmentModel, tmp_path: Path) -> None:
    demo = _toys(range(7, 8), **NOISY)[0]
    result = segment_demonstration(demo, clean_model)
    doc = json.loads(json.dumps(result.to_dict()))
    assert len(doc["time"]) == len(result.times)
    first = doc["pairs"][0]
    assert {"a", "b", "probability", "label", "intervals"} <= set(first)
    assert len(first["label"]) == len(doc["time"])
    assert doc["hands"] and {"hand", "object", "label", "intervals"} <= set(doc["hands"][0])
    path = tmp_path / "m.json"
    clean_model.save(path)
    again = load_model(path)
    np.testing.assert_array_equal(again.coef_state, clean_model.coef_state)
    np.testing.assert_array_equal(again.coef_transition, clean_model.coef_transition)
    assert again.features == clean_model.features
    assert set(again.per_kind) == set(clean_model.per_kind) == {"finger-object"}
    for kind, (t, w) in clean_model.per_kind.items():
        np.testing.assert_array_equal(again.per_kind[kind][0], t)
        np.testing.assert_array_equal(again.per_kind[kind][1], w)


def test_malformed_model_files(tmp_path: Path) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text("{\n  nope")
    with pytest.raises(ModelFileError, match=r"bad\.json line 2: not JSON"):
        load_model(bad)
    bad.write_text(json.dumps({"format": "other"}))
    with pytest.raises(ModelFileError, match="expected format"):
        load_model(bad)
    doc = SegmentModel(FeatureConfig(), np.zeros((2, 2)), np.zeros(5)).to_dict()
    doc["theta"]["state"] = [1.0, 2.0]
    bad.write_text(json.dumps(doc))
    with pytest.raises(ModelFileError, match="5 state weights"):
        load_model(bad)
    with pytest.raises(ModelFileError, match="cannot read"):
        load_model(tmp_path / "absent.json")


def _two_bodies(n: int, *, b_valid: bool = True) -> Demonstration:
    t = np.arange(n) / 120.0
    p = np.column_stack([np.sin(t), np.cos(t), t])
    q = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
    vb = np.full(n, b_valid)
    return Demonstration(
        t,
        [BodyInfo("hand", kind="hand"), BodyInfo("box", kind="part")],
        {"hand": p, "box": np.where(vb[:, None], p + 0.1, np.nan)},
        {"hand": q, "box": np.where(vb[:, None], q, np.nan)},
        {"hand": np.ones(n, bool), "box": vb},
    )


def test_corrupt_input(clean_model: SegmentModel) -> None:
    # A body never tracked: no evidence anywhere, so no label and no probability.
    res = segment_demonstration(_two_bodies(600, b_valid=False), clean_model)
    (pair,) = res.pairs
    assert not pair.label.any() and pair.intervals == []
    assert np.isnan(pair.probability).all()
    # A 2-frame recording: one latent step, segmented.
    res = segment_demonstration(_two_bodies(2), clean_model)
    assert len(res.times) == 1 and res.pairs[0].label.shape == (1,)
    with pytest.raises(SegmentationError, match="1 frame"):
        segment_demonstration(_two_bodies(1), clean_model)
    with pytest.raises(DemonstrationError, match="no body named 'lid'"):
        segment_demonstration(_two_bodies(50), clean_model, pairs=[("hand", "lid")])
    with pytest.raises(SegmentationError, match="with itself"):
        segment_demonstration(_two_bodies(50), clean_model, pairs=[("hand", "hand")])
    with pytest.raises(SegmentationError, match="no labelled pair"):
        labelled_sequences(_toys(range(1)), FeatureConfig(), hand="other")


def test_short_gaps_are_bridged_long_gaps_are_not(clean_model: SegmentModel) -> None:
    demo = random_pick_place_demo(
        np.random.default_rng(3), n_parts=1, duration=20.0, pick_length=(3.0, 4.0)
    )
    t = demo.t
    (iv, *_) = demo.labels.interactions
    valid = demo.valid("part0").copy()
    mid = 0.5 * (iv.start + iv.end)
    valid[np.abs(t - mid) < 0.4] = False  # 0.8 s gap inside a carried interval
    valid[(t > 0.3) & (t < 0.3 + 1.6)] = False  # a 1.6 s gap while at rest
    tracks = {
        n: (demo.pos(n), demo.quat(n), demo.valid(n)) for n in demo.body_names if n != "part0"
    }
    tracks["part0"] = (
        np.where(valid[:, None], demo.pos("part0"), np.nan),
        np.where(valid[:, None], demo.quat("part0"), np.nan),
        valid,
    )
    res = segment_demonstration(demo.replace(tracks=tracks), clean_model)
    pair = res.pair("carrier", "part0")
    k_mid = int(np.argmin(np.abs(res.times - mid)))
    assert pair.label[k_mid] == 1 and not pair.evidence[k_mid]
    k_gap = int(np.argmin(np.abs(res.times - 1.1)))
    assert np.isnan(pair.probability[k_gap]) and pair.label[k_gap] == 0


def test_cli_segment_train_evaluate(tmp_path: Path, clean_model: SegmentModel) -> None:
    demos = _toys(range(2), **NOISY)
    paths = []
    for i, d in enumerate(demos):
        paths.append(tmp_path / f"d{i}.parquet")
        io.save(d, paths[-1])
    runner = CliRunner()
    model = tmp_path / "model.json"
    r = runner.invoke(app, ["train", *map(str, paths), "-o", str(model)])
    assert r.exit_code == 0, r.output
    assert load_model(model).training["sequences"] > 0
    out_json, png = tmp_path / "phases.json", tmp_path / "phases.png"
    args = [str(paths[0]), "--model", str(model), "--json", str(out_json), "--plot", str(png)]
    r = runner.invoke(app, args)
    assert r.exit_code == 0, r.output
    assert json.loads(out_json.read_text())["pairs"]
    assert png.read_bytes()[:4] == b"\x89PNG"
    r = runner.invoke(app, ["evaluate", *map(str, paths)])
    assert r.exit_code == 0, r.output
    assert "CRF" in r.output and "logistic" in r.output
    r = runner.invoke(app, [str(paths[0]), "--model", str(out_json)])
    assert r.exit_code != 0 and isinstance(r.exception, ModelFileError)


def test_labels_from_a_kvg_annotation_file(tmp_path: Path) -> None:
    from thirdhand.segment.cli import read_label_file

    demo = random_pick_place_demo(np.random.default_rng(4), n_parts=1, duration=10.0)
    ann = tmp_path / "ann_kvg.kvg"
    ann.write_text("TS carrier part0 { lock { from=120 to=360 } }\n")
    labels = read_label_file(ann, demo)
    (iv,) = labels.interactions
    assert (iv.a, iv.b) == ("carrier", "part0")
    assert iv.start == pytest.approx(demo.t[120]) and iv.end == pytest.approx(demo.t[360])
    with pytest.raises(ThirdhandError, match="unknown label file type"):
        read_label_file(tmp_path / "labels.csv", demo)


def test_a_kind_can_leave_features_out_and_hands_without_labels_have_no_truth() -> None:
    demos = _toys(range(2))
    model = fit_model(demos, l2=1.0, exclude={"finger-object": ["log_eps_zeta_rot"]})
    col = model.features.feature_names.index("log_eps_zeta_rot")
    _, w = model.per_kind["finger-object"]
    assert w[col] == 0.0 and np.all(w[np.arange(w.size) != col] != 0.0)
    with pytest.raises(SegmentationError, match="unknown feature"):
        fit_model(demos, l2=1.0, exclude={"finger-object": ["nope"]})
    # Labels of the left hand only: the right hand's pairs are unknown, not negatives.
    demo = demos[0]
    left = tuple(i for i in demo.labels.interactions if i.a.startswith("lh_"))
    only_left = demo.replace(labels=type(demo.labels)(interactions=left))
    result = segment_demonstration(only_left, model)
    for p in result.pairs:
        if p.kind == "finger-object":
            assert (p.truth is not None) == p.a.startswith("lh_"), p.a
