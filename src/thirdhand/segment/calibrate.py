"""Calibrate a segmentation model to a user's own rig from a few labelled intervals.

A model trained elsewhere ranks steps well (its state score ``s_t = w · x_t``
grows with the evidence of manipulation) but its operating point — where the
score crosses zero, and how sticky the chain is — depends on the tracker, the
people and the task. Calibration keeps the trained state weights ``w`` of a
pair kind and refits three things on the user's labelled pairs, by maximum
likelihood of the same linear-chain CRF:

- an offset ``a`` and a scale ``b`` of the state score, ``s'_t = a + b s_t``
  (the at-rest bias: where "interacting" starts);
- the 2 × 2 transition weights (how long phases last, how short a pause is).

The new weights are ``w' = b w + a e_bias`` (``e_bias`` the bias column), so
the calibrated model is an ordinary model file. The prior keeps the fit close
to the trained model when labels are few: a Gaussian penalty
``λ/2 ‖θ − θ₀‖²`` around ``θ₀ = (trained transitions, a = 0, b = 1)``.

Which steps are labelled: every step of every pair named in the labels, within
``span`` (seconds from the start of the recording) when given; steps without
a labelled interval are negatives, so label every interaction of those pairs
inside the span.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np
from scipy.optimize import minimize

from thirdhand.arrays import FloatArray, IntArray
from thirdhand.demonstration import Demonstration
from thirdhand.segment.crf import N_TRANS, PairCRF, _Data
from thirdhand.segment.design import DemoFeatures
from thirdhand.segment.features import SegmentationError
from thirdhand.segment.intervals import labels_from_intervals, pair_intervals
from thirdhand.segment.model import SegmentModel
from thirdhand.segment.pipeline import pair_kind


def labelled_pairs(demo: Demonstration) -> list[tuple[str, str]]:
    """The body pairs that carry at least one labelled interval, in label order.

    Raises
    ------
    SegmentationError
        A label names a body the recording does not have, pairs a body with
        itself, or lies outside the recording.
    """
    names = set(demo.body_names)
    t0, t1 = float(demo.t[0]), float(demo.t[-1])
    out: list[tuple[str, str]] = []
    for k, iv in enumerate(demo.labels.interactions):
        for body in (iv.a, iv.b):
            if body not in names:
                raise SegmentationError(
                    f"label {k + 1} ({iv.a} · {iv.b}): no body {body!r} in the recording"
                )
        if iv.a == iv.b:
            raise SegmentationError(f"label {k + 1}: pairs {iv.a!r} with itself")
        if not (t0 - 1e-9 <= iv.start < iv.end <= t1 + 1e-9):
            raise SegmentationError(
                f"label {k + 1} ({iv.a} · {iv.b}): interval {iv.start - t0:.3f}–"
                f"{iv.end - t0:.3f} s is not inside the recording (0–{t1 - t0:.3f} s)"
            )
        pair = (iv.a, iv.b)
        if pair not in out and (iv.b, iv.a) not in out:
            out.append(pair)
    if not out:
        raise SegmentationError("the labels hold no interval: nothing to calibrate on")
    return out


def calibrate(
    model: SegmentModel,
    demos: Sequence[Demonstration],
    *,
    span: tuple[float, float] | None = None,
    prior: float = 1.0,
    scale: bool = True,
    transitions: bool = True,
) -> tuple[SegmentModel, dict[str, Any]]:
    """Refit the score offset, scale and transitions of each labelled pair kind.

    Parameters
    ----------
    model : SegmentModel
        The model to calibrate (e.g. the shipped default).
    demos : sequence of Demonstration
        The user's recordings with labels (interaction intervals).
    span : (float, float), optional
        Seconds from each recording's start: only the steps inside are used.
    prior : float
        ``λ`` of the Gaussian prior around the trained model (per parameter).
    scale, transitions : bool
        Refit the score's scale / the transition weights (else kept as trained;
        the offset is always refitted).

    Returns
    -------
    model : SegmentModel
        The calibrated model (a copy).
    report : dict
        Per pair kind: ``offset``, ``scale``, ``transition``, the number of
        sequences and steps, and the NLL per step before and after.

    Raises
    ------
    SegmentationError
        No demonstration, bad labels (see :func:`labelled_pairs`), an empty span,
        or no labelled pair with evidence.
    """
    if not demos:
        raise SegmentationError("calibration needs at least one labelled recording")
    if not prior > 0 or not np.isfinite(prior):
        raise SegmentationError(f"prior must be a positive number, got {prior}")
    by_kind: dict[str, tuple[list[FloatArray], list[IntArray]]] = {}
    for demo in demos:
        pairs = labelled_pairs(demo)
        feats = DemoFeatures(demo, model.features)
        times = feats.axis.times
        keep = np.ones(times.size, dtype=bool)
        if span is not None:
            lo, hi = span
            if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
                raise SegmentationError(f"span must be two increasing times, got {lo}, {hi}")
            rel = times - float(demo.t[0])
            keep = (rel >= lo) & (rel <= hi)
            if not keep.any():
                raise SegmentationError(
                    f"span {lo}–{hi} s holds no step of the recording "
                    f"(0–{float(demo.t[-1] - demo.t[0]):.3f} s)"
                )
        for a, b in pairs:
            x, ev = feats.pair(a, b)
            if not ev[keep].any():
                continue
            kind = pair_kind(demo, a, b)
            w = model.crf(kind).coef_state_
            s = x @ w
            x2 = np.stack([x[:, 0], s], axis=1)[keep]
            y = labels_from_intervals(pair_intervals(demo.labels, a, b), times)[keep]
            xs, ys = by_kind.setdefault(kind, ([], []))
            xs.append(x2)
            ys.append(y)
    if not by_kind:
        raise SegmentationError("no labelled pair has tracking evidence: nothing to calibrate on")
    crf = PairCRF(l2=0.0)
    per_kind = dict(model.per_kind)
    report: dict[str, Any] = {}
    for kind, (xs, ys) in sorted(by_kind.items()):
        base = model.crf(kind)
        data = _Data(xs, ys)
        theta0 = np.concatenate([base.coef_transition_.ravel(), [0.0, 1.0]])

        def objective(theta: FloatArray, data: _Data = data, theta0: FloatArray = theta0) -> Any:
            f, g = crf.objective(theta, data)
            d = theta - theta0
            return f + 0.5 * prior * float(d @ d), g + prior * d

        before = crf.objective(theta0, data)[0] / data.n_steps
        bounds: list[tuple[float | None, float | None]] = [(None, None)] * theta0.size
        if not transitions:
            bounds[:N_TRANS] = [(float(v), float(v)) for v in theta0[:N_TRANS]]
        if not scale:
            bounds[N_TRANS + 1] = (1.0, 1.0)
        res = minimize(objective, theta0, jac=True, method="L-BFGS-B", bounds=bounds)
        theta = res.x
        after = crf.objective(theta, data)[0] / data.n_steps
        offset, factor = float(theta[N_TRANS]), float(theta[N_TRANS + 1])
        w = factor * base.coef_state_
        w[0] += offset
        per_kind[kind] = (theta[:N_TRANS].reshape(2, 2).copy(), w)
        report[kind] = {
            "offset": offset,
            "scale": factor,
            "transition": theta[:N_TRANS].reshape(2, 2).round(4).tolist(),
            "sequences": len(xs),
            "steps": data.n_steps,
            "positive_steps": int(sum(int(y.sum()) for y in ys)),
            "nll_per_step_before": before,
            "nll_per_step_after": after,
        }
    training = {**model.training, "calibration": report}
    return replace(model, per_kind=per_kind, training=training), report


__all__ = ["calibrate", "labelled_pairs"]
