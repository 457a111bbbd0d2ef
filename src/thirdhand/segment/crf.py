"""The pair-wise linear-chain CRF of interaction phases (3rdHand report, annex).

``p(y | x) = Z(x)⁻¹ Π_t exp(φ_t(y_t, y_{t-1}, x)ᵀ θ)`` with binary ``y_t`` and

- transition features ``[y_t = a][y_{t-1} = b]``, ``a, b ∈ {0, 1}`` (zero at ``t = 0``),
  weights ``coef_transition_[a, b]``;
- state features ``x_t [y_t = 1]``, weights ``coef_state_``.

Training minimises the convex negative log-likelihood
``Σ_seq (log Z(x) − Σ_t φ_tᵀ θ) + ½ λ ||θ||²`` with L-BFGS; its gradient is the
expected features under the (pairwise) marginals minus the empirical features.
The state weights start from a logistic regression on the same features.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize

from thirdhand.arrays import FloatArray, IntArray
from thirdhand.segment.chain import (
    binary_expectations,
    binary_marginals,
    forward_backward,
    viterbi,
)
from thirdhand.segment.features import SegmentationError
from thirdhand.segment.logistic import fit_logistic_newton

N_TRANS = 4


class _Data:
    """Sequences concatenated once: rows, labels, offsets, empirical counts."""

    def __init__(self, xs: Sequence[FloatArray], ys: Sequence[IntArray] | None) -> None:
        if isinstance(xs, np.ndarray) and xs.ndim == 2:
            xs = [xs]
            ys = None if ys is None else [np.asarray(ys)]
        if not len(xs):
            raise SegmentationError("no sequence given")
        lens = np.array([len(x) for x in xs], dtype=np.int64)
        self.offsets = np.concatenate([[0], np.cumsum(lens)]).astype(np.int64)
        self.x = np.ascontiguousarray(np.concatenate([np.asarray(x, np.float64) for x in xs]))
        if self.x.ndim != 2:
            raise SegmentationError(f"feature sequences must be 2-D, got shape {self.x.shape}")
        if not np.all(np.isfinite(self.x)):
            raise SegmentationError("feature sequences contain a non-finite value")
        self.y: IntArray | None = None
        if ys is not None:
            if len(ys) != len(xs):
                raise SegmentationError(
                    f"{len(xs)} feature sequences but {len(ys)} label sequences"
                )
            for i, (x, y) in enumerate(zip(xs, ys, strict=True)):
                if len(x) != len(y):
                    raise SegmentationError(
                        f"sequence {i}: {len(x)} feature rows but {len(y)} labels"
                    )
            y_all = np.concatenate([np.asarray(y) for y in ys]).astype(np.int64)
            if y_all.size and not np.isin(y_all, (0, 1)).all():
                raise SegmentationError("labels must be 0 or 1")
            self.y = y_all
            first = np.zeros(len(y_all), dtype=bool)
            first[self.offsets[:-1][lens > 0]] = True
            prev = np.roll(y_all, 1)
            counts = np.zeros((2, 2))
            np.add.at(counts, (y_all[~first], prev[~first]), 1.0)
            self.trans_counts = counts
            self.state_counts = self.x[y_all == 1].sum(axis=0)

    @property
    def n_steps(self) -> int:
        return int(self.x.shape[0])


def _unary(x: FloatArray, w: FloatArray) -> FloatArray:
    u = np.zeros((x.shape[0], 2))
    u[:, 1] = x @ w
    return u


class PairCRF:
    """Binary linear-chain CRF over sequences of state features.

    Parameters
    ----------
    l2 : float
        Ridge penalty λ on every weight (transitions included).
    init : {"logistic", "zero"}
        Start from a Newton-fitted logistic regression on the state features, or zeros.
    max_iter : int
        L-BFGS iterations.
    tol : float
        L-BFGS relative tolerance on the objective (``ftol``).

    Attributes
    ----------
    coef_transition_ : ndarray, shape (2, 2)
        ``[a, b]``: weight of ``y_t = a`` after ``y_{t-1} = b``.
    coef_state_ : ndarray, shape (n_features,)
    n_iter_ : int
    """

    def __init__(
        self,
        *,
        l2: float = 1.0,
        init: str = "logistic",
        max_iter: int = 500,
        tol: float = 1e-9,
    ) -> None:
        self.l2 = l2
        self.init = init
        self.max_iter = max_iter
        self.tol = tol

    # ------------------------------------------------------------ objective
    def objective(self, theta: FloatArray, data: _Data) -> tuple[float, FloatArray]:
        """Penalised NLL and its gradient at ``theta = [transition (4), state (d)]``."""
        if data.y is None:
            raise SegmentationError("the objective needs labels")
        trans = theta[:N_TRANS].reshape(2, 2)
        w = theta[N_TRANS:]
        log_z, e_state, e_trans = binary_expectations(data.x, data.offsets, w, trans)
        score = float(w @ data.state_counts + np.sum(trans * data.trans_counts))
        f = log_z - score + 0.5 * self.l2 * float(theta @ theta)
        g = np.concatenate([(e_trans - data.trans_counts).ravel(), e_state - data.state_counts])
        return f, g + self.l2 * theta

    def fit(self, xs: Sequence[FloatArray], ys: Sequence[IntArray]) -> PairCRF:
        """Maximum-likelihood fit on sequences ``xs[i]`` (n_i, d), labels ``ys[i]`` (n_i,).

        L-BFGS runs on preconditioned variables: the state weights are whitened
        by the Cholesky factor of the logistic regression's Hessian at the
        starting point, and the transition weights scaled by ``sqrt(n / 20)``,
        ``n`` the number of steps (a rough curvature of transition counts), which
        about halves the iterations on badly scaled features.
        """
        data = _Data(xs, ys)
        assert data.y is not None
        d = data.x.shape[1]
        if self.init == "logistic":
            w0 = fit_logistic_newton(data.x, data.y.astype(float), l2=self.l2)
        elif self.init == "zero":
            w0 = np.zeros(d)
        else:
            raise SegmentationError(f"init must be 'logistic' or 'zero', got {self.init!r}")
        s = data.x @ w0
        p = np.exp(-np.logaddexp(0.0, -s))
        hess = (data.x * (p * (1.0 - p))[:, None]).T @ data.x
        chol = np.linalg.cholesky(hess + max(self.l2, 1e-6) * np.eye(d))
        t_scale = np.sqrt(max(data.n_steps, 1) / 20.0)

        def to_theta(phi: FloatArray) -> FloatArray:
            return np.concatenate([phi[:N_TRANS] / t_scale, np.linalg.solve(chol.T, phi[N_TRANS:])])

        def objective(phi: FloatArray) -> tuple[float, FloatArray]:
            f, g = self.objective(to_theta(phi), data)
            return f, np.concatenate([g[:N_TRANS] / t_scale, np.linalg.solve(chol, g[N_TRANS:])])

        phi0 = np.concatenate([np.zeros(N_TRANS), chol.T @ w0])
        res = minimize(
            objective,
            phi0,
            jac=True,
            method="L-BFGS-B",
            options={"maxiter": self.max_iter, "ftol": self.tol, "gtol": 1e-9},
        )
        self.set_params_theta(to_theta(res.x))
        self.n_iter_ = int(res.nit)
        return self

    def set_params_theta(self, theta: FloatArray) -> PairCRF:
        """Set the learned weights from a flat vector ``[transition (4), state (d)]``."""
        theta = np.asarray(theta, dtype=np.float64)
        self.coef_transition_ = theta[:N_TRANS].reshape(2, 2).copy()
        self.coef_state_ = theta[N_TRANS:].copy()
        return self

    @property
    def theta_(self) -> FloatArray:
        """Flat weights ``[transition (4), state (d)]``."""
        return np.concatenate([self.coef_transition_.ravel(), self.coef_state_])

    # ------------------------------------------------------------ inference
    def _split(self, data: _Data, flat: NDArray[np.generic]) -> list[NDArray[np.generic]]:
        return [flat[a:b] for a, b in zip(data.offsets[:-1], data.offsets[1:], strict=True)]

    def predict_proba(self, xs: Sequence[FloatArray]) -> list[FloatArray]:
        """Marginals ``p(y_t = 1 | x)`` per sequence, each of shape (n_i,)."""
        data = _Data(xs, None)
        marg = binary_marginals(data.x @ self.coef_state_, self.coef_transition_, data.offsets)
        return self._split(data, np.clip(marg, 0.0, 1.0))  # type: ignore[return-value]

    def predict(self, xs: Sequence[FloatArray]) -> list[IntArray]:
        """Viterbi labelling per sequence, each of shape (n_i,)."""
        data = _Data(xs, None)
        path, _ = viterbi(_unary(data.x, self.coef_state_), self.coef_transition_, data.offsets)
        return self._split(data, path)  # type: ignore[return-value]

    def decode(self, x: FloatArray) -> tuple[FloatArray, IntArray]:
        """Marginals and Viterbi labels of one sequence, sharing the state scores.

        Parameters
        ----------
        x : ndarray, shape (n_steps, n_features)

        Returns
        -------
        probability : ndarray, shape (n_steps,)
            ``p(y_t = 1 | x)``, as :meth:`predict_proba`.
        label : ndarray of int, shape (n_steps,)
            As :meth:`predict`.
        """
        data = _Data([x], None)
        score = np.einsum("ij,j->i", data.x, self.coef_state_)
        marg = binary_marginals(score, self.coef_transition_, data.offsets)
        u = np.zeros((score.shape[0], 2))
        u[:, 1] = score
        path, _ = viterbi(u, self.coef_transition_, data.offsets)
        return np.clip(marg, 0.0, 1.0), np.asarray(path, dtype=np.int64)

    def nll(self, xs: Sequence[FloatArray], ys: Sequence[IntArray]) -> float:
        """Unpenalised negative log-likelihood of the labels, summed over sequences."""
        data = _Data(xs, ys)
        assert data.y is not None
        u = _unary(data.x, self.coef_state_)
        log_z, _, _ = forward_backward(u, self.coef_transition_, data.offsets)
        score = u[data.y == 1, 1].sum() + np.sum(self.coef_transition_ * data.trans_counts)
        return float(log_z.sum() - score)


__all__ = ["PairCRF"]
