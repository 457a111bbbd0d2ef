"""Probabilistic movement primitives (Paraschos et al. 2013).

A trajectory of ``dims`` dimensions over the phase ``z ∈ [0, 1]`` (normalised
time) is ``y(z) = Φ(z) w`` with normalised Gaussian RBFs per dimension; the
weights are Gaussian, ``w ~ N(mean_, cov_)``, learnt from several demonstrations
(ridge per demonstration, or EM with a shared observation noise).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from thirdhand.arrays import FloatArray
from thirdhand.primitives.checks import PrimitiveError, check_trajectory


def rbf_features(z: ArrayLike, n_weights: int, *, width: float | None = None) -> FloatArray:
    """Normalised RBFs over the phase, shape (n, n_weights).

    Centres equally spaced on ``[0, 1]``; width ``σ = 1 / n_weights`` by default.
    """
    za = np.asarray(z, dtype=np.float64)[:, None]
    c = np.linspace(0.0, 1.0, n_weights)
    sig = 1.0 / n_weights if width is None else width
    psi = np.exp(-0.5 * ((za - c) / sig) ** 2)
    out: FloatArray = psi / psi.sum(axis=1, keepdims=True)
    return out


def design_matrix(z: ArrayLike, n_weights: int, dims: int) -> FloatArray:
    """Block-diagonal features, shape (n * dims, n_weights * dims), dimension-major rows."""
    return np.asarray(np.kron(np.eye(dims), rbf_features(z, n_weights)), dtype=np.float64)


def ridge_weights(
    z: FloatArray, y: FloatArray, n_weights: int, regularization: float = 1e-6
) -> FloatArray:
    """Ridge weights of trajectories on a common phase grid.

    Parameters
    ----------
    z : ndarray, shape (n,)
        Phase of each sample.
    y : ndarray, shape (..., n, dims)
        Samples (a batch of trajectories is allowed).

    Returns
    -------
    ndarray, shape (..., dims * n_weights)
        Dimension-major: the first ``n_weights`` are dimension 0.
    """
    f = rbf_features(z, n_weights)
    gram = f.T @ f + regularization * np.eye(n_weights)
    w = np.linalg.solve(gram, f.T @ y)  # (..., n_weights, dims)
    return np.swapaxes(w, -1, -2).reshape(*y.shape[:-2], -1)


class ProMP:
    """Gaussian distribution over trajectory weights.

    Parameters
    ----------
    n_weights : int
        RBFs per dimension.
    regularization : float
        Ridge coefficient, and the diagonal added to the covariance (relative to its
        mean variance) to keep it invertible.

    Attributes
    ----------
    mean_ : ndarray, shape (dims * n_weights,)
    cov_ : ndarray, shape (dims * n_weights, dims * n_weights)
    noise_ : float
        Observation noise variance (units² of the data).
    dims_ : int
    duration_ : float
        Mean demonstrated duration, seconds.
    """

    def __init__(self, n_weights: int = 15, *, regularization: float = 1e-6) -> None:
        self.n_weights = n_weights
        self.regularization = regularization

    @classmethod
    def from_params(
        cls,
        mean: ArrayLike,
        cov: ArrayLike,
        *,
        dims: int,
        noise: float = 1e-8,
        duration: float = 1.0,
    ) -> ProMP:
        """A ProMP from stored parameters (see :mod:`thirdhand.primitives.serialize`)."""
        m = np.asarray(mean, dtype=np.float64)
        c = np.asarray(cov, dtype=np.float64)
        if m.size % dims or c.shape != (m.size, m.size):
            raise PrimitiveError(
                f"ProMP parameters: mean of {m.size} and cov {c.shape} do not fit {dims} dims"
            )
        p = cls(m.size // dims)
        p.mean_, p.cov_, p.dims_, p.noise_, p.duration_ = m, c, dims, float(noise), duration
        return p

    def fit(
        self,
        trajectories: Sequence[tuple[ArrayLike, ArrayLike]],
        *,
        method: Literal["ridge", "em"] = "ridge",
        n_iter: int = 20,
    ) -> ProMP:
        """Learn from demonstrations ``[(t, y), …]``, each ``t (n_i,)`` and ``y (n_i, dims)``.

        Each demonstration's time is normalised to the phase ``[0, 1]``.
        ``method="em"`` treats the weights as latent with a shared isotropic noise.
        """
        if not trajectories:
            raise PrimitiveError("ProMP: no demonstration given")
        data = [
            check_trajectory(t, y, name=f"demonstration {i}")
            for i, (t, y) in enumerate(trajectories)
        ]
        dims = data[0][1].shape[1]
        for i, (_, y) in enumerate(data):
            if y.shape[1] != dims:
                raise PrimitiveError(
                    f"ProMP: demonstration {i} has {y.shape[1]} dimensions, expected {dims}"
                )
        zs = [(t - t[0]) / (t[-1] - t[0]) for t, _ in data]
        ws = np.stack(
            [
                ridge_weights(z, y, self.n_weights, self.regularization)
                for z, (_, y) in zip(zs, data, strict=True)
            ]
        )
        mean = ws.mean(axis=0)
        cov = _cov(ws, mean, self.regularization)
        resid = [
            y - (rbf_features(z, self.n_weights) @ w.reshape(dims, -1).T)
            for z, (_, y), w in zip(zs, data, ws, strict=True)
        ]
        noise = max(float(np.mean(np.concatenate(resid) ** 2)), 1e-12)
        if method == "em":
            mean, cov, noise = self._em(zs, [y for _, y in data], mean, cov, noise, n_iter)
        elif method != "ridge":
            raise PrimitiveError(f"ProMP: method must be 'ridge' or 'em', got {method!r}")
        self.mean_, self.cov_, self.noise_, self.dims_ = mean, cov, noise, dims
        self.duration_ = float(np.mean([t[-1] - t[0] for t, _ in data]))
        return self

    def _em(
        self,
        zs: list[FloatArray],
        ys: list[FloatArray],
        mean: FloatArray,
        cov: FloatArray,
        noise: float,
        n_iter: int,
    ) -> tuple[FloatArray, FloatArray, float]:
        dims = ys[0].shape[1]
        phis = [design_matrix(z, self.n_weights, dims) for z in zs]
        obs = [y.T.reshape(-1) for y in ys]
        n_obs = sum(o.size for o in obs)
        for _ in range(n_iter):
            prec = np.linalg.inv(cov)
            ms, ss = [], []
            for ph, o in zip(phis, obs, strict=True):
                s = np.linalg.inv(prec + ph.T @ ph / noise)
                ms.append(s @ (prec @ mean + ph.T @ o / noise))
                ss.append(s)
            m_arr = np.stack(ms)
            mean = m_arr.mean(axis=0)
            cov = _cov(m_arr, mean, self.regularization) + np.mean(ss, axis=0)
            sq = sum(
                float(np.sum((o - ph @ m) ** 2) + np.trace(ph @ s @ ph.T))
                for ph, o, m, s in zip(phis, obs, ms, ss, strict=True)
            )
            noise = max(sq / n_obs, 1e-12)
        return mean, cov, noise

    # --------------------------------------------------------------- queries
    def _phi(self, z: ArrayLike) -> FloatArray:
        return design_matrix(
            np.atleast_1d(np.asarray(z, dtype=np.float64)), self.n_weights, self.dims_
        )

    def mean_trajectory(self, z: ArrayLike) -> FloatArray:
        """Mean at phases ``z`` (n,), shape (n, dims)."""
        za = np.atleast_1d(np.asarray(z, dtype=np.float64))
        return rbf_features(za, self.n_weights) @ self.mean_.reshape(self.dims_, -1).T

    def std_trajectory(self, z: ArrayLike) -> FloatArray:
        """Standard deviation at phases ``z`` (n,), shape (n, dims) (weights' spread only)."""
        za = np.atleast_1d(np.asarray(z, dtype=np.float64))
        ph = self._phi(za)
        var = np.einsum("ij,jk,ik->i", ph, self.cov_, ph)
        return np.sqrt(np.maximum(var, 0.0)).reshape(self.dims_, -1).T

    def sample(
        self, z: ArrayLike, n: int, *, rng: np.random.Generator | int | None = None
    ) -> FloatArray:
        """Trajectories sampled from the weight distribution, shape (n, len(z), dims)."""
        gen = np.random.default_rng(rng)
        w = gen.multivariate_normal(self.mean_, self.cov_, size=n, method="cholesky")
        f = rbf_features(np.atleast_1d(np.asarray(z, dtype=np.float64)), self.n_weights)
        return np.einsum("zk,ndk->nzd", f, w.reshape(n, self.dims_, -1))

    def condition(self, z: float, y: ArrayLike, *, variance: float | ArrayLike = 1e-8) -> ProMP:
        """The ProMP conditioned on passing through ``y`` (dims,) at phase ``z``.

        Start (z = 0), via points and goal (z = 1) alike; ``variance`` is the
        observation variance (scalar or per dimension, units²).
        """
        ya = np.asarray(y, dtype=np.float64).reshape(-1)
        if ya.size != self.dims_ or not np.isfinite(ya).all():
            raise PrimitiveError(f"ProMP condition: expected {self.dims_} finite numbers, got {ya}")
        if not 0.0 <= z <= 1.0:
            raise PrimitiveError(f"ProMP condition: phase must be in [0, 1], got {z}")
        ph = self._phi([z])
        sy = np.diag(np.broadcast_to(np.asarray(variance, dtype=np.float64), (self.dims_,)))
        gain = np.linalg.solve(sy + ph @ self.cov_ @ ph.T, ph @ self.cov_).T
        out = ProMP(self.n_weights, regularization=self.regularization)
        out.mean_ = self.mean_ + gain @ (ya - ph @ self.mean_)
        out.cov_ = self.cov_ - gain @ ph @ self.cov_
        out.cov_ = 0.5 * (out.cov_ + out.cov_.T)
        out.noise_, out.dims_, out.duration_ = self.noise_, self.dims_, self.duration_
        return out


def _cov(ws: FloatArray, mean: FloatArray, reg: float) -> FloatArray:
    d = ws - mean
    cov = d.T @ d / max(len(ws) - 1, 1)
    scale = max(float(np.trace(cov)) / cov.shape[0], 1e-12)
    cov[np.diag_indices_from(cov)] += max(reg, 1e-6) * scale + 1e-12
    return cov
