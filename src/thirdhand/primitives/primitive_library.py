"""The primitive-library parser (Lioutikov, Maeda, Peters, Neumann): segments and skills at once.

Candidate cuts are where the smoothed speed falls under a threshold; they
over-segment, and the parser decides which cuts are real while it learns a
mixture of ProMPs in weight space, ``p(S | θ) = Σ_k π_k N(φ(S) | μ_k, Σ_k)``,
``φ(S)`` being the weights of the segment after linear temporal scaling,
translation to the origin and a rotation about z (the angle kept as a feature).

Outer EM over segmentations: the E-step weights each segmentation ``D_j`` by
``γ_j ∝ Π_{S_h ∈ D_j} p(S_h | θ)`` (uniform prior over the ``2^M`` subsets of
cuts); the M-step needs only the segment marginals ``u_h = Σ_j γ_j [S_h ∈ D_j]``,
computed exactly by forward–backward over the cuts
(:mod:`~thirdhand.primitives.segmentation_dp`), and refits the mixture by a
weighted inner EM (:class:`~thirdhand.primitives.mixture.ProMPMixture`).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import logsumexp

from thirdhand.arrays import FloatArray, IntArray
from thirdhand.primitives.checks import PrimitiveError, check_trajectory
from thirdhand.primitives.mixture import ProMPMixture
from thirdhand.primitives.promp import ProMP
from thirdhand.primitives.segment_features import (
    SegmentStats,
    candidate_cuts,
    segment_stats,
    smoothed_speed,
)
from thirdhand.primitives.segmentation_dp import (
    best_labelled_segmentation,
    best_segmentation,
    segment_marginals,
)


@dataclass(frozen=True)
class Parse:
    """A demonstration parsed into primitives.

    Attributes
    ----------
    bounds : ndarray of int, shape (m + 1,)
        Sample indices of the segment boundaries (first sample, cuts kept, last sample).
    labels : ndarray of int, shape (m,)
        Skill of each segment.
    log_prob : float
        Score of this segmentation and labelling.
    candidates : ndarray of int, shape (M,)
        All candidate cuts that were considered.
    """

    bounds: IntArray
    labels: IntArray
    log_prob: float
    candidates: IntArray

    @property
    def cuts(self) -> IntArray:
        """Kept cuts (sample indices), without the ends."""
        return self.bounds[1:-1]

    def merged(self) -> Parse:
        """Consecutive segments of the same skill as one: a phase of repeated strokes.

        The score is kept (the same segmentation, read one level up).
        """
        if self.labels.size == 0:
            return self
        keep = np.concatenate([[True], self.labels[1:] != self.labels[:-1]])
        bounds = np.concatenate([self.bounds[:-1][keep], self.bounds[-1:]])
        return Parse(bounds, self.labels[keep], self.log_prob, self.candidates)

    def frame_labels(self) -> IntArray:
        """Skill of every sample, shape (bounds[-1] + 1,) (a cut starts its segment)."""
        out = np.repeat(self.labels, np.diff(self.bounds))
        return np.concatenate([out, self.labels[-1:]])


@dataclass
class PreparedTrack:
    y: FloatArray
    levels: FloatArray
    nodes: IntArray
    ia: IntArray
    ib: IntArray
    allowed: NDArray[np.bool_]
    features: SegmentStats
    offset: int
    n_full: int


class PrimitiveLibrary:
    """Learn skills (a mixture of ProMPs) and the segmentation of demonstrations together.

    Parameters
    ----------
    n_skills : int
        Number of mixture components ``K``.
    threshold : float
        Speed under which a candidate cut is placed, units/s.
    window : int
        Moving-average length for the speed, samples.
    n_samples, n_weights : int
        Common length of the temporal scaling; RBFs per dimension.
    min_length : int
        Shortest segment allowed, samples (shorter ones get probability 0).
    reg : float
        Covariance floor, relative to the features' mean variance.
    n_iter, n_inner, n_init : int
        Outer EM iterations, inner EM iterations per outer step, random restarts.
    noise_floor : float
        Smallest observation variance, relative to the segments' mean square: the
        resolution below which two shapes count as the same.
    covariance : {"full", "diag"}
        Covariance of each skill's weights (see :class:`ProMPMixture`). Diagonal by
        default: with a handful of examples per skill (7 per LASA shape) full
        covariances reach a higher likelihood by grouping different shapes, and in
        1-D a full covariance makes a move and its mirror one skill.
    n_reseed : int
        A skill that explains (almost) no segment is moved onto the worst explained
        probable segment, at most this many times per restart.
    grid : float, optional
        Also place a candidate cut every ``grid`` seconds: motions that never stop
        (circles, a wiping phase) give the speed threshold no cut at all.
    trim_rest : bool
        Leave the rest (speed under ``threshold``) at the start and end of a track out
        of the skills: it joins the first and the last segment. A person standing
        still before reaching is not performing a skill, and annotators count that
        wait as part of the reach.
    skill_noise : bool
        One observation noise per skill (see :class:`ProMPMixture`).
    switch_penalty : float
        Log-probability cost of a change of skill between consecutive segments in
        :meth:`parse` (a semi-Markov chain over skills that prefers to stay: a
        prior on how long a phase lasts); 0 scores every segment on its own.
    seed : int
        Seeds the restarts.

    Attributes
    ----------
    mixture_ : ProMPMixture
    log_likelihood_ : float
        ``Σ_tracks log Σ_j Π_h p(S_h | θ)`` at the end.
    history_ : list of float
        The outer EM's log-likelihood per iteration (best restart).
    candidates_ : list of ndarray of int
        Candidate cuts of each training track.
    marginals_ : list of ndarray, shape (M+2, M+2)
        Final segment marginals of each training track.
    """

    def __init__(
        self,
        n_skills: int = 3,
        *,
        threshold: float,
        window: int = 5,
        n_samples: int = 30,
        n_weights: int = 8,
        min_length: int = 4,
        reg: float = 1e-3,
        n_iter: int = 30,
        n_inner: int = 5,
        n_init: int = 8,
        noise_floor: float = 1e-4,
        covariance: str = "diag",
        n_reseed: int = 10,
        grid: float | None = None,
        trim_rest: bool = False,
        skill_noise: bool = False,
        switch_penalty: float = 0.0,
        seed: int = 0,
    ) -> None:
        self.switch_penalty = switch_penalty
        self.skill_noise = skill_noise
        self.grid = grid
        self.trim_rest = trim_rest
        self.noise_floor = noise_floor
        self.covariance = covariance
        self.n_reseed = n_reseed
        self.n_skills = n_skills
        self.threshold = threshold
        self.window = window
        self.n_samples = n_samples
        self.n_weights = n_weights
        self.min_length = min_length
        self.reg = reg
        self.n_iter = n_iter
        self.n_inner = n_inner
        self.n_init = n_init
        self.seed = seed

    # ----------------------------------------------------------------- data
    def prepare(
        self,
        t: ArrayLike,
        y: ArrayLike,
        name: str,
        cuts: IntArray | None = None,
        levels: ArrayLike | None = None,
    ) -> PreparedTrack:
        """A track checked and cut into candidate segments (nodes) with their features.

        Raises
        ------
        PrimitiveError
            If the track is shorter than a speed window and the shortest segment.
        """
        need = max(self.min_length, 3, self.window)
        n_given = int(np.asarray(t).size)
        if n_given < need:
            raise PrimitiveError(
                f"{name}: expected at least {need} samples (one speed window of {self.window} "
                f"and the shortest segment of {self.min_length}), got {n_given}"
            )
        ta, ya = check_trajectory(t, y, name=name, min_samples=need)
        if levels is None or np.asarray(levels).shape == (ta.size, 0):
            la = np.zeros((ta.size, 0))
        else:
            _, la = check_trajectory(ta, levels, name=f"{name} levels", min_samples=need)
        dt = np.diff(ta)
        if dt.max() > 1.01 * dt.min():
            even = np.linspace(ta[0], ta[-1], ta.size)
            ya = np.stack([np.interp(even, ta, col) for col in ya.T], axis=1)
            la = np.stack([np.interp(even, ta, col) for col in la.T], axis=1).reshape(ta.size, -1)
        step = float((ta[-1] - ta[0]) / (ta.size - 1))
        n_full, lo = ya.shape[0], 0
        if self.trim_rest:
            moving = np.flatnonzero(smoothed_speed(ya, step, self.window) >= self.threshold)
            if moving.size and moving[-1] - moving[0] + 1 >= need:
                lo, hi = int(moving[0]), int(moving[-1])
                ya, la = ya[lo : hi + 1], la[lo : hi + 1]
                if cuts is not None:
                    cuts = cuts[(cuts > lo) & (cuts < hi)] - lo
        if cuts is None:
            cuts = candidate_cuts(
                ya, dt=step, threshold=self.threshold, window=self.window, min_gap=self.min_length
            )
            if self.grid is not None:
                every = max(round(self.grid / step), self.min_length)
                cuts = _union_cuts(cuts, np.arange(every, ya.shape[0] - 1, every), self.min_length)
        nodes = np.concatenate([[0], cuts, [ya.shape[0] - 1]]).astype(np.int64)
        ia, ib = np.triu_indices(nodes.size, k=1)
        allowed = (nodes[ib] - nodes[ia] + 1) >= self.min_length
        feats = segment_stats(
            ya,
            nodes[ia],
            nodes[ib],
            n_samples=self.n_samples,
            n_weights=self.n_weights,
            levels=la,
        )
        return PreparedTrack(
            ya, la, nodes, ia.astype(np.int64), ib.astype(np.int64), allowed, feats, lo, n_full
        )

    def segment_scores(
        self, tr: PreparedTrack, mixture: ProMPMixture
    ) -> tuple[FloatArray, FloatArray]:
        """Log-scores of every candidate segment between the track's cut nodes, per skill
        summed out (``mat[i, j]``: nodes i to j; -inf where not allowed), and per skill."""
        lj = mixture.log_joint(tr.features)
        s = np.where(tr.allowed, logsumexp(lj, axis=1), -np.inf)
        n = tr.nodes.size
        mat = np.full((n, n), -np.inf)
        mat[tr.ia, tr.ib] = s
        return mat, lj

    def _e_step(
        self, tracks: list[PreparedTrack], mixture: ProMPMixture
    ) -> tuple[FloatArray, float, list[FloatArray]]:
        us, total, mats = [], 0.0, []
        for tr in tracks:
            mat, _ = self.segment_scores(tr, mixture)
            u, log_z = segment_marginals(mat)
            us.append(u[tr.ia, tr.ib])
            mats.append(u)
            total += log_z
        return np.concatenate(us), total, mats

    # ------------------------------------------------------------------ fit
    def fit(self, tracks: Sequence[tuple[ArrayLike, ...]]) -> PrimitiveLibrary:
        """Learn from demonstrations ``[(t, y), …]``: ``t (n,)`` seconds, ``y (n, dims)``.

        A third element ``levels (n, L)`` per track adds level channels (see
        :class:`~thirdhand.primitives.segment_features.SegmentStats`); all tracks
        must then have the same ``L``.

        Raises
        ------
        PrimitiveError
            For a bad trajectory (named by its index), or fewer possible segments
            than skills.
        """
        if not tracks:
            raise PrimitiveError("primitive library: no demonstration given")
        if self.n_skills < 1:
            raise PrimitiveError(f"primitive library: at least 1 skill, got {self.n_skills}")
        prepared = [
            self.prepare(tr[0], tr[1], f"track {i}", levels=tr[2] if len(tr) > 2 else None)
            for i, tr in enumerate(tracks)
        ]
        dims = {(tr.y.shape[1], tr.levels.shape[1]) for tr in prepared}
        if len(dims) != 1:
            raise PrimitiveError(
                f"primitive library: tracks have different (dimensions, levels) {sorted(dims)}"
            )
        self.dims_, self.n_levels_ = dims.pop()
        x = SegmentStats.concat([tr.features for tr in prepared])
        n_possible = int(sum(tr.allowed.sum() for tr in prepared))
        if n_possible < self.n_skills:
            raise PrimitiveError(
                f"primitive library: {n_possible} possible segments for {self.n_skills} skills "
                "(fewer candidate cuts than skills: lower the threshold or use --skills)"
            )
        prior_u = np.concatenate([segment_marginals(_flat(tr))[0][tr.ia, tr.ib] for tr in prepared])
        best: tuple[float, ProMPMixture, list[float]] | None = None
        rng = np.random.default_rng(self.seed)
        for _ in range(self.n_init):
            mix = ProMPMixture(
                self.n_skills,
                reg=self.reg,
                noise_floor=self.noise_floor,
                covariance=self.covariance,
                use_angle=self.dims_ >= 2,
                skill_noise=self.skill_noise,
            )
            mix.init_kmeanspp(x, prior_u, rng)
            u = prior_u
            hist: list[float] = []
            reseeds = 0
            for _ in range(self.n_iter):
                mix.fit_weighted(x, u, n_iter=self.n_inner)
                u, ll, _ = self._e_step(prepared, mix)
                hist.append(ll)
                if reseeds < self.n_reseed and self._reseed(mix, x, u):
                    reseeds += 1
                    continue
                if len(hist) > 1 and abs(hist[-1] - hist[-2]) < 1e-6 * max(abs(ll), 1.0):
                    break
            if best is None or hist[-1] > best[0]:
                best = (hist[-1], mix, hist)
        assert best is not None
        self.log_likelihood_, self.mixture_, self.history_ = best
        _, _, mats = self._e_step(prepared, self.mixture_)
        self.marginals_ = mats
        self.candidates_ = [tr.nodes[1:-1] + tr.offset for tr in prepared]
        return self

    def score(self, tracks: Sequence[tuple[ArrayLike, ...]]) -> float:
        """Log-likelihood of (new) tracks under the fitted library: held-out model selection.

        ``Σ_tracks log Σ_j Π_{S_h ∈ D_j} p(S_h | θ)`` over every segmentation of each
        track at its candidate cuts (the quantity :meth:`fit` maximises, so a
        library's score on its own training tracks is ``log_likelihood_``).

        Parameters
        ----------
        tracks : sequence of tuple
            As in :meth:`fit`.
        """
        prepared = [
            self.prepare(tr[0], tr[1], f"track {i}", levels=tr[2] if len(tr) > 2 else None)
            for i, tr in enumerate(tracks)
        ]
        return self._e_step(prepared, self.mixture_)[1]

    def n_possible_segments(self, tracks: Sequence[tuple[ArrayLike, ...]]) -> int:
        """Segments the candidate cuts of ``tracks`` allow (``K`` can be at most this).

        Parameters
        ----------
        tracks : sequence of tuple
            As in :meth:`fit`.
        """
        return sum(
            int(
                self.prepare(
                    tr[0], tr[1], f"track {i}", levels=tr[2] if len(tr) > 2 else None
                ).allowed.sum()
            )
            for i, tr in enumerate(tracks)
        )

    @staticmethod
    def _reseed(mix: ProMPMixture, x: SegmentStats, u: FloatArray) -> bool:
        """Move one dead component onto the probable segment explained worst (per sample)."""
        dead = np.flatnonzero(mix.weights_ < 0.01 / mix.n_components)
        if dead.size == 0:
            return False
        fit = logsumexp(mix.log_joint(x), axis=1) / np.maximum(x.n_obs, 1.0)
        worst = int(np.argmin(np.where(u > 0.5, fit, np.inf)))
        if not np.isfinite(fit[worst]) or u[worst] <= 0.5:
            return False
        k = int(dead[0])
        mix.means_[k] = x.ridge[worst]
        mix.covs_[k] = np.mean(mix.covs_, axis=0)
        mix.skill_noise_[k] = mix.noise_
        mix.weights_[k] = 1.0 / mix.n_components
        mix.weights_ /= mix.weights_.sum()
        if mix.use_angle:
            mix.angle_mean_[k] = x.angle[worst]
        if x.n_levels:
            mix.level_mean_[k] = x.lev_sum[worst] / max(float(x.lev_n[worst]), 1.0)
            mix.level_var_[k] = np.mean(mix.level_var_, axis=0)
        return True

    # ---------------------------------------------------------------- parse
    def parse(
        self,
        t: ArrayLike,
        y: ArrayLike,
        *,
        levels: ArrayLike | None = None,
        cuts: ArrayLike | None = None,
        name: str = "track",
    ) -> Parse:
        """Most likely segmentation and skill labels of a (new) demonstration.

        Parameters
        ----------
        t : array_like, shape (n,)
        y : array_like, shape (n, dims)
        levels : array_like, shape (n, L), optional
            Level channels, as in :meth:`fit`.
        cuts : array_like of int, optional
            Candidate cuts to use instead of the speed threshold.
        """
        tr = self.prepare(
            t,
            y,
            name,
            None if cuts is None else np.asarray(cuts, dtype=np.int64),
            levels=levels,
        )
        if (tr.y.shape[1], tr.levels.shape[1]) != (self.dims_, self.n_levels_):
            raise PrimitiveError(
                f"{name}: {tr.y.shape[1]} dimensions and {tr.levels.shape[1]} levels, "
                f"the library has {self.dims_} and {self.n_levels_}"
            )
        lj = self.mixture_.log_joint(tr.features)
        n = tr.nodes.size
        if self.switch_penalty > 0:
            cube = np.full((n, n, lj.shape[1]), -np.inf)
            cube[tr.ia, tr.ib] = np.where(tr.allowed[:, None], lj, -np.inf)
            path, labels_list, score = best_labelled_segmentation(cube, self.switch_penalty)
            labels = np.array(labels_list, dtype=np.int64)
        else:
            mat = np.full((n, n), -np.inf)
            mat[tr.ia, tr.ib] = np.where(tr.allowed, lj.max(axis=1), -np.inf)
            path, score = best_segmentation(mat)
            lab = np.full((n, n), -1, dtype=np.int64)
            lab[tr.ia, tr.ib] = np.argmax(lj, axis=1)
            labels = np.array([lab[a, b] for a, b in itertools.pairwise(path)], dtype=np.int64)
        bounds = tr.nodes[path] + tr.offset
        bounds[0], bounds[-1] = 0, tr.n_full - 1
        return Parse(bounds, labels, score, tr.nodes[1:-1] + tr.offset)

    def skills(self, *, duration: float = 1.0) -> list[ProMP]:
        """Each component as a ProMP over the normalised segment (the angle feature dropped)."""
        nw = self.n_weights * self.dims_
        return [
            ProMP.from_params(m[:nw], c[:nw, :nw], dims=self.dims_, duration=duration)
            for m, c in zip(self.mixture_.means_, self.mixture_.covs_, strict=True)
        ]


def _union_cuts(a: IntArray, b: IntArray, min_gap: int) -> IntArray:
    """Sorted union of two cut lists, dropping a cut closer than ``min_gap`` to the previous."""
    both = np.unique(np.concatenate([a, b]).astype(np.int64))
    out: list[int] = []
    for c in both:
        if not out or c - out[-1] >= min_gap:
            out.append(int(c))
    return np.array(out, dtype=np.int64)


def _flat(tr: PreparedTrack) -> FloatArray:
    n = tr.nodes.size
    mat = np.full((n, n), -np.inf)
    mat[tr.ia, tr.ib] = np.where(tr.allowed, 0.0, -np.inf)
    return mat
