"""Scores of a segmentation against ground truth.

- **NLL**: negative log-likelihood of the true labels, total and per latent variable;
- **frame F1**: F1 of the positive class over all latent steps;
- **interval IoU**: for each true interval, the best intersection-over-union with a
  predicted interval of the same pair, averaged over true intervals (0 when missed);
- **boundary error**: for each true start (end), the distance in seconds to the
  nearest predicted start (end) of the same pair, averaged over the true
  boundaries that have a predicted counterpart; ``missed`` counts the others.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from thirdhand.arrays import IntArray

Interval = tuple[float, float]


def frame_f1(y_true: Sequence[IntArray], y_pred: Sequence[IntArray]) -> float:
    """F1 of the positive class over all steps of all sequences (1.0 when both are empty)."""
    t = np.concatenate([np.asarray(y) for y in y_true]) != 0
    p = np.concatenate([np.asarray(y) for y in y_pred]) != 0
    tp = float(np.sum(t & p))
    denom = float(np.sum(t) + np.sum(p))
    return 1.0 if denom == 0 else 2.0 * tp / denom


def frame_accuracy(y_true: Sequence[IntArray], y_pred: Sequence[IntArray]) -> float:
    """Fraction of steps labelled correctly."""
    t = np.concatenate([np.asarray(y) for y in y_true]) != 0
    p = np.concatenate([np.asarray(y) for y in y_pred]) != 0
    return float(np.mean(t == p)) if t.size else 1.0


def _iou(a: Interval, b: Interval) -> float:
    inter = max(0.0, min(a[1], b[1]) - max(a[0], b[0]))
    union = max(a[1], b[1]) - min(a[0], b[0])
    return inter / union if union > 0 else 0.0


def interval_iou(true: Sequence[Sequence[Interval]], pred: Sequence[Sequence[Interval]]) -> float:
    """Mean over true intervals of the best IoU with a predicted interval of the same pair.

    Parameters
    ----------
    true, pred : sequence (one per pair) of sequences of (start, end), seconds

    Returns
    -------
    float
        NaN when there is no true interval at all.
    """
    scores = [
        max((_iou(ti, pi) for pi in ps), default=0.0)
        for ts, ps in zip(true, pred, strict=True)
        for ti in ts
    ]
    return float(np.mean(scores)) if scores else float("nan")


@dataclass(frozen=True)
class BoundaryError:
    """Mean absolute boundary error, seconds, and the boundaries without a prediction."""

    mean_s: float
    matched: int
    missed: int


def boundary_error(
    true: Sequence[Sequence[Interval]], pred: Sequence[Sequence[Interval]]
) -> BoundaryError:
    """Distance from each true start/end to the nearest predicted start/end of its pair."""
    errs: list[float] = []
    missed = 0
    for ts, ps in zip(true, pred, strict=True):
        for k in (0, 1):
            cand = np.array([p[k] for p in ps])
            for ti in ts:
                if cand.size == 0:
                    missed += 1
                else:
                    errs.append(float(np.min(np.abs(cand - ti[k]))))
    return BoundaryError(
        mean_s=float(np.mean(errs)) if errs else float("nan"), matched=len(errs), missed=missed
    )


__all__ = [
    "BoundaryError",
    "boundary_error",
    "frame_accuracy",
    "frame_f1",
    "interval_iou",
]
