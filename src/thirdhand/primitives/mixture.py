"""Mixture of ProMPs over segments, fit by a weighted EM (the parser's inner EM).

Component ``k`` is a ProMP ``w ~ N(μ_k, Σ_k)`` with shared observation noise
``σ²``; a normalised segment ``q`` (samples after the first) has the marginal
likelihood ``N(q | Φ μ_k, Φ Σ_k Φᵀ + σ² I)`` — a density over the segment's own
samples, so segmentations with different numbers of segments explain the same
data and compare fairly. For tracks of two or more dimensions the removed
rotation angle is an extra Gaussian variable per component. Level channels
(:attr:`SegmentStats.lev_sum`), when given, add a per-sample diagonal Gaussian
``N(l_t | m_k, diag v_k)`` on each segment's samples.

Everything is computed from :class:`~thirdhand.primitives.segment_features.SegmentStats`
in the eigenbasis of ``L_kᵀ Φᵀ Φ L_k`` (``Σ_k = L_k L_kᵀ``), where every
segment's posterior covariance is diagonal: no per-segment matrix inverse.
"""

from __future__ import annotations

import numpy as np
from scipy.special import logsumexp

from thirdhand.arrays import FloatArray
from thirdhand.primitives.segment_features import SegmentStats

LOG_2PI = float(np.log(2.0 * np.pi))


class ProMPMixture:
    """Mixture of ProMPs over normalised segments.

    Parameters
    ----------
    n_components : int
    reg : float
        Covariance floor relative to the weights' mean variance.
    noise_floor : float
        Smallest observation variance relative to the segments' mean square.
    covariance : {"full", "diag"}
        Weight covariance of each ProMP. ``"diag"`` keeps skills apart that a full
        covariance could merge (e.g. a move and its mirror image, one amplitude
        direction apart).
    use_angle : bool
        Model the removed rotation angle (2-D and 3-D tracks).
    skill_noise : bool
        One observation variance per component instead of a shared one: a precise
        skill (a reach) then keeps its shape term sharp beside a sloppy one (circles).

    Attributes
    ----------
    weights_ : ndarray, shape (K,)
    means_ : ndarray, shape (K, F)
    covs_ : ndarray, shape (K, F, F)
    noise_ : float
        Observation variance σ², units² (shared; the mean of ``skill_noise_``).
    skill_noise_ : ndarray, shape (K,)
        Per-component observation variance (all equal to ``noise_`` unless ``skill_noise``).
    angle_mean_, angle_var_ : ndarray, shape (K,)
        Radians, radians².
    level_mean_, level_var_ : ndarray, shape (K, L)
        Per-sample Gaussian of the level channels (units, units²).
    """

    def __init__(
        self,
        n_components: int,
        *,
        reg: float = 1e-3,
        noise_floor: float = 1e-4,
        covariance: str = "full",
        use_angle: bool = False,
        skill_noise: bool = False,
    ) -> None:
        self.skill_noise = skill_noise
        self.noise_floor = noise_floor
        self.covariance = covariance
        self.n_components = n_components
        self.reg = reg
        self.use_angle = use_angle

    # ------------------------------------------------------------ init
    def init_kmeanspp(self, st: SegmentStats, w: FloatArray, rng: np.random.Generator) -> None:
        """Weighted k-means++ seeding on the ridge weights; global covariance everywhere."""
        x = st.ridge
        k = self.n_components
        p = w / w.sum()
        idx = [int(rng.choice(len(x), p=p))]
        for _ in range(1, k):
            d2 = np.min(((x[:, None, :] - x[idx][None]) ** 2).sum(-1), axis=1)
            q = p * d2
            q = p if q.sum() <= 0 else q / q.sum()
            idx.append(int(rng.choice(len(x), p=q)))
        self.means_ = x[idx].copy()
        mu = p @ x
        var = p @ (x - mu) ** 2
        self._floor = self.reg * max(float(var.mean()), 1e-12)
        cov = (x - mu).T @ ((x - mu) * p[:, None]) + self._floor * np.eye(x.shape[1])
        self.covs_ = np.repeat(cov[None], k, axis=0)
        self.weights_ = np.full(k, 1.0 / k)
        data_var = max(float(p @ (st.sq / np.maximum(st.n_obs, 1.0))), 1e-300)
        self._noise_floor = max(self.noise_floor * data_var, 1e-14)
        self.noise_ = max(1e-2 * data_var, self._noise_floor)
        self.skill_noise_ = np.full(k, self.noise_)
        ang = st.angle[idx]
        self.angle_mean_ = ang.copy()
        avar = float(p @ (st.angle - p @ st.angle) ** 2)
        self._angle_floor = max(self.reg * avar, 1e-6)
        self.angle_var_ = np.full(k, avar + self._angle_floor)
        n_l = max(float(p @ st.lev_n), 1e-12)
        lm = (p @ st.lev_sum) / n_l
        lv = np.maximum((p @ st.lev_sq) / n_l - lm**2, 0.0)
        self._level_floor = np.maximum(1e-3 * lv, 1e-12)
        denom = np.maximum(st.lev_n[idx], 1.0)[:, None]
        self.level_mean_ = st.lev_sum[idx] / denom
        self.level_var_ = np.repeat((lv + self._level_floor)[None], k, axis=0)

    # ------------------------------------------------------------ core
    def _posterior(
        self, st: SegmentStats, k: int
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """For component k: log marginal likelihood (h,), posterior means (h, F),
        posterior variances in the eigenbasis (h, F) and that basis P (F, F) (S_h = P diag Pᵀ)."""
        chol = np.linalg.cholesky(self.covs_[k])
        lam, v = np.linalg.eigh(chol.T @ st.gram @ chol)
        lam = np.maximum(lam, 0.0)
        basis = chol @ v
        s2 = float(self.skill_noise_[k])
        mu = self.means_[k]
        a_mu = st.gram @ mu
        g = (st.proj - st.scale[:, None] * a_mu[None]) / s2
        rr = st.sq - 2.0 * st.proj @ mu + st.scale * float(mu @ a_mu)
        dvar = 1.0 / (1.0 + st.scale[:, None] * lam[None] / s2)
        hcoef = g @ basis
        quad = rr / s2 - np.sum(hcoef**2 * dvar, axis=1)
        logdet = st.n_obs * np.log(s2) - np.sum(np.log(dvar), axis=1)
        ll = -0.5 * (quad + logdet + st.n_obs * LOG_2PI)
        mean = mu + (hcoef * dvar) @ basis.T
        return ll, mean, dvar, basis

    def log_joint(self, st: SegmentStats) -> FloatArray:
        """``log π_k + log p(segment | k)``, shape (h, K)."""
        out = np.empty((len(st.scale), self.n_components))
        for k in range(self.n_components):
            out[:, k] = self._posterior(st, k)[0]
            if self.use_angle:
                out[:, k] += -0.5 * (
                    (st.angle - self.angle_mean_[k]) ** 2 / self.angle_var_[k]
                    + np.log(self.angle_var_[k])
                    + LOG_2PI
                )
            if st.n_levels:
                m, v = self.level_mean_[k], self.level_var_[k]
                quad = (st.lev_sq - 2.0 * st.lev_sum * m + st.lev_n[:, None] * m**2) / v
                out[:, k] += -0.5 * np.sum(
                    quad + st.lev_n[:, None] * (np.log(v) + LOG_2PI)[None], axis=1
                )
        with np.errstate(divide="ignore"):
            return out + np.log(self.weights_)[None]

    def fit_weighted(
        self, st: SegmentStats, w: FloatArray, *, n_iter: int = 10, tol: float = 1e-7
    ) -> float:
        """EM from the current parameters with per-segment weights ``w`` (h,).

        Returns the final weighted log-likelihood ``Σ_h w_h log p(segment_h)``.
        """
        keep = w > 1e-10
        st, w = st.take(keep), w[keep]
        prev, ll = -np.inf, -np.inf
        for _ in range(n_iter):
            lj = self.log_joint(st)
            lp = logsumexp(lj, axis=1)
            ll = float(w @ lp)
            r = np.exp(lj - lp[:, None]) * w[:, None]
            nk = r.sum(axis=0)
            self.weights_ = np.maximum(nk, 1e-12) / nk.sum()
            resid, n_tot = np.zeros(self.n_components), np.zeros(self.n_components)
            for k in range(self.n_components):
                _, mean, dvar, basis = self._posterior(st, k)
                rk = r[:, k]
                if nk[k] > 1e-9:
                    mu = rk @ mean / nk[k]
                    d = mean - mu
                    spread = basis @ np.diag(rk @ dvar / nk[k]) @ basis.T
                    cov = d.T @ (d * rk[:, None]) / nk[k] + spread
                    if self.covariance == "diag":
                        cov = np.diag(np.diag(cov))
                    self.means_[k] = mu
                    self.covs_[k] = 0.5 * (cov + cov.T) + self._floor * np.eye(cov.shape[0])
                    if self.use_angle:
                        am = rk @ st.angle / nk[k]
                        self.angle_mean_[k] = am
                        self.angle_var_[k] = rk @ (st.angle - am) ** 2 / nk[k] + self._angle_floor
                    if st.n_levels:
                        nl = max(float(rk @ st.lev_n), 1e-12)
                        lm = rk @ st.lev_sum / nl
                        lv = (rk @ st.lev_sq) / nl - lm**2
                        self.level_mean_[k] = lm
                        self.level_var_[k] = np.maximum(lv, 0.0) + self._level_floor
                a_diag = np.einsum("fi,fg,gi->i", basis, st.gram, basis)
                e_sq = (
                    st.sq
                    - 2.0 * np.sum(mean * st.proj, axis=1)
                    + st.scale * (np.einsum("hf,fg,hg->h", mean, st.gram, mean) + dvar @ a_diag)
                )
                resid[k] = float(rk @ e_sq)
                n_tot[k] = float(rk @ st.n_obs)
            self.noise_ = max(resid.sum() / max(n_tot.sum(), 1e-12), self._noise_floor)
            if self.skill_noise:
                per = resid / np.maximum(n_tot, 1e-12)
                self.skill_noise_ = np.where(
                    n_tot > 1e-9, np.maximum(per, self._noise_floor), self.noise_
                )
            else:
                self.skill_noise_ = np.full(self.n_components, self.noise_)
            if abs(ll - prev) <= tol * max(abs(ll), 1.0):
                break
            prev = ll
        return ll
