"""A hidden semi-Markov model over per-sample channels: phases with durations.

Each of ``K`` states (a phase, or a skill) emits the samples of its segment
independently from a Gaussian over per-sample channels (forces, torques, speeds
of each arm), lasts a duration drawn from its own discretised log-normal
(``1 … max_duration`` samples), and is followed by another state according to a
transition matrix with no self-transitions (a change of segment is a change of
state). The most likely segmentation and labelling of a stream is found exactly
by the semi-Markov Viterbi recursion (:func:`hsmm_viterbi`, ``O(T · D · K + T ·
K²)``), checked against enumeration of every segmentation × labelling on short
streams (:func:`brute_force_hsmm`).

Two ways to fit it:

- :meth:`HiddenSemiMarkov.fit_labelled` — from human labels (every maximal run
  of one label is a segment): the *label-trained* parse, "label some
  demonstrations, parse the rest". Its states are the human's labels.
- :meth:`HiddenSemiMarkov.fit_unsupervised` — without labels, by hard EM
  (Viterbi training): states initialised by k-means on the samples, then
  parse → refit from the parse → parse, until the parse no longer changes.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from thirdhand.primitives._checks import PrimitiveError

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

LOG_2PI = float(np.log(2.0 * np.pi))


def runs(labels: IntArray) -> tuple[IntArray, IntArray, IntArray]:
    """Maximal runs of one label: starts, lengths and labels, each shape (r,)."""
    lab = np.asarray(labels)
    if lab.size == 0:
        e = np.zeros(0, dtype=np.int64)
        return e, e, e
    change = np.flatnonzero(lab[1:] != lab[:-1]) + 1
    starts = np.concatenate([[0], change]).astype(np.int64)
    ends = np.concatenate([change, [lab.size]]).astype(np.int64)
    return starts, ends - starts, lab[starts].astype(np.int64)


def hsmm_viterbi(
    log_emit: FloatArray,
    log_dur: FloatArray,
    log_trans: FloatArray,
    log_init: FloatArray,
) -> tuple[IntArray, float]:
    """Most likely state of every sample under a hidden semi-Markov model.

    ``log p(x, z) = log_init[k_1] + Σ_h (log_dur[k_h, d_h − 1] + Σ_{t ∈ h} log_emit[t, k_h])
    + Σ_{h>1} log_trans[k_{h−1}, k_h]``, segments covering ``0 … T−1`` exactly.

    Parameters
    ----------
    log_emit : ndarray, shape (T, K)
        Per-sample emission log-likelihoods.
    log_dur : ndarray, shape (K, D)
        ``log p(d | k)`` for ``d = 1 … D`` samples.
    log_trans : ndarray, shape (K, K)
        ``log p(k' → k)``; the diagonal is ignored (no self-transition).
    log_init : ndarray, shape (K,)

    Returns
    -------
    states : ndarray of int, shape (T,)
    score : float
        ``log p(x, z)`` of the returned path.
    """
    t_n, k_n = log_emit.shape
    if log_dur.shape[0] != k_n or log_trans.shape != (k_n, k_n) or log_init.shape != (k_n,):
        raise PrimitiveError(
            f"HSMM: emissions for {k_n} states but durations {log_dur.shape}, "
            f"transitions {log_trans.shape}, initial {log_init.shape}"
        )
    if t_n == 0:
        raise PrimitiveError("HSMM: an empty stream")
    d_n = log_dur.shape[1]
    trans = np.where(np.eye(k_n, dtype=bool), -np.inf, log_trans)
    cum = np.vstack([np.zeros((1, k_n)), np.cumsum(log_emit, axis=0)])
    # entry[s, k]: best score of a path ending at s followed by a segment of k starting at s
    entry = np.full((t_n + 1, k_n), -np.inf)
    entry_from = np.full((t_n + 1, k_n), -1, dtype=np.int64)
    entry[0] = log_init
    best = np.full((t_n + 1, k_n), -np.inf)
    back_d = np.zeros((t_n + 1, k_n), dtype=np.int64)
    cols = np.arange(k_n)
    for e in range(1, t_n + 1):
        d_max = min(d_n, e)
        starts = e - np.arange(1, d_max + 1)  # d = 1 … d_max
        cand = entry[starts] + (cum[e][None, :] - cum[starts]) + log_dur[:, :d_max].T
        j = np.argmax(cand, axis=0)
        best[e] = cand[j, cols]
        back_d[e] = j + 1
        if e < t_n:
            via = best[e][:, None] + trans  # (k', k)
            entry_from[e] = np.argmax(via, axis=0)
            entry[e] = via[entry_from[e], cols]
    k = int(np.argmax(best[t_n]))
    score = float(best[t_n, k])
    if not np.isfinite(score):
        raise PrimitiveError(
            f"HSMM: no labelling of {t_n} samples has a finite score (durations up to {d_n})"
        )
    states = np.empty(t_n, dtype=np.int64)
    e = t_n
    while e > 0:
        d = int(back_d[e, k])
        states[e - d : e] = k
        s = e - d
        if s > 0:
            k = int(entry_from[s, k])
        e = s
    return states, score


def path_score(
    states: IntArray,
    log_emit: FloatArray,
    log_dur: FloatArray,
    log_trans: FloatArray,
    log_init: FloatArray,
) -> float:
    """``log p(x, z)`` of a given labelling (``−inf`` if a run is too long)."""
    st, ln, lab = runs(states)
    total = float(log_init[lab[0]])
    for h, (s, d, k) in enumerate(zip(st, ln, lab, strict=True)):
        if d > log_dur.shape[1]:
            return -np.inf
        total += float(log_dur[k, d - 1]) + float(log_emit[s : s + d, k].sum())
        if h:
            total += float(log_trans[lab[h - 1], k])
    return total


def brute_force_hsmm(
    log_emit: FloatArray,
    log_dur: FloatArray,
    log_trans: FloatArray,
    log_init: FloatArray,
) -> tuple[IntArray, float]:
    """Same as :func:`hsmm_viterbi` by enumerating every labelling of every sample (K^T ≤ 10^6)."""
    t_n, k_n = log_emit.shape
    if k_n**t_n > 1_000_000:
        raise PrimitiveError(f"brute force over {k_n}^{t_n} labellings refused")
    best: tuple[float, tuple[int, ...]] = (-np.inf, ())
    for z in itertools.product(range(k_n), repeat=t_n):
        s = path_score(np.array(z), log_emit, log_dur, log_trans, log_init)
        if s > best[0]:
            best = (s, z)
    return np.array(best[1], dtype=np.int64), best[0]


def _check_streams(xs: Sequence[ArrayLike]) -> list[FloatArray]:
    if not xs:
        raise PrimitiveError("HSMM: no stream given")
    out = []
    for i, x in enumerate(xs):
        a = np.asarray(x, dtype=np.float64)
        if a.ndim == 1:
            a = a[:, None]
        if a.ndim != 2 or a.shape[0] < 1:
            raise PrimitiveError(f"HSMM: stream {i} must be (n, channels), got {a.shape}")
        if not np.isfinite(a).all():
            raise PrimitiveError(f"HSMM: stream {i} has NaN or infinite values")
        out.append(a)
    dims = {a.shape[1] for a in out}
    if len(dims) != 1:
        raise PrimitiveError(f"HSMM: streams have different numbers of channels {sorted(dims)}")
    return out


class HiddenSemiMarkov:
    """Hidden semi-Markov model with Gaussian emissions and log-normal durations.

    Parameters
    ----------
    n_states : int
        ``K`` (with :meth:`fit_labelled` it is taken from the labels).
    max_duration : int or None
        ``D``, samples; None: 1.5 × the longest run seen in fitting.
    covariance : {"full", "diag"}
        Of each state's emission Gaussian.
    reg : float
        Added to every emission variance, channel units².
    min_log_sd : float
        Floor of each duration log-normal's standard deviation (of ``log d``).
    emission_weight : float
        Multiplies the emission log-likelihoods in :meth:`decode` (in ``(0, 1]``):
        ``1 / w`` when every sample is a mean over ``w`` consecutive samples, whose
        evidence would otherwise be counted ``w`` times against the durations.
    seed : int
        Seeds the k-means initialisation of :meth:`fit_unsupervised`.

    Attributes
    ----------
    states_ : ndarray of int, shape (K,)
        The label each state stands for (the labels given to :meth:`fit_labelled`;
        ``0 … K−1`` unsupervised).
    means_ : ndarray, shape (K, C)
    covs_ : ndarray, shape (K, C, C)
    dur_mu_, dur_sd_ : ndarray, shape (K,)
        Log-normal of the duration in samples.
    log_trans_ : ndarray, shape (K, K)
    log_init_ : ndarray, shape (K,)
    history_ : list of float
        :meth:`fit_unsupervised`: ``Σ log p(x, z*)`` per round of the restart kept.
    score_ : float
        :meth:`fit_unsupervised`: that restart's final ``Σ log p(x, z*)``.
    """

    def __init__(
        self,
        n_states: int = 3,
        *,
        max_duration: int | None = None,
        covariance: str = "full",
        reg: float = 1e-2,
        min_log_sd: float = 0.2,
        emission_weight: float = 1.0,
        seed: int = 0,
    ) -> None:
        if not 0.0 < emission_weight <= 1.0:
            raise PrimitiveError(f"HSMM emission weight must be in (0, 1], got {emission_weight}")
        self.emission_weight = emission_weight
        if covariance not in ("full", "diag"):
            raise PrimitiveError(f"HSMM covariance must be 'full' or 'diag', got {covariance!r}")
        self.n_states = n_states
        self.max_duration = max_duration
        self.covariance = covariance
        self.reg = reg
        self.min_log_sd = min_log_sd
        self.seed = seed

    # ------------------------------------------------------------ fitting
    def _fit_from(self, xs: Sequence[FloatArray], zs: Sequence[IntArray], k_n: int) -> None:
        """M-step from state sequences (0 … K−1)."""
        x = np.vstack(xs)
        z = np.concatenate(zs)
        c = x.shape[1]
        glob = np.cov(x.T).reshape(c, c) if x.shape[0] > 1 else np.eye(c)
        self.means_ = np.zeros((k_n, c))
        self.covs_ = np.zeros((k_n, c, c))
        for k in range(k_n):
            xk = x[z == k]
            if xk.shape[0] == 0:
                self.means_[k] = x.mean(axis=0)
                cov = glob
            elif xk.shape[0] == 1:
                self.means_[k] = xk[0]
                cov = glob
            else:
                self.means_[k] = xk.mean(axis=0)
                cov = np.cov(xk.T).reshape(c, c)
            if self.covariance == "diag":
                cov = np.diag(np.diag(cov))
            self.covs_[k] = cov + self.reg * np.eye(c)
        lens: list[list[float]] = [[] for _ in range(k_n)]
        # Laplace counts, no self-transition (a single state only ever starts)
        trans = np.ones((k_n, k_n)) - np.eye(k_n) if k_n > 1 else np.ones((1, 1))
        init = np.ones(k_n)
        longest = 1
        for zz in zs:
            _, ln, lab = runs(zz)
            init[lab[0]] += 1
            for a, b in itertools.pairwise(lab):
                trans[a, b] += 1
            for d, k in zip(ln, lab, strict=True):
                lens[k].append(float(np.log(d)))
            longest = max(longest, int(ln.max()))
        self.max_duration_ = (
            self.max_duration if self.max_duration is not None else int(np.ceil(1.5 * longest))
        )
        allv = [v for ls in lens for v in ls]
        # within-state variance of log d, pooled over the states
        dev = [v - np.mean(ls) for ls in lens if ls for v in ls]
        n_free = len(dev) - sum(1 for ls in lens if ls)
        pooled = float(np.sum(np.square(dev)) / n_free) if n_free > 0 else 1.0
        self.dur_mu_ = np.array([np.mean(ls) if ls else np.mean(allv) for ls in lens])
        # shrink each state's variance towards the pooled one by one pseudo-run
        self.dur_sd_ = np.array(
            [
                max(
                    np.sqrt((np.sum((np.array(ls) - np.mean(ls)) ** 2) + pooled) / (len(ls) + 1))
                    if ls
                    else np.sqrt(pooled),
                    self.min_log_sd,
                )
                for ls in lens
            ]
        )
        with np.errstate(divide="ignore"):
            self.log_trans_ = np.log(trans / trans.sum(axis=1, keepdims=True))
        self.log_init_ = np.log(init / init.sum())

    def fit_labelled(
        self, xs: Sequence[ArrayLike], labels: Sequence[ArrayLike]
    ) -> HiddenSemiMarkov:
        """Fit from per-sample labels: every maximal run of one label is a segment.

        Parameters
        ----------
        xs : sequence of array_like, shape (n_i, C)
            Per-sample channels of each stream.
        labels : sequence of array_like of int, shape (n_i,)
            Any integer labels; the states are the labels present.
        """
        xa = _check_streams(xs)
        if len(labels) != len(xa):
            raise PrimitiveError(f"HSMM: {len(xa)} streams but {len(labels)} label sequences")
        la = []
        for i, (x, lab) in enumerate(zip(xa, labels, strict=True)):
            a = np.asarray(lab)
            if a.shape != (x.shape[0],):
                raise PrimitiveError(
                    f"HSMM: stream {i} has {x.shape[0]} samples but labels of shape {a.shape}"
                )
            la.append(a.astype(np.int64))
        self.states_ = np.unique(np.concatenate(la))
        index = {int(s): i for i, s in enumerate(self.states_)}
        zs = [np.array([index[int(v)] for v in a], dtype=np.int64) for a in la]
        self.n_states = int(self.states_.size)
        self._fit_from(xa, zs, self.n_states)
        return self

    def fit_unsupervised(
        self, xs: Sequence[ArrayLike], *, n_iter: int = 20, n_init: int = 1
    ) -> HiddenSemiMarkov:
        """Hard EM (Viterbi training) from k-means initialisations of the samples.

        Parameters
        ----------
        xs : sequence of array_like, shape (n_i, C)
        n_iter : int
            At most this many parse → refit rounds per restart (stops when the parse
            repeats).
        n_init : int
            Restarts, each from its own k-means++ seeding (``seed + r``); the one whose
            final parses have the highest ``Σ log p(x, z*)`` on ``xs`` is kept.
        """
        from scipy.cluster.vq import kmeans2

        if self.n_states < 1:
            raise PrimitiveError(f"HSMM: at least 1 state, got {self.n_states}")
        if n_init < 1:
            raise PrimitiveError(f"HSMM: at least 1 restart, got {n_init}")
        xa = _check_streams(xs)
        x = np.vstack(xa)
        if x.shape[0] < self.n_states:
            raise PrimitiveError(f"HSMM: {x.shape[0]} samples for {self.n_states} states")
        mu, sd = x.mean(axis=0), x.std(axis=0)
        sd[sd == 0] = 1.0
        split = np.cumsum([a.shape[0] for a in xa])[:-1]
        self.states_ = np.arange(self.n_states)
        best: tuple[float, dict[str, object]] | None = None
        for r in range(n_init):
            _, lab = kmeans2((x - mu) / sd, self.n_states, minit="++", seed=self.seed + r)
            zs = np.split(lab.astype(np.int64), split)
            history: list[float] = []
            for _ in range(n_iter):
                self._fit_from(xa, zs, self.n_states)
                parsed = [self.decode(a) for a in xa]
                history.append(sum(s for _, s in parsed))
                new = [p for p, _ in parsed]
                if all(np.array_equal(a, b) for a, b in zip(new, zs, strict=True)):
                    break
                zs = new
            self._fit_from(xa, zs, self.n_states)
            score = sum(self.decode(a)[1] for a in xa)
            if best is None or score > best[0]:
                state = {k: v for k, v in self.__dict__.items() if k.endswith("_")}
                best = (score, {**state, "history_": history})
        assert best is not None
        self.__dict__.update(best[1])
        self.score_ = best[0]
        return self

    # ------------------------------------------------------------ parsing
    def log_emissions(self, x: ArrayLike) -> FloatArray:
        """Per-sample emission log-likelihood, shape (n, K)."""
        xa = _check_streams([x])[0]
        if xa.shape[1] != self.means_.shape[1]:
            raise PrimitiveError(
                f"HSMM: {xa.shape[1]} channels, the model has {self.means_.shape[1]}"
            )
        out = np.empty((xa.shape[0], self.n_states))
        for k in range(self.n_states):
            chol = np.linalg.cholesky(self.covs_[k])
            sol = np.linalg.solve(chol, (xa - self.means_[k]).T)
            out[:, k] = -0.5 * (
                np.sum(sol**2, axis=0) + 2.0 * np.sum(np.log(np.diag(chol))) + xa.shape[1] * LOG_2PI
            )
        return out

    def log_durations(self) -> FloatArray:
        """``log p(d | k)``, shape (K, D): the log-normal discretised on ``d = 1 … D``."""
        d = np.arange(1, self.max_duration_ + 1, dtype=np.float64)
        z = (np.log(d)[None, :] - self.dur_mu_[:, None]) / self.dur_sd_[:, None]
        lp = -0.5 * z**2 - np.log(d)[None, :]
        top = lp.max(axis=1, keepdims=True)
        return lp - top - np.log(np.exp(lp - top).sum(axis=1, keepdims=True))

    def decode(self, x: ArrayLike) -> tuple[IntArray, float]:
        """Most likely state index (0 … K−1) of every sample, and its ``log p(x, z)``."""
        return hsmm_viterbi(
            self.emission_weight * self.log_emissions(x),
            self.log_durations(),
            self.log_trans_,
            self.log_init_,
        )

    def predict(self, x: ArrayLike) -> IntArray:
        """Most likely label (:attr:`states_`) of every sample, shape (n,)."""
        return self.states_[self.decode(x)[0]]
