"""Agreement of a segmentation with a human's per-sample phase labels.

- **Frame accuracy** under the best one-to-one map from predicted skills to
  human labels (Hungarian assignment, :func:`scipy.optimize.linear_sum_assignment`,
  on the confusion counts of all streams together); a skill left without a
  label (more skills than labels) counts as wrong wherever it is used.
- **Boundaries**: predicted and true change times are matched one to one, each
  pair at most ``tolerance`` seconds apart (maximum matching, greedy by distance
  on sorted lists, which is optimal on a line); precision = matched / predicted,
  recall = matched / true, F1 their harmonic mean (0 when both are 0).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import linear_sum_assignment

from thirdhand.arrays import FloatArray, IntArray
from thirdhand.primitives.checks import PrimitiveError


@dataclass(frozen=True)
class BoundaryScore:
    """Matched boundaries within a tolerance.

    Attributes
    ----------
    n_true, n_pred, n_matched : int
    tolerance : float
        Seconds.
    """

    n_true: int
    n_pred: int
    n_matched: int
    tolerance: float

    @property
    def precision(self) -> float:
        """Matched / predicted (1 when nothing was predicted and nothing was true)."""
        if self.n_pred == 0:
            return 1.0 if self.n_true == 0 else 0.0
        return self.n_matched / self.n_pred

    @property
    def recall(self) -> float:
        """Matched / true (1 when there is no true boundary)."""
        return 1.0 if self.n_true == 0 else self.n_matched / self.n_true

    @property
    def f1(self) -> float:
        """Harmonic mean of precision and recall."""
        p, r = self.precision, self.recall
        return 0.0 if p + r == 0 else 2 * p * r / (p + r)

    def __add__(self, other: BoundaryScore) -> BoundaryScore:
        return BoundaryScore(
            self.n_true + other.n_true,
            self.n_pred + other.n_pred,
            self.n_matched + other.n_matched,
            self.tolerance,
        )


def change_times(t: ArrayLike, labels: ArrayLike) -> FloatArray:
    """Times where a label sequence changes, midway between the two samples, seconds."""
    ta, la = np.asarray(t, dtype=np.float64), np.asarray(labels)
    k = np.flatnonzero(la[1:] != la[:-1])
    return 0.5 * (ta[k] + ta[k + 1])


def match_boundaries(true: ArrayLike, pred: ArrayLike, *, tolerance: float = 1.0) -> BoundaryScore:
    """One-to-one matching of predicted to true boundary times within ``tolerance`` s.

    Both lists are sorted, so a maximum matching is found by a single sweep
    (match the earliest unmatched pair in reach, else drop the earlier one).
    """
    if not np.isfinite(tolerance) or tolerance < 0:
        raise PrimitiveError(f"boundary tolerance must be a non-negative number, got {tolerance}")
    a = np.sort(np.asarray(true, dtype=np.float64).ravel())
    b = np.sort(np.asarray(pred, dtype=np.float64).ravel())
    i = j = m = 0
    while i < a.size and j < b.size:
        if abs(a[i] - b[j]) <= tolerance:
            m += 1
            i += 1
            j += 1
        elif a[i] < b[j]:
            i += 1
        else:
            j += 1
    return BoundaryScore(int(a.size), int(b.size), m, float(tolerance))


def best_label_map(
    pred: Sequence[ArrayLike], true: Sequence[ArrayLike]
) -> tuple[dict[int, int], int, int]:
    """The one-to-one skill → label map with most agreeing samples over all streams.

    Returns
    -------
    mapping : dict
        Predicted skill → true label (skills left unmatched are absent).
    n_correct, n_total : int
    """
    if len(pred) != len(true):
        raise PrimitiveError(f"{len(pred)} predicted label sequences for {len(true)} true ones")
    ps = [np.asarray(p).ravel().astype(np.int64) for p in pred]
    ts = [np.asarray(t).ravel().astype(np.int64) for t in true]
    for i, (p, t) in enumerate(zip(ps, ts, strict=True)):
        if p.size != t.size:
            raise PrimitiveError(f"stream {i}: {p.size} predicted labels for {t.size} samples")
    allp, allt = np.concatenate(ps), np.concatenate(ts)
    up, ut = np.unique(allp), np.unique(allt)
    conf = np.zeros((up.size, ut.size), dtype=np.int64)
    np.add.at(conf, (np.searchsorted(up, allp), np.searchsorted(ut, allt)), 1)
    rows, cols = linear_sum_assignment(-conf)
    mapping = {int(up[r]): int(ut[c]) for r, c in zip(rows, cols, strict=True)}
    return mapping, int(conf[rows, cols].sum()), int(allp.size)


def apply_map(pred: ArrayLike, mapping: dict[int, int], *, missing: int = -1) -> IntArray:
    """Predicted skills relabelled by ``mapping`` (unmapped skills become ``missing``)."""
    p = np.asarray(pred).astype(np.int64)
    out = np.full(p.shape, missing, dtype=np.int64)
    for k, v in mapping.items():
        out[p == k] = v
    return out


def segments_to_frames(bounds: ArrayLike, labels: ArrayLike, n: int) -> IntArray:
    """Per-sample labels from segment bounds (sample indices, first 0, last n−1) and labels.

    Sample ``bounds[h]`` (a cut) belongs to the segment that starts there.
    """
    b = np.asarray(bounds, dtype=np.int64)
    lab = np.asarray(labels, dtype=np.int64)
    if b.size != lab.size + 1 or b[0] != 0 or b[-1] != n - 1 or np.any(np.diff(b) <= 0):
        raise PrimitiveError(
            f"segment bounds must rise from 0 to {n - 1} with one more entry than labels, "
            f"got {b.size} bounds for {lab.size} labels"
        )
    out = np.empty(n, dtype=np.int64)
    for h in range(lab.size):
        out[b[h] : b[h + 1]] = lab[h]
    out[-1] = lab[-1]
    return out
