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

With ``ends=True`` the ``K`` states are the repeated phases of the work, and an
*entry* state (only a stream's first segment) and an *exit* state (only its
last) are added around them: approach, work, withdrawal. The Viterbi takes the
topology as ``−inf`` initial, transition and final weights (``log_final``).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from thirdhand.arrays import FloatArray, IntArray
from thirdhand.primitives.checks import PrimitiveError

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
    log_final: FloatArray | None = None,
) -> tuple[IntArray, float]:
    """Most likely state of every sample under a hidden semi-Markov model.

    ``log p(x, z) = log_init[k_1] + Σ_h (log_dur[k_h, d_h − 1] + Σ_{t ∈ h} log_emit[t, k_h])
    + Σ_{h>1} log_trans[k_{h−1}, k_h] + log_final[k_H]``, segments covering ``0 … T−1``
    exactly.

    Parameters
    ----------
    log_emit : ndarray, shape (T, K)
        Per-sample emission log-likelihoods.
    log_dur : ndarray, shape (K, D)
        ``log p(d | k)`` for ``d = 1 … D`` samples.
    log_trans : ndarray, shape (K, K)
        ``log p(k' → k)``; the diagonal is ignored (no self-transition).
    log_init : ndarray, shape (K,)
    log_final : ndarray, shape (K,), optional
        Log-weight of a path whose last segment is in state ``k`` (``−inf``: a state a
        stream cannot end in); None: every state may end it, at no cost.

    Returns
    -------
    states : ndarray of int, shape (T,)
    score : float
        ``log p(x, z)`` of the returned path.
    """
    t_n, k_n = log_emit.shape
    final = np.zeros(k_n) if log_final is None else np.asarray(log_final, dtype=np.float64)
    if (
        log_dur.shape[0] != k_n
        or log_trans.shape != (k_n, k_n)
        or log_init.shape != (k_n,)
        or final.shape != (k_n,)
    ):
        raise PrimitiveError(
            f"HSMM: emissions for {k_n} states but durations {log_dur.shape}, "
            f"transitions {log_trans.shape}, initial {log_init.shape}, final {final.shape}"
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
    ending = best[t_n] + final
    k = int(np.argmax(ending))
    score = float(ending[k])
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
    log_final: FloatArray | None = None,
) -> float:
    """``log p(x, z)`` of a given labelling (``−inf`` if a run is too long)."""
    st, ln, lab = runs(states)
    total = float(log_init[lab[0]]) + (0.0 if log_final is None else float(log_final[lab[-1]]))
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
    log_final: FloatArray | None = None,
) -> tuple[IntArray, float]:
    """Same as :func:`hsmm_viterbi` by enumerating every labelling of every sample (K^T ≤ 10^6)."""
    t_n, k_n = log_emit.shape
    if k_n**t_n > 1_000_000:
        raise PrimitiveError(f"brute force over {k_n}^{t_n} labellings refused")
    best: tuple[float, tuple[int, ...]] = (-np.inf, ())
    for z in itertools.product(range(k_n), repeat=t_n):
        s = path_score(np.array(z), log_emit, log_dur, log_trans, log_init, log_final)
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


def _ends_of(z: IntArray, open_start: bool = False, open_end: bool = False) -> tuple[int, int]:
    """Samples of a parse's first and last run (its first and last third with < 3 runs);
    0 at an open start or end (a stream cut from a longer one has no entry or exit there)."""
    st, ln, _ = runs(z)
    if st.size >= 3:
        h, e = int(ln[0]), int(ln[-1])
    else:
        h = e = max(z.size // 3, 1)
    return (0 if open_start else h), (0 if open_end else e)


def allowed_moves(k_n: int, ends: bool) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Allowed first states, transitions and last states (1 allowed, 0 not) of ``k_n`` states.

    With ``ends``, state 0 is the entry and state ``k_n - 1`` the exit: every run starts
    in the entry and ends in the exit, visits neither in between, and does not go
    straight from one to the other.

    Returns
    -------
    init : ndarray, shape (k_n,)
    trans : ndarray, shape (k_n, k_n)
    final : ndarray, shape (k_n,)
    """
    if not ends:
        trans = np.ones((k_n, k_n)) - np.eye(k_n) if k_n > 1 else np.ones((1, 1))
        return np.ones(k_n), trans, np.ones(k_n)
    last = k_n - 1
    trans = np.ones((k_n, k_n)) - np.eye(k_n)
    trans[:, 0] = 0.0  # nothing returns to the entry
    trans[last, :] = 0.0  # nothing follows the exit
    trans[0, last] = 0.0  # the work between them is not skipped
    init, final = np.zeros(k_n), np.zeros(k_n)
    init[0], final[last] = 1.0, 1.0
    return init, trans, final


class HiddenSemiMarkov:
    """Hidden semi-Markov model with Gaussian emissions and log-normal durations.

    Parameters
    ----------
    n_states : int
        ``K`` (with :meth:`fit_labelled` it is taken from the labels).
    ends : bool
        Unsupervised only: add an *entry* state that can only be a stream's first
        segment and an *exit* state that can only be its last, around the ``K``
        states that alternate between them (states ``0`` and ``K + 1``; the stream
        must start in the entry and end in the exit, and goes from the entry to one
        of the ``K`` states and from one of them to the exit). A demonstration
        starts by approaching the work and ends by withdrawing from it, once each;
        the work in between is ``K`` phases repeated in any order.
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
    cov_prior_runs : float
        Weight, in runs, of the covariance of all samples as a prior on each state's
        emission covariance: ``Σ_k = (r_k S_k + w S) / (r_k + w)`` with ``r_k`` the
        state's number of runs in the parse. The samples of one run are strongly
        correlated (smoothed, slowly varying channels), so a state seen in one run
        per stream — the entry and exit of ``ends`` — has far fewer independent
        samples than its sample count; without this its Gaussian fits that run's
        particular values and rejects the same phase in another recording. The same
        one pseudo-run shrinks the duration variances. 0: no prior.
    seed : int
        Seeds the k-means initialisation of :meth:`fit_unsupervised`.

    Attributes
    ----------
    states_ : ndarray of int, shape (S,)
        The label each state stands for (the labels given to :meth:`fit_labelled`;
        ``0 … S−1`` unsupervised). ``S = K``, or ``K + 2`` with ``ends``.
    means_ : ndarray, shape (S, C)
    covs_ : ndarray, shape (S, C, C)
    dur_mu_, dur_sd_ : ndarray, shape (S,)
        Log-normal of the duration in samples.
    log_trans_ : ndarray, shape (S, S)
    log_init_, log_final_ : ndarray, shape (S,)
        ``log_final_`` is 0 for a state a stream may end in, ``−inf`` otherwise.
    history_ : list of float
        :meth:`fit_unsupervised`: ``Σ log p(x, z*)`` per round of the restart kept.
    score_ : float
        :meth:`fit_unsupervised`: that restart's final ``Σ log p(x, z*)``.
    """

    def __init__(
        self,
        n_states: int = 3,
        *,
        ends: bool = False,
        max_duration: int | None = None,
        covariance: str = "full",
        reg: float = 1e-2,
        min_log_sd: float = 0.2,
        emission_weight: float = 1.0,
        cov_prior_runs: float = 0.0,
        seed: int = 0,
    ) -> None:
        if cov_prior_runs < 0:
            raise PrimitiveError(f"HSMM covariance prior must be ≥ 0 runs, got {cov_prior_runs}")
        if not 0.0 < emission_weight <= 1.0:
            raise PrimitiveError(f"HSMM emission weight must be in (0, 1], got {emission_weight}")
        self.emission_weight = emission_weight
        if covariance not in ("full", "diag"):
            raise PrimitiveError(f"HSMM covariance must be 'full' or 'diag', got {covariance!r}")
        self.n_states = n_states
        self.ends = ends
        self.max_duration = max_duration
        self.covariance = covariance
        self.reg = reg
        self.min_log_sd = min_log_sd
        self.seed = seed
        self.cov_prior_runs = cov_prior_runs

    # ------------------------------------------------------------ fitting
    def _fit_from(
        self, xs: Sequence[FloatArray], zs: Sequence[IntArray], k_n: int, ends: bool = False
    ) -> None:
        """M-step from state sequences (0 … k_n−1) under the topology ``ends``."""
        x = np.vstack(xs)
        z = np.concatenate(zs)
        c = x.shape[1]
        glob = np.cov(x.T).reshape(c, c) if x.shape[0] > 1 else np.eye(c)
        self.means_ = np.zeros((k_n, c))
        self.covs_ = np.zeros((k_n, c, c))
        n_runs = np.zeros(k_n)
        for zz in zs:
            np.add.at(n_runs, runs(zz)[2], 1.0)
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
                if self.cov_prior_runs > 0:
                    w = self.cov_prior_runs
                    cov = (n_runs[k] * cov + w * glob) / (n_runs[k] + w)
            if self.covariance == "diag":
                cov = np.diag(np.diag(cov))
            self.covs_[k] = cov + self.reg * np.eye(c)
        lens: list[list[float]] = [[] for _ in range(k_n)]
        # Laplace counts on the allowed moves (no self-transition; a single state only starts)
        allow_init, allow_trans, allow_final = allowed_moves(k_n, ends)
        trans, init = allow_trans.copy(), allow_init.copy()
        longest = 1
        for zz in zs:
            _, ln, lab = runs(zz)
            init[lab[0]] += 1
            for a, b in itertools.pairwise(lab):
                trans[a, b] += 1
            for d, k in zip(ln, lab, strict=True):
                lens[k].append(float(np.log(d)))
            longest = max(longest, int(ln.max()))
        trans *= allow_trans > 0
        init *= allow_init > 0
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
        with np.errstate(divide="ignore", invalid="ignore"):
            rows = trans.sum(axis=1, keepdims=True)
            self.log_trans_ = np.log(np.where(rows > 0, trans / np.where(rows > 0, rows, 1), 0.0))
            self.log_init_ = np.log(init / init.sum())
            self.log_final_ = np.log(allow_final)
        self.ends_ = ends

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
        if self.ends:
            raise PrimitiveError(
                "HSMM: entry/exit states (ends) are learned without labels; a label-trained "
                "model takes its states and their order from the labels"
            )
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

    def _hard_em(
        self,
        xa: Sequence[FloatArray],
        zs: list[IntArray],
        k_n: int,
        ends: bool,
        n_iter: int,
        opens: Sequence[tuple[bool, bool]],
    ) -> tuple[list[IntArray], list[float]]:
        """Parse → refit rounds until the parse repeats (at most ``n_iter``)."""
        history: list[float] = []
        for _ in range(n_iter):
            self._fit_from(xa, zs, k_n, ends)
            parsed = [
                self.decode(a, open_start=o, open_end=c)
                for a, (o, c) in zip(xa, opens, strict=True)
            ]
            history.append(sum(s for _, s in parsed))
            new = [p for p, _ in parsed]
            if all(np.array_equal(a, b) for a, b in zip(new, zs, strict=True)):
                break
            zs = new
        self._fit_from(xa, zs, k_n, ends)
        return zs, history

    def fit_unsupervised(
        self,
        xs: Sequence[ArrayLike],
        *,
        n_iter: int = 20,
        n_init: int = 1,
        open_ends: Sequence[tuple[bool, bool]] | None = None,
    ) -> HiddenSemiMarkov:
        """Hard EM (Viterbi training) from k-means initialisations of the samples.

        With ``ends``, each restart first fits the ``K`` states alone (as without
        ``ends``), then takes the first segment of every stream's parse as the entry
        and the last as the exit and continues hard EM under the entry/exit topology
        from two starts — the ``K`` states' parse in between kept, and the ``K``
        states seeded again by k-means on the samples in between only (so that none
        of them stays spent on the approach or withdrawal) — keeping the one with the
        better training score.

        Parameters
        ----------
        xs : sequence of array_like, shape (n_i, C)
        n_iter : int
            At most this many parse → refit rounds per restart (stops when the parse
            repeats).
        n_init : int
            Restarts, each from its own k-means++ seeding (``seed + r``); the one whose
            final parses have the highest ``Σ log p(x, z*)`` on ``xs`` is kept.
        open_ends : sequence of (bool, bool), optional
            Per stream, whether its start and its end are open (see :meth:`decode`):
            a part cut from a longer recording, e.g. a half in cross-validation.
        """
        from scipy.cluster.vq import kmeans2

        if self.n_states < 1:
            raise PrimitiveError(f"HSMM: at least 1 state, got {self.n_states}")
        if n_init < 1:
            raise PrimitiveError(f"HSMM: at least 1 restart, got {n_init}")
        xa = _check_streams(xs)
        opens = [(False, False)] * len(xa) if open_ends is None else list(open_ends)
        if len(opens) != len(xa):
            raise PrimitiveError(f"HSMM: {len(xa)} streams but {len(opens)} open-end flags")
        x = np.vstack(xa)
        if x.shape[0] < self.n_states:
            raise PrimitiveError(f"HSMM: {x.shape[0]} samples for {self.n_states} states")
        if self.ends and min(a.shape[0] for a in xa) < 3:
            raise PrimitiveError("HSMM: entry and exit states need streams of 3 samples or more")
        mu, sd = x.mean(axis=0), x.std(axis=0)
        sd[sd == 0] = 1.0
        split = np.cumsum([a.shape[0] for a in xa])[:-1]
        k_all = self.n_states + 2 if self.ends else self.n_states
        best: tuple[float, dict[str, object]] | None = None
        for r in range(n_init):
            _, lab = kmeans2((x - mu) / sd, self.n_states, minit="++", seed=self.seed + r)
            zs, history = self._hard_em(
                xa, np.split(lab.astype(np.int64), split), self.n_states, False, n_iter, opens
            )
            if self.ends:
                # the first and last run of each stream's parse are the entry and exit; the
                # K states keep their parse between them, and, as a second start, are seeded
                # again by k-means on those samples only (none then stays spent on the
                # approach or withdrawal); the better training score of the two is kept
                cut = [_ends_of(z, o, c) for z, (o, c) in zip(zs, opens, strict=True)]
                inner = np.vstack(
                    [a[h : a.shape[0] - e] for a, (h, e) in zip(xa, cut, strict=True)]
                )
                kept = [z[h : z.size - e] + 1 for z, (h, e) in zip(zs, cut, strict=True)]
                middles = [kept]
                if inner.shape[0] >= self.n_states:
                    _, lab_in = kmeans2(
                        (inner - mu) / sd, self.n_states, minit="++", seed=self.seed + r
                    )
                    sizes = [a.shape[0] - h - e for a, (h, e) in zip(xa, cut, strict=True)]
                    middles.append(np.split(lab_in.astype(np.int64) + 1, np.cumsum(sizes)[:-1]))
                tries = []
                for middle in middles:
                    start = [
                        np.concatenate([np.zeros(h, np.int64), m, np.full(e, k_all - 1, np.int64)])
                        for m, (h, e) in zip(middle, cut, strict=True)
                    ]
                    got, more = self._hard_em(xa, start, k_all, True, n_iter, opens)
                    tries.append((self._total(xa, opens), got, more))
                _, zs, more = max(tries, key=lambda v: v[0])
                self._fit_from(xa, zs, k_all, True)
                history += more
            score = self._total(xa, opens)
            if best is None or score > best[0]:
                state = {k: v for k, v in self.__dict__.items() if k.endswith("_")}
                best = (score, {**state, "history_": history})
        assert best is not None
        self.__dict__.update(best[1])
        self.states_ = np.arange(k_all)
        self.score_ = best[0]
        return self

    def adapt(self, xs: Sequence[ArrayLike], *, n_iter: int = 20) -> HiddenSemiMarkov:
        """Continue hard EM on ``xs``, starting from this fitted model's parses of them.

        Unsupervised adaptation to new recordings: pass the training streams and
        the new ones together; their Viterbi parses under the current parameters
        are the starting state sequences, and parse → refit rounds follow until the
        parses repeat. No label is used, and the states keep their meaning (each
        starts from its own fitted parameters), so a state → label map learned
        before still applies. Every stream is a whole recording (closed ends).

        Parameters
        ----------
        xs : sequence of array_like, shape (n_i, C)
        n_iter : int
            At most this many parse → refit rounds.
        """
        if not hasattr(self, "means_"):
            raise PrimitiveError(
                "HSMM: adapt needs a fitted model (fit_labelled or fit_unsupervised first)"
            )
        xa = _check_streams(xs)
        opens = [(False, False)] * len(xa)
        zs = [self.decode(a)[0] for a in xa]
        zs, history = self._hard_em(xa, zs, self.means_.shape[0], self.ends_, n_iter, opens)
        self.history_ = list(getattr(self, "history_", [])) + history
        self.score_ = self._total(xa, opens)
        return self

    # ------------------------------------------------------------ parsing
    def log_emissions(self, x: ArrayLike) -> FloatArray:
        """Per-sample emission log-likelihood, shape (n, K)."""
        xa = _check_streams([x])[0]
        if xa.shape[1] != self.means_.shape[1]:
            raise PrimitiveError(
                f"HSMM: {xa.shape[1]} channels, the model has {self.means_.shape[1]}"
            )
        out = np.empty((xa.shape[0], self.means_.shape[0]))
        for k in range(self.means_.shape[0]):
            chol = np.linalg.cholesky(self.covs_[k])
            sol = np.linalg.solve(chol, (xa - self.means_[k]).T)
            out[:, k] = -0.5 * (
                np.sum(sol**2, axis=0) + 2.0 * np.sum(np.log(np.diag(chol))) + xa.shape[1] * LOG_2PI
            )
        return out

    def log_durations(self, d_max: int | None = None) -> FloatArray:
        """``log p(d | k)``, shape (S, D): the log-normal discretised on ``d = 1 … D``.

        ``D`` is ``max_duration_`` unless ``d_max`` is given.
        """
        d = np.arange(1, (d_max or self.max_duration_) + 1, dtype=np.float64)
        z = (np.log(d)[None, :] - self.dur_mu_[:, None]) / self.dur_sd_[:, None]
        lp = -0.5 * z**2 - np.log(d)[None, :]
        top = lp.max(axis=1, keepdims=True)
        return lp - top - np.log(np.exp(lp - top).sum(axis=1, keepdims=True))

    def _total(self, xa: Sequence[FloatArray], opens: Sequence[tuple[bool, bool]]) -> float:
        """``Σ log p(x, z*)`` over streams with their open ends."""
        return sum(
            self.decode(a, open_start=o, open_end=c)[1] for a, (o, c) in zip(xa, opens, strict=True)
        )

    def decode(
        self, x: ArrayLike, *, open_start: bool = False, open_end: bool = False
    ) -> tuple[IntArray, float]:
        """Most likely state index (0 … S−1) of every sample, and its ``log p(x, z)``.

        Durations are cut at ``max_duration_`` for speed; a stream that no path can
        cover within it (e.g. entry, one work state and exit, each at most ``D``, on a
        stream longer than ``3 D``) is parsed again with durations up to its length.
        ``open_start`` / ``open_end``: the stream is cut from a longer one there, so
        with ``ends`` it may start in any state but the entry (equally likely) / end
        in any state.
        """
        emit = self.emission_weight * self.log_emissions(x)
        s_n = emit.shape[1]
        init, final = self.log_init_, self.log_final_
        if open_start and self.ends_:
            init = np.full(s_n, -np.log(s_n - 1))
            init[0] = -np.inf
        if open_end:
            final = np.zeros(s_n)
        args = (self.log_trans_, init, final)
        try:
            return hsmm_viterbi(emit, self.log_durations(), *args)
        except PrimitiveError:
            if emit.shape[0] <= self.max_duration_:
                raise
        return hsmm_viterbi(emit, self.log_durations(emit.shape[0]), *args)

    def predict(self, x: ArrayLike) -> IntArray:
        """Most likely label (:attr:`states_`) of every sample, shape (n,)."""
        return self.states_[self.decode(x)[0]]
