"""Logistic regression on the CRF's state features, fitted by Newton's method.

The per-step baseline of the report's Table I and the CRF's initialisation:
``p(y_t = 1 | x_t) = σ(x_tᵀ w)``, minimising
``Σ_t [log(1 + exp(x_tᵀ w)) − y_t x_tᵀ w] + ½ λ ||w||²``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from thirdhand.arrays import FloatArray, IntArray
from thirdhand.segment.features import SegmentationError


def _softplus(s: FloatArray) -> FloatArray:
    return np.logaddexp(0.0, s)


def _sigmoid(s: FloatArray) -> FloatArray:
    out: FloatArray = np.exp(-np.logaddexp(0.0, -s))
    return out


def logistic_loss(w: FloatArray, x: FloatArray, y: FloatArray, l2: float = 0.0) -> float:
    """Penalised negative log-likelihood of labels ``y`` (n,) given rows ``x`` (n, d)."""
    s = x @ w
    return float(np.sum(_softplus(s) - y * s) + 0.5 * l2 * (w @ w))


def fit_logistic_newton(
    x: FloatArray,
    y: FloatArray,
    *,
    l2: float = 1.0,
    max_iter: int = 100,
    tol: float = 1e-8,
) -> FloatArray:
    """Weights minimising :func:`logistic_loss` by damped Newton steps.

    Parameters
    ----------
    x : ndarray, shape (n, d)
    y : ndarray, shape (n,), values in {0, 1}
    l2 : float
        Ridge penalty λ (applied to every weight); > 0 keeps separable data finite.
    max_iter : int
    tol : float
        Stop when the gradient's max-norm falls below ``tol × n``.

    Returns
    -------
    w : ndarray, shape (d,)
    """
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    n, d = x.shape
    w = np.zeros(d)
    f = logistic_loss(w, x, y, l2)
    for _ in range(max_iter):
        s = x @ w
        p = _sigmoid(s)
        g = x.T @ (p - y) + l2 * w
        if np.max(np.abs(g)) < tol * max(n, 1):
            break
        h = (x * (p * (1.0 - p))[:, None]).T @ x + (l2 + 1e-12) * np.eye(d)
        step = np.linalg.solve(h, g)
        lr = 1.0
        while lr > 1e-10:
            w_new = w - lr * step
            f_new = logistic_loss(w_new, x, y, l2)
            if f_new <= f - 1e-4 * lr * (g @ step):
                break
            lr *= 0.5
        else:
            break
        w, f = w_new, f_new
    return w


class LogisticSegmenter:
    """Per-step logistic regression over sequences of state features.

    Parameters
    ----------
    l2 : float
        Ridge penalty on the weights.
    max_iter : int
        Newton iterations.

    Attributes
    ----------
    coef_ : ndarray, shape (n_features,)
    """

    def __init__(self, *, l2: float = 1.0, max_iter: int = 100) -> None:
        self.l2 = l2
        self.max_iter = max_iter

    def fit(self, xs: Sequence[FloatArray], ys: Sequence[IntArray]) -> LogisticSegmenter:
        """Fit on sequences ``xs[i]`` (n_i, d) with labels ``ys[i]`` (n_i,)."""
        x, y = _stack(xs, ys)
        self.coef_ = fit_logistic_newton(x, y, l2=self.l2, max_iter=self.max_iter)
        return self

    def predict_proba(self, xs: Sequence[FloatArray]) -> list[FloatArray]:
        """``p(y_t = 1 | x_t)`` per sequence, each of shape (n_i,)."""
        return [_sigmoid(np.asarray(x, np.float64) @ self.coef_) for x in xs]

    def predict(self, xs: Sequence[FloatArray]) -> list[IntArray]:
        """Labels ``p >= 0.5`` per sequence."""
        return [(p >= 0.5).astype(np.int64) for p in self.predict_proba(xs)]

    def nll(self, xs: Sequence[FloatArray], ys: Sequence[IntArray]) -> float:
        """Unpenalised negative log-likelihood summed over all steps."""
        x, y = _stack(xs, ys)
        return logistic_loss(self.coef_, x, y, 0.0)


def _stack(xs: Sequence[FloatArray], ys: Sequence[IntArray]) -> tuple[FloatArray, FloatArray]:
    if len(xs) != len(ys) or not xs:
        raise SegmentationError(
            f"expected as many label sequences as feature sequences (at least one), "
            f"got {len(xs)} and {len(ys)}"
        )
    for i, (x, y) in enumerate(zip(xs, ys, strict=True)):
        if len(x) != len(y):
            raise SegmentationError(f"sequence {i}: {len(x)} feature rows but {len(y)} labels")
    return (
        np.concatenate([np.asarray(x, np.float64) for x in xs]),
        np.concatenate([np.asarray(y, np.float64) for y in ys]),
    )


__all__ = ["LogisticSegmenter", "fit_logistic_newton", "logistic_loss"]
