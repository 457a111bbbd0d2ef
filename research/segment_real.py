"""The real labelled recording behind the shipped model, and scores on it.

``toolbox_coop_4`` (the 3rdHand project's cooperative toolbox assembly,
Polhemus G4, ≈ 100 Hz, 67 s) carries the human ``lock`` labels of the **left
hand only** (``ann_kvg.kvg``): a hand actively manipulating a board. The other
hands' labels are kept apart to test on pairs the model never saw, so every
function here uses the left hand's finger–board pairs and nothing else; the
other hands' pairs are not negatives, they are unknown.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from thirdhand.demonstration import Demonstration
from thirdhand.segment.evaluate import frame_f1
from thirdhand.segment.intervals import intervals_from_labels, runs
from thirdhand.segment.model import SegmentModel
from thirdhand.segment.pipeline import SegmentationResult, segment_demonstration

#: Folder of the recording under the shared data (``../shared/data``).
TOOLBOX_COOP_4 = Path("3rdhand") / "toolbox_coop_4"
#: The hand whose labels are public.
LABELLED_HAND = "/human/lh"


def load_labelled(folder: str | os.PathLike[str]) -> Demonstration:
    """A 3rdHand MLR folder with the labels of its ``ann_kvg.kvg``."""
    from thirdhand.io import kvg, load

    path = Path(folder)
    demo = load(path)
    labels = kvg.read_annotations(path / "ann_kvg.kvg", frame_times=demo.t, bodies=demo.bodies)
    return demo.replace(labels=labels)


@dataclass(frozen=True)
class HandScores:
    """Scores of one hand's finger–object pairs against the labels.

    Attributes
    ----------
    frame_f1 : float
        Over every step of every finger–object pair of the hand.
    interval_recall : float
        Fraction of the labelled intervals (per pair) overlapped by a predicted one.
    intervals : int
        Labelled intervals, over the pairs.
    predicted_fraction, true_fraction : float
        Fraction of steps predicted / labelled interacting.
    per_pair : dict (finger, object) -> frame F1
    """

    frame_f1: float
    interval_recall: float
    intervals: int
    predicted_fraction: float
    true_fraction: float
    per_pair: dict[tuple[str, str], float]


def hand_scores(
    result: SegmentationResult,
    hand: str = LABELLED_HAND,
    *,
    objects: Sequence[str] | None = None,
) -> HandScores:
    """Frame F1 and interval recall of ``hand``'s finger–object pairs (``a`` under ``hand/``).

    ``objects`` restricts the pairs to those objects (e.g. a held-out board).
    """
    rows = [
        (p, p.truth)
        for p in result.pairs
        if p.truth is not None
        and p.kind == "finger-object"
        and p.a.startswith(hand + "/")
        and (objects is None or p.b in objects)
    ]
    if not rows:
        raise ValueError(f"no labelled finger–object pair of {hand} in the result")
    found = total = 0
    for p, y in rows:
        for lo, hi in runs(y.astype(np.int64)):
            total += 1
            found += bool(p.label[lo:hi].any())
    truth = [y for _, y in rows]
    pred = [p.label for p, _ in rows]
    return HandScores(
        frame_f1=frame_f1(truth, pred),
        interval_recall=found / total if total else float("nan"),
        intervals=total,
        predicted_fraction=float(np.mean(np.concatenate(pred))),
        true_fraction=float(np.mean(np.concatenate(truth))),
        per_pair={(p.a, p.b): frame_f1([y], [p.label]) for p, y in rows},
    )


def score_model(
    model: SegmentModel | None, demo: Demonstration, hand: str = LABELLED_HAND
) -> HandScores:
    """Segment ``demo`` with ``model`` (default: shipped) and score ``hand``'s pairs."""
    return hand_scores(segment_demonstration(demo, model), hand)


def predicted_intervals(result: SegmentationResult, a: str, b: str) -> list[tuple[float, float]]:
    """The predicted intervals of one pair, seconds."""
    p = result.pair(a, b)
    return intervals_from_labels(p.label, result.edges)


__all__ = [
    "LABELLED_HAND",
    "TOOLBOX_COOP_4",
    "HandScores",
    "hand_scores",
    "load_labelled",
    "predicted_intervals",
    "score_model",
]
