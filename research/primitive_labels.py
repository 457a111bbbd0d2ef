"""The primitive-library parser against a human's phase labels, leave one recording out.

For each recording of a file the library is fitted on the others (on the
recording itself when the file holds only one, reported as in-sample), the
recording is parsed, consecutive segments of the same skill are merged into one
run (:meth:`~thirdhand.primitives.primitive_library.Parse.merged`), optionally runs are
grouped into phases (:class:`~thirdhand.primitives.phases.PhaseGrouper`, learned
on the training recordings' parses), and the result is compared with the labels
(:mod:`~research.primitive_scores`): boundary precision / recall / F1
within a tolerance, and frame accuracy under the best one-to-one map from
predicted to human labels — one map per held-out recording, since each is
parsed by its own library whose skill numbers mean nothing to another fold's
(the single map over all recordings is reported beside it).
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from research.primitive_channels import stream_channels
from research.primitive_scores import (
    BoundaryScore,
    apply_map,
    best_label_map,
    change_times,
    match_boundaries,
)
from thirdhand.arrays import IntArray
from thirdhand.io.figueroa import LabelledStream
from thirdhand.primitives.checks import PrimitiveError
from thirdhand.primitives.hsmm import HiddenSemiMarkov
from thirdhand.primitives.phases import PhaseGrouper, run_descriptors
from thirdhand.primitives.primitive_library import PrimitiveLibrary
from thirdhand.primitives.segment_features import smoothed_speed

#: How K is selected without ``--skills`` (see :class:`ParserConfig`).
SELECTIONS = ("onese", "heldout", "bic")
#: Models of :func:`evaluate_streams` (see :class:`ParserConfig`).
MODELS = ("library", "hsmm")


@dataclass(frozen=True)
class ParserConfig:
    """Settings of the parser on labelled recordings.

    Attributes
    ----------
    shape, levels : tuple of str
        Channels (:func:`~research.primitive_channels.stream_channels`).
    arms : tuple of int or None
        Arms used (None: all).
    n_skills : int or None
        ``K``; None selects it over ``k_range`` on the training recordings (``select``).
    k_range : tuple of int
    select : {"onese", "heldout", "bic"}
        How ``K`` is selected when not given, from the held-out log-likelihood
        (:func:`heldout_folds`: each training recording scored by a library fitted on
        the other training recordings, or each half of a single training recording by
        the other half): ``onese`` (default) the smallest K within one standard error
        of the best (:func:`one_se_choice`), ``heldout`` the best; or ``bic`` the
        lowest BIC of the library fitted on all of them. All tables are computed
        either way.
    subsample : int
        Keep every n-th sample (the parse is mapped back to every sample).
    grid : float or None
        Extra candidate cuts every ``grid`` seconds.
    threshold : float or None
        Speed threshold of the candidate cuts, channel units/s; default 5 % of
        the median peak smoothed speed of the training recordings.
    window : int
        Speed smoothing, samples (after subsampling).
    trim_rest : bool
    n_phases : int or None
        Group runs of skills into this many phases (None: every run of a skill is a phase).
    switch_penalty : float
        Cost of a change of skill in the parse, nats (see :class:`PrimitiveLibrary`).
    n_init : int
        Restarts of the library's EM, and of the HSMM's hard EM (the best training
        score is kept).
    seed : int
    model : {"library", "hsmm"}
        ``library``: the primitive-library parser (ProMP skills over candidate
        segments); ``hsmm``: a hidden semi-Markov model over the per-sample level
        channels (:class:`~thirdhand.primitives.hsmm.HiddenSemiMarkov`, fitted without
        labels by hard EM; ``n_skills`` states).
    label_trained : bool
        Fit the HSMM on the training recordings' human labels (its states are the
        labels) instead of without them: the supervised "label some, parse the
        rest" mode, reported apart from the unsupervised figures.
    zero_ft : bool
        Subtract each arm's force/torque at the start of the recording
        (:func:`~research.primitive_channels.stream_channels`).
    ends : bool
        Unsupervised HSMM: an entry state only at the start of a recording and an exit
        state only at its end around the ``n_skills`` states
        (:class:`~thirdhand.primitives.hsmm.HiddenSemiMarkov` ``ends``).
    normalise : {"none", "scale", "zscore"}
        Level channels per recording: as they are, divided by that recording's
        standard deviation of each channel, or also centred on its median.
    adapt : bool
        HSMM: after fitting on the training recordings, continue hard EM on them
        together with the recording to parse (its samples, never its labels;
        :meth:`~thirdhand.primitives.hsmm.HiddenSemiMarkov.adapt`). Transductive:
        the parsed recording is then part of the fit, which strict leave-one-out
        excludes, so its figures are reported apart.
    """

    shape: tuple[str, ...] = ("pos",)
    levels: tuple[str, ...] = ("force",)
    arms: tuple[int, ...] | None = None
    n_skills: int | None = 3
    k_range: tuple[int, ...] = (2, 3, 4, 5, 6)
    select: str = "onese"
    subsample: int = 5
    grid: float | None = 0.5
    threshold: float | None = None
    window: int = 5
    trim_rest: bool = False
    n_phases: int | None = None
    switch_penalty: float = 0.0
    n_init: int = 4
    seed: int = 0
    model: str = "library"
    label_trained: bool = False
    zero_ft: bool = False
    ends: bool = False
    normalise: str = "none"
    adapt: bool = False


@dataclass(frozen=True)
class KSelection:
    """How ``K`` was chosen on one fold's training recordings.

    Attributes
    ----------
    bic : dict of int to float
        K → BIC of the library fitted on all training recordings.
    heldout : dict of int to float
        K → held-out log-likelihood per scalar observation (:func:`heldout_scores`).
    chosen : int
    folds : dict of int to list of (float, int)
        K → per fold (log-likelihood, observations) (:func:`heldout_folds`).
    """

    bic: dict[int, float]
    heldout: dict[int, float]
    chosen: int
    folds: dict[int, list[tuple[float, int]]] = field(default_factory=dict)


@dataclass(frozen=True)
class StreamResult:
    """One held-out recording.

    Attributes
    ----------
    name : str
    n_samples : int
    skills : ndarray of int, shape (n_samples,)
        Skill per sample after merging.
    boundaries : BoundaryScore
        Changes of skill (consecutive segments of one skill merged).
    raw_boundaries : BoundaryScore
        Every kept cut, unmerged (the seed parser's output).
    accuracy : float
        Under this recording's best map.
    global_accuracy : float
        Under the file's single best map (filled in after all recordings are parsed).
    n_candidates, n_segments, n_phases : int
    n_skills : int
        ``K`` used for this recording's library.
    in_sample : bool
    fit_s : float
    selection : KSelection or None
        How K was chosen on this recording's training recordings (None: K given).
    named_accuracy : float or None
        Label-trained parses only: frame accuracy with the predicted labels taken
        as they are named (no map).
    """

    name: str
    n_samples: int
    skills: IntArray
    boundaries: BoundaryScore
    raw_boundaries: BoundaryScore
    accuracy: float
    global_accuracy: float
    n_candidates: int
    n_segments: int
    n_phases: int
    n_skills: int
    in_sample: bool
    fit_s: float
    selection: KSelection | None = None
    named_accuracy: float | None = None


@dataclass(frozen=True)
class FileResult:
    """All recordings of one file.

    Attributes
    ----------
    streams : list of StreamResult
    accuracy : float
        Frame accuracy over all samples, each recording under its own best map.
    global_accuracy : float
        Frame accuracy over all samples under ``mapping``.
    boundaries : BoundaryScore
        Summed over the recordings.
    raw_boundaries : BoundaryScore
        Every kept cut, summed over the recordings.
    mapping : dict
        Skill → human label.
    bic : dict
        K → BIC of the library fitted on the last fold's training recordings (empty
        with a fixed K).
    heldout : dict
        K → held-out log-likelihood per scalar observation, same fold (empty with a fixed K).
    """

    streams: list[StreamResult]
    accuracy: float
    global_accuracy: float
    boundaries: BoundaryScore
    raw_boundaries: BoundaryScore
    mapping: dict[int, int]
    bic: dict[int, float] = field(default_factory=dict)
    heldout: dict[int, float] = field(default_factory=dict)


def n_parameters(lib: PrimitiveLibrary) -> int:
    """Free parameters of a fitted library (for BIC)."""
    mix = lib.mixture_
    f = mix.means_.shape[1]
    per = f + (f if lib.covariance == "diag" else f * (f + 1) // 2)
    per += 2 if mix.use_angle else 0
    per += 2 * lib.n_levels_
    return mix.n_components * per + (mix.n_components - 1) + 1


def bic(lib: PrimitiveLibrary, n_obs: int) -> float:
    """``−2 log L + p log n``, ``n`` scalar observations."""
    return -2.0 * lib.log_likelihood_ + n_parameters(lib) * float(np.log(max(n_obs, 2)))


def _tracks(
    streams: Sequence[LabelledStream], cfg: ParserConfig
) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    out = []
    for s in streams:
        y, lev = stream_channels(
            s,
            shape=cfg.shape,
            levels=cfg.levels,
            arms=cfg.arms,
            window=cfg.window * cfg.subsample,
            zero_ft=cfg.zero_ft,
        )
        k = cfg.subsample
        out.append((s.t[::k], y[::k], normalise_levels(lev[::k], cfg.normalise)))
    return out


#: Per-recording normalisations of the level channels (see :class:`ParserConfig`).
NORMALISATIONS = ("none", "scale", "zscore")


def normalise_levels(lev: np.ndarray, how: str) -> np.ndarray:
    """Level channels of one recording divided by their spread (and centred on their median).

    Parameters
    ----------
    lev : ndarray, shape (n, L)
    how : {"none", "scale", "zscore"}

    Returns
    -------
    ndarray, shape (n, L)
        A new array; a constant channel is left unscaled.
    """
    if how not in NORMALISATIONS:
        raise PrimitiveError(
            f"normalisation must be one of {', '.join(NORMALISATIONS)}, got {how!r}"
        )
    if how == "none" or lev.shape[0] == 0:
        return lev.copy()
    sd = lev.std(axis=0)
    sd[sd == 0] = 1.0
    centre = np.median(lev, axis=0) if how == "zscore" else 0.0
    return np.asarray((lev - centre) / sd, dtype=np.float64)


def _threshold(tracks: Sequence[tuple[np.ndarray, ...]], cfg: ParserConfig) -> float:
    if cfg.threshold is not None:
        return cfg.threshold
    peaks = [
        smoothed_speed(y, float(np.median(np.diff(t))), cfg.window).max() for t, y, _ in tracks
    ]
    return 0.05 * float(np.median(peaks))


def _make_library(k: int, thr: float, cfg: ParserConfig) -> PrimitiveLibrary:
    return PrimitiveLibrary(
        k,
        threshold=thr,
        window=cfg.window,
        grid=cfg.grid,
        trim_rest=cfg.trim_rest,
        switch_penalty=cfg.switch_penalty,
        n_init=cfg.n_init,
        seed=cfg.seed,
    )


def _halves(
    track: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    t, y, lev = track
    h = t.size // 2
    return [(t[:h], y[:h], lev[:h]), (t[h:], y[h:], lev[h:])]


def heldout_folds(
    tracks: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]],
    cfg: ParserConfig,
    k_range: Sequence[int],
    threshold: float,
) -> dict[int, list[tuple[float, int]]]:
    """Held-out log-likelihood of each K on each cross-validation fold.

    Each track is scored (:meth:`PrimitiveLibrary.score`) by a library fitted on
    the other tracks; a single track is cut in two halves in time, each scored
    by a library fitted on the other. The candidate cuts use ``threshold`` (the
    one of the final fit), so every K is scored on the same segmentations.

    Returns
    -------
    dict of int to list of (float, int)
        K → per fold ``(log p(held-out | θ_K), n)``, ``n`` scalar observations held
        out; K that cannot be fitted on some fold are left out.
    """
    folds = list(tracks) if len(tracks) > 1 else _halves(tracks[0])

    def score(k: int, train: list[Any], held: Any) -> tuple[float, int]:
        fitted = _make_library(k, threshold, cfg).fit(train)
        return fitted.score([held]), int(held[1].size + held[2].size)

    return _cross_validate(folds, k_range, score)


def _cross_validate(
    folds: Sequence[Any],
    k_range: Sequence[int],
    score: Callable[[int, list[Any], Any], tuple[float, int]],
) -> dict[int, list[tuple[float, int]]]:
    """K → per fold ``score(k, the other folds, the fold)``; K that fail to fit left out."""
    out: dict[int, list[tuple[float, int]]] = {}
    for k in k_range:
        per: list[tuple[float, int]] = []
        try:
            for i, held in enumerate(folds):
                per.append(score(k, [f for j, f in enumerate(folds) if j != i], held))
        except PrimitiveError:
            continue
        out[k] = per
    return out


def per_observation(folds: dict[int, list[tuple[float, int]]]) -> dict[int, float]:
    """K → ``Σ_folds log p / Σ_folds n``: the held-out log-likelihood per scalar observation."""
    return {k: sum(s for s, _ in v) / sum(n for _, n in v) for k, v in folds.items()}


def one_se_choice(folds: dict[int, list[tuple[float, int]]]) -> int:
    """The smallest K whose held-out score is within one standard error of the best.

    The one-standard-error rule of cross-validation (Breiman et al. 1984; Hastie,
    Tibshirani & Friedman, *Elements of Statistical Learning* §7.10): the best
    K's score is an estimate with an error, the spread of its per-fold scores
    (per observation) over ``√folds``; a K with fewer skills whose score lies
    within that error of the best is not distinguishable from it, and the
    simpler model is kept. With one fold there is no spread: the best K.

    Parameters
    ----------
    folds : dict of int to list of (float, int)
        As returned by :func:`heldout_folds`.
    """
    if not folds:
        raise PrimitiveError("one-SE rule: no K was scored")
    mean = per_observation(folds)
    best = max(mean, key=lambda k: mean[k])
    per = np.array([s / n for s, n in folds[best]])
    se = float(per.std(ddof=1) / np.sqrt(per.size)) if per.size > 1 else 0.0
    return min(k for k in mean if mean[k] >= mean[best] - se)


def heldout_scores(
    tracks: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]],
    cfg: ParserConfig,
    k_range: Sequence[int],
    threshold: float,
) -> dict[int, float]:
    """Held-out log-likelihood per scalar observation of each K (:func:`heldout_folds`).

    Returns
    -------
    dict of int to float
        K → ``Σ_folds log p(held-out | θ_K) / n``, ``n`` scalar observations held out;
        K that cannot be fitted on some fold are left out.
    """
    return per_observation(heldout_folds(tracks, cfg, k_range, threshold))


def fit_library(
    tracks: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]], cfg: ParserConfig
) -> tuple[PrimitiveLibrary, KSelection | None]:
    """Fit with ``cfg.n_skills``, or with the K selected over ``cfg.k_range`` (``cfg.select``).

    Returns
    -------
    library : PrimitiveLibrary
    selection : KSelection or None
        None when ``cfg.n_skills`` is given.
    """
    if cfg.select not in SELECTIONS:
        raise PrimitiveError(f"K selection must be 'onese', 'heldout' or 'bic', got {cfg.select!r}")
    thr = _threshold(tracks, cfg)
    if cfg.n_skills is not None:
        return _make_library(cfg.n_skills, thr, cfg).fit(list(tracks)), None
    n_obs = sum(y.size + lev.size for _, y, lev in tracks)
    libs: dict[int, PrimitiveLibrary] = {}
    scores: dict[int, float] = {}
    for k in cfg.k_range:
        try:
            libs[k] = _make_library(k, thr, cfg).fit(list(tracks))
        except PrimitiveError:
            if not libs:
                raise
            break
        scores[k] = bic(libs[k], n_obs)
    if not libs:
        raise PrimitiveError(f"no K in {list(cfg.k_range)} could be fitted")
    per_fold = heldout_folds(tracks, cfg, list(libs), thr)
    held = per_observation(per_fold)
    if cfg.select == "onese" and held:
        chosen = one_se_choice(per_fold)
    elif cfg.select == "heldout" and held:
        chosen = max(held, key=lambda k: held[k])
    else:
        chosen = min(scores, key=lambda k: scores[k])
    return libs[chosen], KSelection(scores, held, chosen, per_fold)


def evaluate_streams(
    streams: Sequence[LabelledStream], cfg: ParserConfig, *, tolerance: float = 1.0
) -> FileResult:
    """Leave-one-recording-out parse of every recording, scored against its labels."""
    if not streams:
        raise PrimitiveError("no labelled recording to evaluate")
    if cfg.model not in MODELS:
        raise PrimitiveError(f"model must be one of {', '.join(MODELS)}, got {cfg.model!r}")
    if cfg.model == "hsmm" or cfg.label_trained:
        return _finish(_hsmm_results(streams, cfg, tolerance), streams)
    tracks = _tracks(streams, cfg)
    results: list[StreamResult] = []
    for i, (s, (t, y, lev)) in enumerate(zip(streams, tracks, strict=True)):
        train = [tr for j, tr in enumerate(tracks) if j != i] or [tracks[i]]
        t0 = time.perf_counter()
        lib, selection = fit_library(train, cfg)
        raw = lib.parse(t, y, levels=lev, name=s.name)
        parse = raw.merged()
        if cfg.n_phases is not None:
            parse = _phase_grouper(lib, train, cfg).group(y, parse)
        fit_s = time.perf_counter() - t0
        sub = parse.frame_labels()
        idx = np.clip(np.searchsorted(t, s.t, side="right") - 1, 0, t.size - 1)
        skills = sub[idx]
        results.append(
            StreamResult(
                s.name,
                s.n_samples,
                skills,
                match_boundaries(s.boundaries, change_times(s.t, skills), tolerance=tolerance),
                match_boundaries(s.boundaries, t[raw.cuts], tolerance=tolerance),
                float(best_label_map([skills], [s.labels])[1] / s.n_samples),
                float("nan"),
                int(raw.candidates.size),
                int(raw.labels.size),
                int(parse.labels.size),
                int(lib.n_skills),
                len(streams) == 1,
                fit_s,
                selection,
            )
        )
    return _finish(results, streams)


def _finish(results: list[StreamResult], streams: Sequence[LabelledStream]) -> FileResult:
    """The file's single map, global accuracies and summed boundary scores."""
    mapping, n_ok, n_all = best_label_map([r.skills for r in results], [s.labels for s in streams])
    final = []
    for r, s in zip(results, streams, strict=True):
        acc = float(np.mean(apply_map(r.skills, mapping) == s.labels))
        final.append(StreamResult(**{**r.__dict__, "global_accuracy": acc}))
    per_map = sum(r.accuracy * r.n_samples for r in final) / n_all
    total, raw_total = final[0].boundaries, final[0].raw_boundaries
    for r in final[1:]:
        total, raw_total = total + r.boundaries, raw_total + r.raw_boundaries
    last = next((r.selection for r in reversed(final) if r.selection is not None), None)
    bic_table = {} if last is None else last.bic
    held_table = {} if last is None else last.heldout
    return FileResult(
        final, per_map, n_ok / n_all, total, raw_total, mapping, bic_table, held_table
    )


def _make_hsmm(k: int, cfg: ParserConfig) -> HiddenSemiMarkov:
    # each parse sample's level is a mean over ``window`` parse samples: its
    # evidence is shared with that many neighbours and counted once
    ends = cfg.ends and not cfg.label_trained
    return HiddenSemiMarkov(
        k,
        ends=ends,
        emission_weight=1.0 / max(cfg.window, 1),
        # the entry and exit are one run per recording: their covariances need the prior
        cov_prior_runs=1.0 if ends else 0.0,
        seed=cfg.seed,
    )


def hsmm_heldout_folds(
    xs: Sequence[np.ndarray], cfg: ParserConfig, k_range: Sequence[int]
) -> dict[int, list[tuple[float, int]]]:
    """Held-out score of each number of HSMM states on each fold (as :func:`heldout_folds`).

    The score of a held-out stream is ``log p(x, z*)`` of its best parse
    (:meth:`HiddenSemiMarkov.decode`) under a model fitted without labels on the
    other folds; a single stream is cut in two halves, the first with an open end
    and the second with an open start (no exit / no entry with ``ends``).
    """
    if len(xs) > 1:
        folds = [(x, (False, False)) for x in xs]
    else:
        h = len(xs[0]) // 2
        # a half is a prefix (its end open) or a suffix (its start open): with entry and
        # exit states it has only one of them
        folds = [(xs[0][:h], (False, True)), (xs[0][h:], (True, False))]

    def score(k: int, train: list[Any], held: Any) -> tuple[float, int]:
        model = _make_hsmm(k, cfg).fit_unsupervised(
            [x for x, _ in train], n_init=cfg.n_init, open_ends=[o for _, o in train]
        )
        x, (o, c) = held
        return model.decode(x, open_start=o, open_end=c)[1], int(x.size)

    return _cross_validate(folds, k_range, score)


def _hsmm_results(
    streams: Sequence[LabelledStream], cfg: ParserConfig, tolerance: float
) -> list[StreamResult]:
    """Leave-one-recording-out HSMM parses, unsupervised or label-trained."""
    tracks = _tracks(streams, cfg)
    for s, (_, _, lev) in zip(streams, tracks, strict=True):
        if lev.shape[1] == 0:
            raise PrimitiveError(f"{s.name}: the HSMM needs level channels (--levels)")
    sub_labels = [s.labels[:: cfg.subsample] for s in streams]
    results: list[StreamResult] = []
    for i, (s, (t, _, lev)) in enumerate(zip(streams, tracks, strict=True)):
        train = [j for j in range(len(streams)) if j != i] or [i]
        t0 = time.perf_counter()
        selection = None
        if cfg.label_trained:
            model = _make_hsmm(1, cfg).fit_labelled(
                [tracks[j][2] for j in train], [sub_labels[j] for j in train]
            )
        elif cfg.n_skills is not None:
            model = _make_hsmm(cfg.n_skills, cfg).fit_unsupervised(
                [tracks[j][2] for j in train], n_init=cfg.n_init
            )
        else:
            per_fold = hsmm_heldout_folds([tracks[j][2] for j in train], cfg, cfg.k_range)
            if not per_fold:
                raise PrimitiveError(f"no number of states in {list(cfg.k_range)} could be fitted")
            held = per_observation(per_fold)
            chosen = (
                one_se_choice(per_fold)
                if cfg.select == "onese"
                else max(held, key=lambda k: held[k])
            )
            model = _make_hsmm(chosen, cfg).fit_unsupervised(
                [tracks[j][2] for j in train], n_init=cfg.n_init
            )
            selection = KSelection({}, held, chosen, per_fold)
        if cfg.adapt:
            model.adapt([tracks[j][2] for j in train if j != i] + [lev])
        sub = model.predict(lev)
        fit_s = time.perf_counter() - t0
        idx = np.clip(np.searchsorted(t, s.t, side="right") - 1, 0, t.size - 1)
        pred = sub[idx]
        n_runs = int(np.count_nonzero(np.diff(pred)) + 1)
        results.append(
            StreamResult(
                s.name,
                s.n_samples,
                pred,
                match_boundaries(s.boundaries, change_times(s.t, pred), tolerance=tolerance),
                match_boundaries(s.boundaries, change_times(s.t, pred), tolerance=tolerance),
                float(best_label_map([pred], [s.labels])[1] / s.n_samples),
                float("nan"),
                0,
                n_runs,
                n_runs,
                int(model.n_states),
                len(streams) == 1,
                fit_s,
                selection,
                float(np.mean(pred == s.labels)) if cfg.label_trained else None,
            )
        )
    return results


def _phase_grouper(
    lib: PrimitiveLibrary,
    train: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]],
    cfg: ParserConfig,
) -> PhaseGrouper:
    assert cfg.n_phases is not None
    descs, lens = [], []
    for t, y, lev in train:
        d, w = run_descriptors(y, lib.parse(t, y, levels=lev).merged(), lib.n_skills)
        descs.append(d)
        lens.append(w)
    return PhaseGrouper(cfg.n_phases, n_skills=lib.n_skills, seed=cfg.seed).fit(descs, lens)


def cluster_segments(
    features: Sequence[np.ndarray],
    bounds: Sequence[np.ndarray],
    n_clusters: int,
    *,
    seed: int = 0,
) -> list[IntArray]:
    """Per-sample cluster labels of segments, for methods that only give change points.

    Each segment is represented by the mean of its samples' features (each
    column standardised over all recordings) and the segments of all recordings
    are grouped by k-means (k-means++ seeding, best of 10, weighted by length),
    so that a change-point method gets a frame accuracy under the same
    Hungarian map as the parser.

    Parameters
    ----------
    features : sequence of ndarray, shape (n_i, d)
    bounds : sequence of ndarray of int
        Per recording, ``[0, cut_1, …, n_i − 1]``.
    n_clusters : int

    Returns
    -------
    list of ndarray of int, shape (n_i,)
    """
    from scipy.cluster.vq import kmeans2

    allx = np.vstack(features)
    mu, sd = allx.mean(axis=0), allx.std(axis=0)
    sd[sd == 0] = 1.0
    means, lens = [], []
    for x, b in zip(features, bounds, strict=True):
        z = (x - mu) / sd
        for a, e in itertools.pairwise(b):
            means.append(z[a : max(e, a + 1)].mean(axis=0))
            lens.append(max(int(e - a), 1))
    pts = np.array(means)
    w = np.array(lens, dtype=np.float64)
    k = min(n_clusters, len(pts))
    best: tuple[float, IntArray] | None = None
    for r in range(10):
        cent, lab = kmeans2(pts, k, minit="++", seed=seed + r)
        cost = float(w @ ((pts - cent[lab]) ** 2).sum(axis=1))
        if best is None or cost < best[0]:
            best = (cost, lab.astype(np.int64))
    assert best is not None
    out, h = [], 0
    for x, b in zip(features, bounds, strict=True):
        lab = np.empty(x.shape[0], dtype=np.int64)
        for a, e in itertools.pairwise(b):
            lab[a:e] = best[1][h]
            h += 1
        lab[-1] = best[1][h - 1]
        out.append(lab)
    return out
