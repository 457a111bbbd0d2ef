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

from thirdhand.arrays import FloatArray, IntArray
from thirdhand.demonstration import Demonstration
from thirdhand.segment.assembly import CLOSED_KINDS, ClosureConfig, touching
from thirdhand.segment.crf import PairCRF
from thirdhand.segment.design import DemoFeatures, FeatureConfig
from thirdhand.segment.evaluate import boundary_error, frame_f1, interval_iou
from thirdhand.segment.features import SegmentationError
from thirdhand.segment.intervals import intervals_from_labels, labels_from_intervals, pair_intervals
from thirdhand.segment.logistic import LogisticSegmenter
from thirdhand.segment.model import SegmentModel
from thirdhand.segment.pipeline import (
    default_pairs,
    labelled_hands,
    labelled_kinds,
    pair_has_truth,
    pair_kind,
)


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
    hands = labelled_hands(demo)
    out = []
    for a, b in default_pairs(demo):
        kind = pair_kind(demo, a, b)
        if not pair_has_truth(demo, a, b, labelled, hands):
            continue
        if hand is not None and (
            kind not in ("finger-object", "hand-object") or demo.info(a).hand != hand
        ):
            continue
        out.append((a, b))
    return out


def _per_demo(hand: str | Sequence[str | None] | None, n: int) -> list[str | None]:
    if hand is None or isinstance(hand, str):
        return [hand] * n
    hands = list(hand)
    if len(hands) != n:
        raise SegmentationError(f"got {len(hands)} hand choices for {n} demonstrations")
    return hands


def labelled_sequences(
    demos: Sequence[Demonstration],
    config: FeatureConfig,
    *,
    hand: str | Sequence[str | None] | None = None,
    repeat: Sequence[int] | None = None,
) -> SequenceSet:
    """Design matrices and true labels of every training pair of every demonstration.

    Parameters
    ----------
    demos : sequence of Demonstration
    config : FeatureConfig
    hand : {"left", "right"} or sequence of them (or None), optional
        Keep only that hand's finger/hand–object pairs, for all demonstrations
        or one choice per demonstration (None: every pair of the labelled kinds).
    repeat : sequence of int, optional
        Integer weight of each demonstration: its sequences enter that many times
        (a few real labelled pairs beside hundreds of synthetic ones).
    """
    out = SequenceSet()
    hands = _per_demo(hand, len(demos))
    reps = [1] * len(demos) if repeat is None else [int(r) for r in repeat]
    if len(reps) != len(demos) or any(r < 1 for r in reps):
        raise SegmentationError(f"repeat must give a count >= 1 per demonstration, got {reps}")
    for k, demo in enumerate(demos):
        if not demo.labels.interactions:
            raise SegmentationError(f"demonstration {k} ({demo!r}) has no interaction labels")
        feats = DemoFeatures(demo, config)
        for a, b in training_pairs(demo, hand=hands[k]) * reps[k]:
            x, _ = feats.pair(a, b)
            out.xs.append(x)
            out.ys.append(
                labels_from_intervals(pair_intervals(demo.labels, a, b), feats.axis.times)
            )
            out.pairs.append((k, a, b, pair_kind(demo, a, b)))
            out.edges.append(feats.axis.edges)
            out.gaps.append(feats.gaps.get((a, b)))
    if not out.xs:
        side = "" if hand is None or not isinstance(hand, str) else f" of the {hand} hand"
        known = sorted(set().union(*(labelled_hands(d) for d in demos)))
        raise SegmentationError(
            f"no labelled pair{side} in the {len(demos)} recording(s) "
            f"(labelled hands: {', '.join(known) or 'none'})"
        )
    return out


def fit_model(
    demos: Sequence[Demonstration],
    config: FeatureConfig | None = None,
    *,
    l2: float = 1.0,
    hand: str | Sequence[str | None] | None = None,
    repeat: Sequence[int] | None = None,
    per_kind: bool = True,
    min_sequences: int = 4,
    closure: ClosureConfig | None = None,
    rest_gate: bool = False,
    exclude: dict[str, Sequence[str]] | None = None,
    training: dict[str, Any] | None = None,
) -> SegmentModel:
    """Train a CRF segmentation model on labelled demonstrations.

    Parameters
    ----------
    demos : sequence of Demonstration
    config : FeatureConfig, optional
    l2 : float
        Ridge penalty.
    hand : {"left", "right"} or sequence of them (or None), optional
        Learn from that hand's finger/hand–object pairs only (one choice for all
        demonstrations or one per demonstration; see :func:`labelled_sequences`).
    repeat : sequence of int, optional
        Integer weight per demonstration.
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
    rest_gate : bool
        Stored in the model: hand/finger–object steps whose object is at rest are
        labelled 0 (:mod:`thirdhand.segment.noise`).
    exclude : dict kind -> feature names, optional
        Features a pair kind's own weights do not use: their columns are zeroed
        while that kind is fitted, so their weights are exactly 0 (the ridge
        penalty alone acts on them) and the model file keeps one feature layout.
    training : dict, optional
        Provenance merged into :attr:`SegmentModel.training`.
    """
    config = FeatureConfig() if config is None else config
    data = labelled_sequences(demos, config, hand=hand, repeat=repeat)
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
            dropped = list((exclude or {}).get(kind, ()))
            if dropped:
                names = config.feature_names
                unknown = sorted(set(dropped) - set(names))
                if unknown:
                    raise SegmentationError(f"exclude[{kind!r}]: unknown feature(s) {unknown}")
                cols = [names.index(n) for n in dropped]
                xs = [x.copy() for x in xs]
                for x in xs:
                    x[:, cols] = 0.0
                info[f"excluded[{kind}]"] = dropped
            k_crf = PairCRF(l2=l2).fit(xs, ys)
            kinds[kind] = (k_crf.coef_transition_, k_crf.coef_state_)
            info[f"train_nll_per_variable[{kind}]"] = k_crf.nll(xs, ys) / sum(map(len, ys))
    return SegmentModel.from_crf(
        crf, config, training=info, per_kind=kinds, closure=closure, rest_gate=rest_gate
    )


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
    try:
        train = labelled_sequences(demos, config, hand=train_hand)
        test = labelled_sequences(demos, config, hand=test_hand)
    except SegmentationError as err:
        raise SegmentationError(
            f"{err}; --split hand trains on one hand's pairs and tests on the other's: "
            "with one hand labelled, split within its pairs (--split object or --split time)"
        ) from None
    for side, data in ((train_hand, train), (test_hand, test)):
        if not any(y.any() for y in data.ys):
            raise SegmentationError(
                f"the labels hold no interval of the {side} hand's pairs; "
                "split within one hand's pairs instead (--split object or --split time)"
            )
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


def _subset(data: SequenceSet, idx: Sequence[int], steps: slice | None = None) -> SequenceSet:
    out = SequenceSet()
    for i in idx:
        x, y, e = data.xs[i], data.ys[i], data.edges[i]
        g = data.gaps[i]
        if steps is not None:
            lo, hi, _ = steps.indices(len(y))
            x, y, e = x[lo:hi], y[lo:hi], e[lo : hi + 1]
            g = None if g is None else g[lo:hi]
        out.xs.append(x)
        out.ys.append(y)
        out.pairs.append(data.pairs[i])
        out.edges.append(e)
        out.gaps.append(g)
    return out


def _merge_sets(sets: Sequence[SequenceSet]) -> SequenceSet:
    out = SequenceSet()
    for s in sets:
        out.xs += s.xs
        out.ys += s.ys
        out.pairs += s.pairs
        out.edges += s.edges
        out.gaps += s.gaps
    return out


def split_folds(data: SequenceSet, split: str) -> list[tuple[str, SequenceSet, SequenceSet]]:
    """Train/test folds of labelled sequences.

    Parameters
    ----------
    data : SequenceSet
    split : {"object", "time"}
        ``"object"``: leave one object out — for each object, train on the pairs
        without it and test on the pairs with it (e.g. one board of a toolbox;
        the three fingers of a hand on one board are nearly the same sequence,
        so leaving one pair out would test on what was trained). ``"time"``: train
        on the first half of every sequence, test on the second, and the reverse.

    Returns
    -------
    list of (fold name, train, test)
    """
    folds: list[tuple[str, SequenceSet, SequenceSet]] = []
    if split == "object":
        objects = sorted({p[2] for p in data.pairs})
        for obj in objects:
            test = [i for i, p in enumerate(data.pairs) if obj in (p[1], p[2])]
            train = [i for i in range(len(data.pairs)) if i not in test]
            if not train or not any(data.ys[i].any() for i in train):
                raise SegmentationError(
                    f"leaving {obj!r} out leaves no labelled interval to train on"
                )
            folds.append((f"without {obj}", _subset(data, train), _subset(data, test)))
    elif split == "time":
        first = _merge_sets(
            [_subset(data, [i], slice(0, len(y) // 2)) for i, y in enumerate(data.ys)]
        )
        second = _merge_sets(
            [_subset(data, [i], slice(len(y) // 2, None)) for i, y in enumerate(data.ys)]
        )
        for name, a, b in (("first half", first, second), ("second half", second, first)):
            if not any(y.any() for y in a.ys):
                raise SegmentationError(f"the {name} of the sequences holds no labelled interval")
            folds.append((f"train on the {name}", a, b))
    else:
        raise SegmentationError(f"split must be 'hand', 'object' or 'time', got {split!r}")
    return folds


def table_one_folds(
    folds: Sequence[tuple[str, SequenceSet, SequenceSet]], *, l2: float = 1.0
) -> dict[str, dict[str, dict[str, float]]]:
    """The Table I comparison over folds: NLL summed, F1 pooled over the test folds.

    Returns the same layout as :func:`table_one`; ``train`` rows are pooled over
    each fold's training set (a sequence trains in several folds).
    """
    out: dict[str, dict[str, dict[str, float]]] = {}
    for name in ("logistic", "crf"):
        acc: dict[str, dict[str, Any]] = {
            "train": {"nll": 0.0, "n": 0, "ys": [], "pred": [], "edges": []},
            "test": {"nll": 0.0, "n": 0, "ys": [], "pred": [], "edges": []},
        }
        for _, train, test in folds:
            model = (LogisticSegmenter(l2=l2) if name == "logistic" else PairCRF(l2=l2)).fit(
                train.xs, train.ys
            )
            for split, data in (("train", train), ("test", test)):
                a = acc[split]
                a["nll"] += model.nll(data.xs, data.ys)
                a["n"] += data.n_steps
                a["ys"] += data.ys
                a["pred"] += model.predict(data.xs)
                a["edges"] += data.edges
        out[name] = {}
        for split, a in acc.items():
            pooled = SequenceSet(xs=[], ys=a["ys"], pairs=[], edges=a["edges"], gaps=[])
            out[name][split] = {
                "nll": a["nll"],
                "nll_per_variable": a["nll"] / a["n"],
                "latent_variables": float(a["n"]),
                **scores(pooled, a["pred"]),
            }
    return out


__all__ = [
    "SequenceSet",
    "fit_model",
    "labelled_sequences",
    "scores",
    "split_folds",
    "table_one",
    "table_one_folds",
    "training_pairs",
]
