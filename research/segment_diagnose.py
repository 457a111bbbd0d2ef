"""Where a segmentation goes wrong: boundary shifts vs whole missed or extra intervals.

Every wrong latent step of a pair falls in exactly one class:

- **boundary**: a run of wrong steps (false positives or false negatives) that
  touches a true boundary, is at most ``k`` steps long, and shifts the edge of an
  interval that truth and prediction share (the predicted interval overlaps the
  true one);
- **missed**: a false-negative step of a true interval that no predicted interval
  overlaps at all;
- **extra**: a false-positive step of a predicted interval that overlaps no true
  interval;
- **other**: the rest: a gap between two true intervals bridged by the
  prediction, a hole inside a true interval, an edge shifted by more than ``k``.

The *tolerant* frame F1 (``collar_f1``) drops, from the score, the steps within
``k`` steps of a true boundary (a "collar", as in speech and action
segmentation): a prediction that only shifts boundaries by up to ``k`` steps
scores 1. With ``k = 1`` on a 20 Hz latent axis that is ±50 ms, about the
uncertainty of where a window-based feature places a change.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from thirdhand import se3
from thirdhand.arrays import BoolArray, IntArray
from thirdhand.demonstration import Demonstration
from thirdhand.segment.features import LatentAxis
from thirdhand.segment.intervals import runs
from thirdhand.segment.pipeline import SegmentationResult

#: Error classes, in report order.
ERROR_CLASSES: tuple[str, ...] = ("boundary", "missed", "extra", "other")


@dataclass
class ErrorBreakdown:
    """Counts of latent steps of one or more sequences.

    Attributes
    ----------
    steps : int
        Latent steps scored.
    true_pos, false_pos, false_neg : int
    errors : dict str -> int
        Wrong steps per class of :data:`ERROR_CLASSES` (they sum to
        ``false_pos + false_neg``).
    collar_tp, collar_fp, collar_fn : int
        As ``true_pos`` … over the steps outside the boundary collar.
    true_intervals, missed_intervals, pred_intervals, extra_intervals : int
        Intervals in the truth (in the prediction) and those without any overlap.
    """

    steps: int = 0
    true_pos: int = 0
    false_pos: int = 0
    false_neg: int = 0
    errors: dict[str, int] = field(default_factory=lambda: dict.fromkeys(ERROR_CLASSES, 0))
    collar_tp: int = 0
    collar_fp: int = 0
    collar_fn: int = 0
    true_intervals: int = 0
    missed_intervals: int = 0
    pred_intervals: int = 0
    extra_intervals: int = 0

    def __iadd__(self, other: ErrorBreakdown) -> ErrorBreakdown:
        for name in (
            "steps",
            "true_pos",
            "false_pos",
            "false_neg",
            "collar_tp",
            "collar_fp",
            "collar_fn",
            "true_intervals",
            "missed_intervals",
            "pred_intervals",
            "extra_intervals",
        ):
            setattr(self, name, getattr(self, name) + getattr(other, name))
        for c in ERROR_CLASSES:
            self.errors[c] += other.errors[c]
        return self

    @property
    def f1(self) -> float:
        """Strict frame F1 (1.0 when truth and prediction are both empty)."""
        return _f1(self.true_pos, self.false_pos, self.false_neg)

    @property
    def collar_f1(self) -> float:
        """Frame F1 outside the ±k-step collar around true boundaries."""
        return _f1(self.collar_tp, self.collar_fp, self.collar_fn)

    def share(self, cls: str) -> float:
        """Fraction of the wrong steps in class ``cls`` (NaN when nothing is wrong)."""
        wrong = self.false_pos + self.false_neg
        return self.errors[cls] / wrong if wrong else float("nan")


def _f1(tp: int, fp: int, fn: int) -> float:
    denom = 2 * tp + fp + fn
    return 1.0 if denom == 0 else 2.0 * tp / denom


def boundary_collar(truth: IntArray, k: int) -> BoolArray:
    """Steps within ``k`` steps of a true boundary, shape (n_steps,).

    A boundary lies between steps ``i − 1`` and ``i`` where the label changes;
    the collar holds steps ``i − k … i + k − 1`` (``2k`` steps per boundary).
    The ends of the recording are not boundaries.
    """
    y = np.asarray(truth) != 0
    n = y.size
    out = np.zeros(n, dtype=bool)
    if k <= 0 or n < 2:
        return out
    for i in np.flatnonzero(y[1:] != y[:-1]) + 1:
        out[max(i - k, 0) : min(i + k, n)] = True
    return out


def _overlaps(a: tuple[int, int], spans: list[tuple[int, int]]) -> bool:
    return any(s < a[1] and a[0] < e for s, e in spans)


def error_breakdown(truth: IntArray, pred: IntArray, k: int = 1) -> ErrorBreakdown:
    """Classify the wrong steps of one labelled sequence (see the module docstring).

    Parameters
    ----------
    truth, pred : ndarray of int, shape (n_steps,)
        0/1 labels on the latent axis.
    k : int
        Boundary tolerance, latent steps.
    """
    t = np.asarray(truth) != 0
    p = np.asarray(pred) != 0
    if t.shape != p.shape:
        raise ValueError(f"truth has {t.size} steps but the prediction {p.size}")
    out = ErrorBreakdown(steps=int(t.size))
    out.true_pos = int(np.sum(t & p))
    out.false_pos = int(np.sum(~t & p))
    out.false_neg = int(np.sum(t & ~p))
    keep = ~boundary_collar(t.astype(np.int64), k)
    out.collar_tp = int(np.sum(t & p & keep))
    out.collar_fp = int(np.sum(~t & p & keep))
    out.collar_fn = int(np.sum(t & ~p & keep))
    t_runs = runs(t.astype(np.int64))
    p_runs = runs(p.astype(np.int64))
    out.true_intervals = len(t_runs)
    out.pred_intervals = len(p_runs)
    t_lonely = [r for r in t_runs if not _overlaps(r, p_runs)]
    p_lonely = [r for r in p_runs if not _overlaps(r, t_runs)]
    out.missed_intervals = len(t_lonely)
    out.extra_intervals = len(p_lonely)
    for lo, hi in t_lonely:
        out.errors["missed"] += hi - lo
    for lo, hi in p_lonely:
        out.errors["extra"] += hi - lo
    n = t.size
    # Remaining wrong runs: false negatives inside predicted-overlapping true
    # intervals, false positives inside truth-overlapping predicted intervals.
    for wrong, inside in ((t & ~p, t_runs), (~t & p, p_runs)):
        lonely = t_lonely if inside is t_runs else p_lonely
        for lo, hi in runs(wrong.astype(np.int64)):
            if any(s <= lo and hi <= e for s, e in lonely):
                continue
            at_edge = (lo > 0 and t[lo - 1] != t[lo]) or (hi < n and t[hi] != t[hi - 1])
            # A boundary shift borders the shared interval on one side only.
            shared_left = lo > 0 and p[lo - 1] and t[lo - 1]
            shared_right = hi < n and p[hi] and t[hi]
            if at_edge and hi - lo <= k and (shared_left != shared_right):
                out.errors["boundary"] += hi - lo
            else:
                out.errors["other"] += hi - lo
    return out


def breakdown_many(
    truths: Sequence[IntArray], preds: Sequence[IntArray], k: int = 1
) -> ErrorBreakdown:
    """:func:`error_breakdown` summed over sequences."""
    total = ErrorBreakdown()
    for t, p in zip(truths, preds, strict=True):
        total += error_breakdown(t, p, k)
    return total


def breakdown_by_kind(result: SegmentationResult, k: int = 1) -> dict[str, ErrorBreakdown]:
    """Error breakdown of a segmented, labelled demonstration per pair kind.

    Parameters
    ----------
    result : SegmentationResult
        With ground truth (``PairResult.truth``); pairs without it are skipped.
    k : int
        Boundary tolerance, latent steps.

    Returns
    -------
    dict
        Pair kind (and ``"hand-object (aggregated)"``) → :class:`ErrorBreakdown`.
    """
    out: dict[str, ErrorBreakdown] = {}
    for p in result.pairs:
        if p.truth is not None:
            out.setdefault(p.kind, ErrorBreakdown()).__iadd__(error_breakdown(p.truth, p.label, k))
    for h in result.hands:
        if h.truth is not None:
            key = "hand-object (aggregated)"
            out.setdefault(key, ErrorBreakdown()).__iadd__(error_breakdown(h.truth, h.label, k))
    return out


#: Kinematic classes of :func:`kinematic_classes`, by code.
KINEMATIC_CLASSES: tuple[str, ...] = ("non-rigid", "rigid, moving", "rigid, still")


def kinematic_classes(
    demo: Demonstration, a: str, b: str, axis: LatentAxis, *, tol: float = 1e-7
) -> IntArray:
    """What the bodies do during each latent step of a noise-free recording.

    A label audit: the report defines interaction as moving together under a
    (temporarily) rigid transformation, so on exact data a step is

    - 0 ``"non-rigid"``: B's pose in A's frame changes between two frames of the
      step by more than ``tol`` (metres, or quaternion components);
    - 1 ``"rigid, moving"``: it does not, and A or B moves in the world (by more
      than ``tol`` m between two frames): interacting by the definition;
    - 2 ``"rigid, still"``: neither moves: the definition cannot tell, and
      neither can any feature of the two trajectories over that step alone.

    Parameters
    ----------
    demo : Demonstration
        Noise-free, fully tracked (invalid frames are not checked).
    a, b : str
    axis : LatentAxis
    tol : float

    Returns
    -------
    ndarray of int, shape (axis.n_steps,)
    """
    ta, tb = demo.track(a), demo.track(b)
    rp, rq = se3.relative_pose(ta.pos, ta.quat, tb.pos, tb.quat)
    rq = se3.quat_make_continuous(rq)
    rel = np.maximum(
        np.linalg.norm(np.diff(rp, axis=0), axis=1), np.linalg.norm(np.diff(rq, axis=0), axis=1)
    )
    world = np.maximum(
        np.linalg.norm(np.diff(ta.pos, axis=0), axis=1),
        np.linalg.norm(np.diff(tb.pos, axis=0), axis=1),
    )
    steps = axis.frame_step[1:]
    rel_moves = np.zeros(axis.n_steps, dtype=bool)
    world_moves = np.zeros(axis.n_steps, dtype=bool)
    np.logical_or.at(rel_moves, steps, rel > tol)
    np.logical_or.at(world_moves, steps, world > tol)
    out = np.where(rel_moves, 0, np.where(world_moves, 1, 2))
    return out.astype(np.int64)


__all__ = [
    "ERROR_CLASSES",
    "KINEMATIC_CLASSES",
    "ErrorBreakdown",
    "boundary_collar",
    "breakdown_by_kind",
    "breakdown_many",
    "error_breakdown",
    "kinematic_classes",
]
