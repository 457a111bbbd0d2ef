"""Training sets from labelled demonstrations, model fitting, and the Table I protocol.

Which pairs train the model
---------------------------
The candidates are :func:`~thirdhand.segment.pipeline.default_pairs`. A pair
kind (finger–object, hand–object, tool–part, part–part) enters the training set
only when the labels hold at least one interval of that kind: labels covering
only hands and objects (the 3rdHand ``TS`` annotations) say nothing about
part–part contact, and their part–part pairs must not be taken as negatives.
Every candidate of a labelled kind is used, unlabelled ones as all-zero sequences.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from thirdhand.demonstration import Demonstration
from thirdhand.segment.assembly import CLOSED_KINDS, ClosureConfig, touching
from thirdhand.segment.crf import PairCRF
from thirdhand.segment.design import DemoFeatures, FeatureConfig
from thirdhand.segment.evaluate import boundary_error, frame_f1, interval_iou
from thirdhand.segment.features import SegmentationError
from thirdhand.segment.intervals import intervals_from_labels, labels_from_intervals, pair_intervals
from thirdhand.segment.logistic import LogisticSegmenter
from thirdhand.segment.model import SegmentModel
from thirdhand.segment.pipeline import default_pairs, labelled_kinds, pair_kind

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass
class SequenceSet:
    """Labelled pair sequences of one or more demonstrations.

    Attributes
    ----------
    xs : list of ndarray, each (n_steps_i, n_features)
    ys : list of ndarray of int, each (n_steps_i,)
    pairs : list of (demo index, a, b, kind)
    edges : list of ndarray, each (n_steps_i + 1,), seconds
    gaps : list of (ndarray, each (n_steps_i,), metres) or None
        Bounding-box gap of the pair, None when a body has no box.
    """

    xs: list[FloatArray] = field(default_factory=list)
    ys: list[IntArray] = field(default_factory=list)
    pairs: list[tuple[int, str, str, str]] = field(default_factory=list)
    edges: list[FloatArray] = field(default_factory=list)
    gaps: list[FloatArray | None] = field(default_factory=list)

    @property
    def n_steps(self) -> int:
        """Latent variables in total."""
        return int(sum(len(y) for y in self.ys))


def training_pairs(demo: Demonstration, *, hand: str | None = None) -> list[tuple[str, str]]:
    """Candidate pairs of the kinds the demonstration's labels cover.

    Parameters
    ----------
    demo : Demonstration
    hand : {"left", "right"}, optional
        Keep only finger/hand–object pairs of that hand.
    """
    labelled = labelled_kinds(demo)
    out = []
    for a, b in default_pairs(demo):
        kind = pair_kind(demo, a, b)
        if kind not in labelled:
            continue
        if hand is not None and (
            kind not in ("finger-object", "hand-object") or demo.info(a).hand != hand
        ):
            continue
        out.append((a, b))
    return out


def labelled_sequences(
    demos: Sequence[Demonstration], config: FeatureConfig, *, hand: str | None = None
) -> SequenceSet:
    """Design matrices and true labels of every training pair of every demonstration."""
    out = SequenceSet()
    for k, demo in enumerate(demos):
        if not demo.labels.interactions:
            raise SegmentationError(f"demonstration {k} ({demo!r}) has no interaction labels")
        feats = DemoFeatures(demo, config)
        for a, b in training_pairs(demo, hand=hand):
            x, _ = feats.pair(a, b)
            out.xs.append(x)
            out.ys.append(
                labels_from_intervals(pair_intervals(demo.labels, a, b), feats.axis.times)
            )
            out.pairs.append((k, a, b, pair_kind(demo, a, b)))
            out.edges.append(feats.axis.edges)
            out.gaps.append(feats.gaps.get((a, b)))
    if not out.xs:
        side = "" if hand is None else f" of the {hand} hand"
        raise SegmentationError(f"no labelled pair{side} to learn from")
    return out


def fit_model(
    demos: Sequence[Demonstration],
    config: FeatureConfig | None = None,
    *,
    l2: float = 1.0,
    hand: str | None = None,
    per_kind: bool = True,
    min_sequences: int = 4,
    closure: ClosureConfig | None = None,
    training: dict[str, Any] | None = None,
) -> SegmentModel:
    """Train a CRF segmentation model on labelled demonstrations.

    Parameters
    ----------
    demos : sequence of Demonstration
    config : FeatureConfig, optional
    l2 : float
        Ridge penalty.
    hand : {"left", "right"}, optional
        Learn from that hand's finger/hand–object pairs only.
    per_kind : bool
        Also fit separate weights per pair kind (finger–object, tool–part,
        part–part...) having at least ``min_sequences`` sequences and one interval;
        the shared weights, fitted on every pair, serve the other kinds.
    min_sequences : int
    closure : ClosureConfig, optional
        Close part–part labels over the assembly (:mod:`thirdhand.segment.assembly`).
        The part–part weights are then fitted only on the pairs that touch at
        some step (or have no boxes): the closure labels the others, whose
        history-dependent labels at rest would only blur the touching ones.
    training : dict, optional
        Provenance merged into :attr:`SegmentModel.training`.
    """
    config = FeatureConfig() if config is None else config
    data = labelled_sequences(demos, config, hand=hand)
    crf = PairCRF(l2=l2).fit(data.xs, data.ys)
    info: dict[str, Any] = {
        "l2": l2,
        "sequences": len(data.xs),
        "latent_variables": data.n_steps,
        "train_nll_per_variable": crf.nll(data.xs, data.ys) / data.n_steps,
        **(training or {}),
    }
    kinds: dict[str, tuple[FloatArray, FloatArray]] = {}
    if per_kind:
        for kind in sorted({p[3] for p in data.pairs}):
            idx = [i for i, p in enumerate(data.pairs) if p[3] == kind]
            if closure is not None and kind in CLOSED_KINDS:
                idx = [i for i in idx if _may_touch(data.gaps[i], closure)]
            xs = [data.xs[i] for i in idx]
            ys = [data.ys[i] for i in idx]
            if len(idx) < min_sequences or not any(y.any() for y in ys):
                continue
            k_crf = PairCRF(l2=l2).fit(xs, ys)
            kinds[kind] = (k_crf.coef_transition_, k_crf.coef_state_)
            info[f"train_nll_per_variable[{kind}]"] = k_crf.nll(xs, ys) / sum(map(len, ys))
    return SegmentModel.from_crf(crf, config, training=info, per_kind=kinds, closure=closure)


def _may_touch(gap: FloatArray | None, closure: ClosureConfig) -> bool:
    near = touching(gap, closure)
    return near is None or bool(near.any())


def scores(data: SequenceSet, pred: Sequence[IntArray]) -> dict[str, float]:
    """Frame F1, interval IoU and boundary error (seconds) of predictions on ``data``."""
    true_i = [intervals_from_labels(y, e) for y, e in zip(data.ys, data.edges, strict=True)]
    pred_i = [intervals_from_labels(y, e) for y, e in zip(pred, data.edges, strict=True)]
    be = boundary_error(true_i, pred_i)
    return {
        "frame_f1": frame_f1(data.ys, pred),
        "interval_iou": interval_iou(true_i, pred_i),
        "boundary_error_s": be.mean_s,
        "boundaries_missed": float(be.missed),
    }


def table_one(
    demos: Sequence[Demonstration],
    config: FeatureConfig | None = None,
    *,
    l2: float = 1.0,
    train_hand: str = "left",
    test_hand: str = "right",
) -> dict[str, dict[str, dict[str, float]]]:
    """The report's Table I protocol: train on one hand's pairs, test on the other's.

    Returns
    -------
    dict
        ``{"logistic" | "crf": {"train" | "test": {"nll", "nll_per_variable",
        "frame_f1", "interval_iou", "boundary_error_s", ...}}}``
    """
    config = FeatureConfig() if config is None else config
    train = labelled_sequences(demos, config, hand=train_hand)
    test = labelled_sequences(demos, config, hand=test_hand)
    logistic = LogisticSegmenter(l2=l2).fit(train.xs, train.ys)
    crf = PairCRF(l2=l2).fit(train.xs, train.ys)
    out: dict[str, dict[str, dict[str, float]]] = {}
    for name, model in (("logistic", logistic), ("crf", crf)):
        out[name] = {}
        for split, data in (("train", train), ("test", test)):
            nll = model.nll(data.xs, data.ys)
            out[name][split] = {
                "nll": nll,
                "nll_per_variable": nll / data.n_steps,
                "latent_variables": float(data.n_steps),
                **scores(data, model.predict(data.xs)),
            }
    return out


__all__ = [
    "SequenceSet",
    "fit_model",
    "labelled_sequences",
    "scores",
    "table_one",
    "training_pairs",
]
