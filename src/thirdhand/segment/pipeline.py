"""Segment a whole demonstration: every relevant body pair, then hands.

Pairs considered by default (:func:`default_pairs`): finger–object and
hand–object (objects are parts and tools), tool–part and part–part. Each pair
gets the CRF's marginal probability and Viterbi label per latent step; each
hand (fingers grouped by ``BodyInfo.hand_body``) gets an aggregated label per
object: it interacts when at least ``min_fingers`` of its fingers do. With a
model carrying a :class:`~thirdhand.segment.assembly.ClosureConfig` (the shipped
one does), part–part pairs whose bounding boxes are apart are labelled by
whether the touching, interacting pairs connect them
(:mod:`thirdhand.segment.assembly`).

Rest: with a model whose ``rest_gate`` is set (the shipped one), a
hand/finger–object step at which the object or the finger shows no motion
beyond its own noise floor is labelled 0 with probability 0
(:mod:`thirdhand.segment.noise`): the report's label means the hand moves the
object, and then both move.

Missing data: a step whose window holds too few valid samples of both bodies
has no evidence (zero state potential). Runs of such steps up to
``model.max_gap_s`` are bridged by the chain; longer runs are not guessed: they
get label 0 and probability NaN (``null`` in JSON). A pair with a body never
tracked therefore gives an all-zero label and no intervals.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from thirdhand.arrays import BoolArray, FloatArray, IntArray
from thirdhand.demonstration import Demonstration
from thirdhand.segment.assembly import CLOSED_KINDS, ClosureConfig, close_pairs, touching
from thirdhand.segment.design import DemoFeatures
from thirdhand.segment.features import SegmentationError
from thirdhand.segment.hands import aggregate_hand, finger_groups
from thirdhand.segment.intervals import (
    clip_intervals,
    intervals_from_labels,
    labels_from_intervals,
    pair_intervals,
    runs,
)
from thirdhand.segment.model import SegmentModel, default_model

#: Pair kinds whose label is a hand moving an object (the rest gate applies).
HAND_KINDS = ("finger-object", "hand-object")


@dataclass
class PairResult:
    """Interaction phases of one body pair.

    Attributes
    ----------
    a, b : str
    kind : str
        ``"finger-object"``, ``"hand-object"``, ``"tool-part"``, ``"part-part"`` or ``"other"``.
    probability : ndarray, shape (n_steps,)
        The pair's own CRF marginal ``p(y_t = 1)``; NaN inside long gaps.
    label : ndarray of int, shape (n_steps,)
        Viterbi labels; for a part–part pair whose boxes are apart, the
        assembly closure's when the model has one (:mod:`thirdhand.segment.assembly`).
    evidence : ndarray of bool, shape (n_steps,)
    intervals : list of (start, end), seconds
    truth : ndarray of int, shape (n_steps,), or None
        Ground truth on the latent axis when the demonstration has labels.
    """

    a: str
    b: str
    kind: str
    probability: FloatArray
    label: IntArray
    evidence: BoolArray
    intervals: list[tuple[float, float]]
    truth: IntArray | None = None


@dataclass
class HandResult:
    """Aggregated interaction of a hand with an object.

    Attributes
    ----------
    hand : str
        ``BodyInfo.hand_body`` of the fingers.
    object : str
    fingers : list of str
    label : ndarray of int, shape (n_steps,)
    intervals : list of (start, end), seconds
    truth : ndarray of int, shape (n_steps,), or None
    """

    hand: str
    object: str
    fingers: list[str]
    label: IntArray
    intervals: list[tuple[float, float]]
    truth: IntArray | None = None


@dataclass
class SegmentationResult:
    """Interaction phases of a demonstration on the latent time axis.

    Attributes
    ----------
    times : ndarray, shape (n_steps,), seconds
        Centre of each latent step.
    edges : ndarray, shape (n_steps + 1,), seconds
    pairs : list of PairResult
    hands : list of HandResult
    """

    times: FloatArray
    edges: FloatArray
    pairs: list[PairResult] = field(default_factory=list)
    hands: list[HandResult] = field(default_factory=list)

    def pair(self, a: str, b: str) -> PairResult:
        """The result of the unordered pair {a, b}."""
        for p in self.pairs:
            if {p.a, p.b} == {a, b}:
                return p
        raise SegmentationError(f"pair ({a!r}, {b!r}) was not segmented")

    def to_dict(self) -> dict[str, Any]:
        """JSON-able form (NaN probabilities become ``null``)."""

        def prob(p: FloatArray) -> list[float | None]:
            return [None if math.isnan(v) else round(float(v), 6) for v in p]

        return {
            "format": "thirdhand.phases/1",
            "time": [round(float(v), 6) for v in self.times],
            "pairs": [
                {
                    "a": p.a,
                    "b": p.b,
                    "kind": p.kind,
                    "probability": prob(p.probability),
                    "label": p.label.tolist(),
                    "intervals": [[s, e] for s, e in p.intervals],
                }
                for p in self.pairs
            ],
            "hands": [
                {
                    "hand": h.hand,
                    "object": h.object,
                    "fingers": h.fingers,
                    "label": h.label.tolist(),
                    "intervals": [[s, e] for s, e in h.intervals],
                }
                for h in self.hands
            ],
        }


def pair_kind(demo: Demonstration, a: str, b: str) -> str:
    """Type of a pair, for reports: finger-object, hand-object, tool-part, part-part, other."""
    ka, kb = demo.info(a).kind, demo.info(b).kind
    kinds = {ka, kb}
    objects = {"part", "tool"}
    if (ka in ("finger", "hand") and kb in objects) or (kb in ("finger", "hand") and ka in objects):
        return "finger-object" if "finger" in kinds else "hand-object"
    if kinds == {"tool", "part"}:
        return "tool-part"
    if kinds == {"part"}:
        return "part-part"
    return "other"


def labelled_kinds(demo: Demonstration) -> set[str]:
    """Pair kinds with at least one labelled interval.

    Labels covering only hands and objects say nothing about part–part contact:
    only pairs of a covered kind get ground truth (unlabelled ones all zero).
    """
    return {pair_kind(demo, i.a, i.b) for i in demo.labels.interactions if i.a != i.b}


def hand_of(demo: Demonstration, body: str) -> str | None:
    """The hand a finger or hand body belongs to (``hand_body``, or itself), else None."""
    info = demo.info(body)
    if info.kind == "finger":
        return info.hand_body or body
    return body if info.kind == "hand" else None


def labelled_hands(demo: Demonstration) -> set[str]:
    """Hands (:func:`hand_of`) with at least one labelled interval.

    A recording may carry the labels of some hands only (``toolbox_coop_4``: the
    left hand's; the others are kept apart): the pairs of the other hands are
    unknown, not negatives, and get no ground truth.
    """
    out = set()
    for i in demo.labels.interactions:
        for body in (i.a, i.b):
            h = hand_of(demo, body)
            if h is not None:
                out.add(h)
    return out


def pair_has_truth(demo: Demonstration, a: str, b: str, kinds: set[str], hands: set[str]) -> bool:
    """Whether the pair (a, b) has ground truth: a labelled kind, and a labelled hand."""
    kind = pair_kind(demo, a, b)
    if kind not in kinds:
        return False
    if kind not in HAND_KINDS:
        return True
    h = hand_of(demo, a) or hand_of(demo, b)
    return h in hands


def default_pairs(demo: Demonstration) -> list[tuple[str, str]]:
    """Finger–object, hand–object, tool–part and part–part pairs, in a stable order."""
    parts = demo.bodies_of_kind("part")
    tools = demo.bodies_of_kind("tool")
    objects = parts + tools
    pairs = [(f, o) for f in demo.bodies_of_kind("finger") for o in objects]
    pairs += [(h, o) for h in demo.bodies_of_kind("hand") for o in objects]
    pairs += [(t, p) for t in tools for p in parts]
    pairs += list(itertools.combinations(parts, 2))
    return pairs


def _blank_long_gaps(
    prob: FloatArray, label: IntArray, evidence: BoolArray, max_steps: int
) -> None:
    for lo, hi in runs((~evidence).astype(np.int64)):
        if hi - lo > max_steps:
            prob[lo:hi] = np.nan
            label[lo:hi] = 0


def _close_assembly(
    pairs: list[PairResult],
    gaps: dict[tuple[str, str], FloatArray],
    config: ClosureConfig,
) -> None:
    """Replace part–part labels by the assembly closure (in place)."""
    parts = [p for p in pairs if p.kind in CLOSED_KINDS]
    closed = close_pairs(
        [(p.a, p.b) for p in parts],
        [p.label for p in parts],
        [touching(gaps.get((p.a, p.b)), config) for p in parts],
    )
    for p, y in zip(parts, closed, strict=True):
        p.label = y


def segment_demonstration(
    demo: Demonstration,
    model: SegmentModel | None = None,
    pairs: Sequence[tuple[str, str]] | None = None,
) -> SegmentationResult:
    """Interaction phases of every pair of a demonstration, and of every hand.

    Parameters
    ----------
    demo : Demonstration
    model : SegmentModel, optional
        Defaults to the model shipped with the package.
    pairs : sequence of (a, b), optional
        Defaults to :func:`default_pairs`.

    Returns
    -------
    SegmentationResult

    Raises
    ------
    SegmentationError
        A recording of fewer than 2 frames, a pair naming one body twice.
    DemonstrationError
        A pair naming an unknown body.
    """
    model = default_model() if model is None else model
    pairs = default_pairs(demo) if pairs is None else [tuple(p) for p in pairs]  # type: ignore[misc]
    feats = DemoFeatures(demo, model.features)
    axis = feats.axis
    crfs: dict[str, Any] = {}
    max_steps = math.floor(model.max_gap_s * axis.rate + 1e-9)
    has_truth = bool(demo.labels.interactions)
    # Ground truth only for the pair kinds the labels cover (see labelled_kinds).
    covered = labelled_kinds(demo)
    hands = labelled_hands(demo)
    result = SegmentationResult(times=axis.times, edges=axis.edges)
    for a, b in pairs:
        x, ev = feats.pair(a, b)
        kind = pair_kind(demo, a, b)
        crf = crfs.setdefault(kind, model.crf(kind))
        prob, label = crf.decode(x)
        if model.rest_gate and kind in HAND_KINDS:
            # Moving an object moves the hand and the object: either at rest, no.
            still = feats.rest(a) | feats.rest(b)
            prob = np.where(still, 0.0, prob)
            label = np.where(still, 0, label)
        truth = (
            labels_from_intervals(pair_intervals(demo.labels, a, b), axis.times)
            if pair_has_truth(demo, a, b, covered, hands)
            else None
        )
        result.pairs.append(PairResult(a, b, kind, prob, label, ev, intervals=[], truth=truth))
    if model.closure is not None:
        _close_assembly(result.pairs, feats.gaps, model.closure)
    span = (float(demo.t[0]), float(demo.t[-1]))
    for p in result.pairs:
        _blank_long_gaps(p.probability, p.label, p.evidence, max_steps)
        if not np.any(demo.valid(p.a) & demo.valid(p.b)):
            # Never tracked together: nothing observed (no probability), nothing interacts.
            p.probability = np.full_like(p.probability, np.nan)
            p.label = np.zeros_like(p.label)
        p.intervals = clip_intervals(intervals_from_labels(p.label, axis.edges), *span)
    result.hands = _hands(demo, result, model.min_fingers, has_truth)
    for h in result.hands:
        h.intervals = clip_intervals(h.intervals, *span)
    return result


def _hands(
    demo: Demonstration, result: SegmentationResult, min_fingers: int, has_truth: bool
) -> list[HandResult]:
    by_pair = {(p.a, p.b): p for p in result.pairs}
    out = []
    for hand, fingers in finger_groups(demo).items():
        objects = sorted({b for (a, b) in by_pair if a in fingers})
        for obj in objects:
            used = [f for f in fingers if (f, obj) in by_pair]
            label = aggregate_hand([by_pair[(f, obj)].label for f in used], min_fingers=min_fingers)
            truth = None
            if has_truth and any(by_pair[(f, obj)].truth is not None for f in used):
                direct = pair_intervals(demo.labels, hand, obj)
                if direct:
                    truth = labels_from_intervals(direct, result.times)
                else:
                    ft = [by_pair[(f, obj)].truth for f in used]
                    truth = aggregate_hand(
                        [t for t in ft if t is not None], min_fingers=min_fingers
                    )
            out.append(
                HandResult(
                    hand=hand,
                    object=obj,
                    fingers=used,
                    label=label,
                    intervals=intervals_from_labels(label, result.edges),
                    truth=truth,
                )
            )
    return out


__all__ = [
    "HandResult",
    "PairResult",
    "SegmentationResult",
    "default_pairs",
    "labelled_kinds",
    "pair_kind",
    "segment_demonstration",
]


def scores_by_kind(result: SegmentationResult) -> dict[str, dict[str, float]]:
    """Frame F1 and interval IoU per pair kind (and ``"hand-object (aggregated)"``).

    Only pairs with ground truth count; empty when the demonstration had no labels.
    """
    from thirdhand.segment.evaluate import frame_f1, interval_iou

    groups: dict[str, list[tuple[IntArray, IntArray, list[tuple[float, float]]]]] = {}
    for p in result.pairs:
        if p.truth is not None:
            groups.setdefault(p.kind, []).append((p.truth, p.label, p.intervals))
    for h in result.hands:
        if h.truth is not None:
            groups.setdefault("hand-object (aggregated)", []).append(
                (h.truth, h.label, h.intervals)
            )
    out = {}
    for kind, rows in groups.items():
        truth_ints = [intervals_from_labels(t, result.edges) for t, _, _ in rows]
        out[kind] = {
            "pairs": float(len(rows)),
            "frame_f1": frame_f1([t for t, _, _ in rows], [y for _, y, _ in rows]),
            "interval_iou": interval_iou(truth_ints, [i for _, _, i in rows]),
        }
    return out
