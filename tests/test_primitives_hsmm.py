"""Hidden semi-Markov model over per-sample channels: exact Viterbi, recovery, K by one SE."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from research.primitive_labels import one_se_choice, per_observation
from thirdhand.primitives import PrimitiveError
from thirdhand.primitives.hsmm import (
    HiddenSemiMarkov,
    allowed_moves,
    brute_force_hsmm,
    hsmm_viterbi,
    path_score,
    runs,
)


def _compositions(n: int, d_max: int) -> list[list[int]]:
    """Every way to write n as an ordered sum of parts 1 … d_max."""
    if n == 0:
        return [[]]
    return [[d, *rest] for d in range(1, min(d_max, n) + 1) for rest in _compositions(n - d, d_max)]


def _enumerate(
    e: np.ndarray, dur: np.ndarray, tr: np.ndarray, ini: np.ndarray, fin: np.ndarray | None = None
) -> float:
    """Best score over segmentations × labellings, consecutive segments of different states."""
    t_n, k_n = e.shape
    fin = np.zeros(k_n) if fin is None else fin
    best = -np.inf
    for parts in _compositions(t_n, dur.shape[1]):
        for labs in itertools.product(range(k_n), repeat=len(parts)):
            if any(a == b for a, b in itertools.pairwise(labs)):
                continue
            v, s = float(ini[labs[0]]) + float(fin[labs[-1]]), 0
            for h, (d, k) in enumerate(zip(parts, labs, strict=True)):
                v += dur[k, d - 1] + e[s : s + d, k].sum()
                if h:
                    v += tr[labs[h - 1], k]
                s += d
            best = max(best, v)
    return best


@pytest.mark.parametrize(("t_n", "k_n", "d_n"), [(1, 1, 1), (5, 2, 3), (7, 3, 4), (8, 3, 8)])
def test_viterbi_equals_enumeration(t_n: int, k_n: int, d_n: int, rng: np.random.Generator) -> None:
    for _ in range(5):
        e = rng.normal(0.0, 2.0, (t_n, k_n))
        dur = rng.normal(0.0, 1.0, (k_n, d_n))
        tr = rng.normal(0.0, 1.0, (k_n, k_n))
        ini = rng.normal(0.0, 1.0, k_n)
        states, score = hsmm_viterbi(e, dur, tr, ini)
        assert score == pytest.approx(_enumerate(e, dur, tr, ini), abs=1e-9)
        # the returned path has the returned score, and so does the module's enumeration
        assert path_score(states, e, dur, tr, ini) == pytest.approx(score, abs=1e-9)
        assert brute_force_hsmm(e, dur, tr, ini)[1] == pytest.approx(score, abs=1e-9)
        assert runs(states)[1].max() <= d_n


@pytest.mark.parametrize(("t_n", "k_n", "d_n"), [(5, 2, 3), (7, 3, 4), (6, 4, 6)])
def test_viterbi_with_final_weights_equals_enumeration(
    t_n: int, k_n: int, d_n: int, rng: np.random.Generator
) -> None:
    for _ in range(5):
        e = rng.normal(0.0, 2.0, (t_n, k_n))
        dur = rng.normal(0.0, 1.0, (k_n, d_n))
        tr = rng.normal(0.0, 1.0, (k_n, k_n))
        ini = rng.normal(0.0, 1.0, k_n)
        fin = rng.normal(0.0, 1.0, k_n)
        fin[rng.integers(k_n)] = -np.inf  # one state a stream may not end in
        states, score = hsmm_viterbi(e, dur, tr, ini, fin)
        assert score == pytest.approx(_enumerate(e, dur, tr, ini, fin), abs=1e-9)
        assert path_score(states, e, dur, tr, ini, fin) == pytest.approx(score, abs=1e-9)
        assert brute_force_hsmm(e, dur, tr, ini, fin)[1] == pytest.approx(score, abs=1e-9)
        assert np.isfinite(fin[states[-1]])


def test_entry_exit_topology_under_viterbi_equals_enumeration(rng: np.random.Generator) -> None:
    # the allowed moves of ``ends`` as −inf weights: enumeration agrees, and every path
    # starts in the entry, ends in the exit and visits neither in between
    allow_init, allow_trans, allow_final = allowed_moves(4, ends=True)
    with np.errstate(divide="ignore"):
        ini, tr, fin = np.log(allow_init), np.log(allow_trans), np.log(allow_final)
    assert list(allow_final) == [0, 0, 0, 1] and list(allow_init) == [1, 0, 0, 0]
    # entry → 1, 2; 1 ↔ 2; 1, 2 → exit; nothing else
    np.testing.assert_array_equal(
        allow_trans, [[0, 1, 1, 0], [0, 0, 1, 1], [0, 1, 0, 1], [0, 0, 0, 0]]
    )
    for _ in range(5):
        e = rng.normal(0.0, 2.0, (7, 4))
        dur = rng.normal(0.0, 1.0, (4, 5))
        states, score = hsmm_viterbi(e, dur, tr, ini, fin)
        assert score == pytest.approx(_enumerate(e, dur, tr, ini, fin), abs=1e-9)
        lab = runs(states)[2]
        assert lab[0] == 0 and lab[-1] == 3 and set(lab[1:-1].tolist()) <= {1, 2}


def test_viterbi_errors() -> None:
    with pytest.raises(PrimitiveError, match="no labelling of 5 samples"):
        # one state, durations up to 2: five samples cannot be covered
        hsmm_viterbi(np.zeros((5, 1)), np.zeros((1, 2)), np.zeros((1, 1)), np.zeros(1))
    with pytest.raises(PrimitiveError, match="emissions for 2 states"):
        hsmm_viterbi(np.zeros((5, 2)), np.zeros((3, 2)), np.zeros((2, 2)), np.zeros(2))


def _phased_stream(order: list[int], durations: dict[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Noise-free 2-channel stream: state k emits the constant (k, 2k) for durations[k] samples."""
    labels = np.concatenate([np.full(durations[k], k) for k in order])
    x = np.stack([labels, 2.0 * labels], axis=1).astype(np.float64)
    return x, labels


def test_label_trained_parse_recovers_labels_and_durations() -> None:
    durations = {1: 12, 2: 5, 3: 8}
    order = [1, 2, 3, 2, 3, 2, 3, 1]
    x, labels = _phased_stream(order, durations)
    model = HiddenSemiMarkov(reg=1e-2).fit_labelled([x], [labels])
    assert list(model.states_) == [1, 2, 3]
    # every run of a label has the same length: the log-normal sits on it
    np.testing.assert_allclose(np.exp(model.dur_mu_), [12, 5, 8], rtol=1e-12)
    # transitions counted with one Laplace count: 2 → 3 three times, 2 → 1 never
    p = np.exp(model.log_trans_)
    assert p[1, 2] == pytest.approx(4 / 5) and p[1, 0] == pytest.approx(1 / 5)
    assert np.all(np.diag(p) == 0.0)
    other, truth = _phased_stream([1, 2, 3, 2, 3, 1], durations)
    np.testing.assert_array_equal(model.predict(other), truth)


def test_unsupervised_parse_recovers_segments_up_to_names() -> None:
    durations = {0: 10, 1: 6, 2: 9}
    x, labels = _phased_stream([0, 1, 2, 1, 2, 1, 2, 0], durations)
    x2, labels2 = _phased_stream([0, 1, 2, 1, 2, 0], durations)
    model = HiddenSemiMarkov(3, seed=0).fit_unsupervised([x, x2])
    for xs, truth in ((x, labels), (x2, labels2)):
        pred = model.predict(xs)
        # a bijection between found states and true labels explains every sample
        pairs = set(zip(pred.tolist(), truth.tolist(), strict=True))
        assert len(pairs) == 3
        assert len({a for a, _ in pairs}) == len({b for _, b in pairs}) == 3


def test_emission_weight_lets_durations_overrule_a_short_blip() -> None:
    # training: state 0 lasts 40 samples, state 1 four (level 0 and 1)
    lab_train = np.repeat([0, 1, 0, 1, 0], [40, 4, 40, 4, 40])
    train = lab_train[:, None].astype(np.float64)
    # a new stream of 40 samples at level 0 with a 4-sample blip at level 1 in the middle
    x = np.zeros((40, 1))
    x[18:22] = 1.0
    strong = HiddenSemiMarkov(reg=0.05).fit_labelled([train], [lab_train])
    weak = HiddenSemiMarkov(reg=0.05, emission_weight=0.2).fit_labelled([train], [lab_train])
    # every sample counted fully, the blip gains 4 × ½ · 1² / 0.05 = 40 nats as state 1,
    # more than the two short runs of state 0 (18 samples, 0.8 log-units from 40) cost
    np.testing.assert_array_equal(strong.predict(x), (x[:, 0] > 0.5).astype(int))
    # weighted by 1/5 it gains 8 nats: one run of 40, state 0's own duration, wins
    assert np.all(weak.predict(x) == 0)
    with pytest.raises(PrimitiveError, match="emission weight"):
        HiddenSemiMarkov(emission_weight=0.0)


def test_hsmm_bad_input() -> None:
    with pytest.raises(PrimitiveError, match="stream 0 has NaN"):
        HiddenSemiMarkov(2).fit_unsupervised([np.full((5, 1), np.nan)])
    with pytest.raises(PrimitiveError, match="3 samples but labels of shape"):
        HiddenSemiMarkov().fit_labelled([np.zeros((3, 1))], [np.zeros(4, dtype=int)])
    with pytest.raises(PrimitiveError, match="at least 1 state"):
        HiddenSemiMarkov(0).fit_unsupervised([np.zeros((5, 1))])
    model = HiddenSemiMarkov().fit_labelled([np.zeros((4, 2))], [np.array([0, 0, 1, 1])])
    with pytest.raises(PrimitiveError, match="3 channels, the model has 2"):
        model.predict(np.zeros((4, 3)))


def test_one_se_rule_arithmetic() -> None:
    # per-observation fold scores: K=2 → 0.40, 0.44; K=3 → 0.40, 0.50 (best, mean 0.45);
    # K=3's fold spread: sd 0.0707, SE 0.05 → anything ≥ 0.40 is within one SE
    folds = {
        2: [(40.0, 100), (44.0, 100)],
        3: [(40.0, 100), (50.0, 100)],
        4: [(30.0, 100), (30.0, 100)],
    }
    assert per_observation(folds) == pytest.approx({2: 0.42, 3: 0.45, 4: 0.30})
    assert one_se_choice(folds) == 2
    # a tighter best (both folds 0.45): K=2's 0.42 is now outside one SE (0)
    folds[3] = [(45.0, 100), (45.0, 100)]
    assert one_se_choice(folds) == 3
    # one fold: no spread, the best K
    assert one_se_choice({2: [(1.0, 10)], 3: [(2.0, 10)]}) == 3
    with pytest.raises(PrimitiveError, match="no K was scored"):
        one_se_choice({})


def test_restarts_keep_the_best_training_score(rng: np.random.Generator) -> None:
    # three overlapping levels in noise: hard EM from different seedings ends differently
    lab = np.repeat([0, 1, 2, 1, 0, 2, 1, 0], [15, 9, 12, 7, 14, 10, 8, 13])
    x = (lab + rng.normal(0.0, 0.6, lab.size))[:, None]
    one = HiddenSemiMarkov(3, seed=5).fit_unsupervised([x])
    many = HiddenSemiMarkov(3, seed=5).fit_unsupervised([x], n_init=6)
    # restart 0 of ``many`` is ``one``: the kept restart can only score higher
    assert many.score_ >= one.score_
    assert many.score_ == pytest.approx(sum(many.decode(a)[1] for a in [x]))
    with pytest.raises(PrimitiveError, match="at least 1 restart"):
        HiddenSemiMarkov(3).fit_unsupervised([x], n_init=0)


def _ends_stream(n_strokes: int) -> tuple[np.ndarray, np.ndarray]:
    """Noise-free: entry (level 5, 10 samples), strokes alternating levels 0 (6) and 1 (8),
    exit (level 5 again, 12 samples); labels 0 entry, 1, 2 strokes, 3 exit."""
    lab = [0] + [1, 2] * n_strokes + [3]
    dur = {0: 10, 1: 6, 2: 8, 3: 12}
    level = {0: 5.0, 1: 0.0, 2: 1.0, 3: 5.0}
    labels = np.concatenate([np.full(dur[k], k) for k in lab])
    x = np.array([level[int(k)] for k in labels])[:, None]
    return x, labels


def test_ends_recover_entry_and_exit_that_look_alike() -> None:
    # entry and exit emit the same level: only where they occur tells them apart
    (x1, l1), (x2, l2) = _ends_stream(3), _ends_stream(2)
    model = HiddenSemiMarkov(2, ends=True, seed=0).fit_unsupervised([x1, x2])
    assert model.means_.shape[0] == 4 and list(model.states_) == [0, 1, 2, 3]
    # durations of the entry and exit: one run each per stream, exactly 10 and 12
    np.testing.assert_allclose(np.exp(model.dur_mu_[[0, 3]]), [10, 12], rtol=1e-12)
    x3, l3 = _ends_stream(4)  # a new stream with more strokes
    for x, truth in ((x1, l1), (x2, l2), (x3, l3)):
        pred = model.predict(x)
        np.testing.assert_array_equal(pred[truth == 0], 0)
        np.testing.assert_array_equal(pred[truth == 3], 3)
        # the two stroke states are a bijection of the two stroke labels
        work = (truth == 1) | (truth == 2)
        pairs = set(zip(pred[work].tolist(), truth[work].tolist(), strict=True))
        assert len(pairs) == 2 and len({a for a, _ in pairs}) == 2
    # without ends, three states cannot give the entry and exit states of their own
    plain = HiddenSemiMarkov(3, seed=0).fit_unsupervised([x1, x2])
    assert plain.predict(x1)[0] == plain.predict(x1)[-1]


def test_covariance_prior_in_runs_is_the_stated_mixture() -> None:
    # state 0: two runs, state 1: one run; w = 1.5 pseudo-runs of the pooled covariance
    rng = np.random.default_rng(3)
    lab = np.repeat([0, 1, 0], [30, 40, 30])
    x = rng.normal(0.0, 1.0, (100, 2)) + lab[:, None] * [4.0, -2.0]
    model = HiddenSemiMarkov(cov_prior_runs=1.5, reg=0.0).fit_labelled([x], [lab])
    glob = np.cov(x.T)
    for k, r in ((0, 2), (1, 1)):
        s_k = np.cov(x[lab == k].T)
        np.testing.assert_allclose(model.covs_[k], (r * s_k + 1.5 * glob) / (r + 1.5), rtol=1e-12)
    plain = HiddenSemiMarkov(reg=0.0).fit_labelled([x], [lab])
    np.testing.assert_allclose(plain.covs_[1], np.cov(x[lab == 1].T), rtol=1e-12)


def test_ends_bad_input() -> None:
    with pytest.raises(PrimitiveError, match="learned without labels"):
        HiddenSemiMarkov(2, ends=True).fit_labelled([np.zeros((4, 1))], [np.array([0, 0, 1, 1])])
    with pytest.raises(PrimitiveError, match="streams of 3 samples or more"):
        HiddenSemiMarkov(1, ends=True).fit_unsupervised([np.zeros((2, 1)), np.zeros((5, 1))])
    with pytest.raises(PrimitiveError, match="covariance prior must be ≥ 0 runs"):
        HiddenSemiMarkov(cov_prior_runs=-1.0)


def test_decode_lengthens_durations_when_no_path_fits_within_them() -> None:
    # one work state between entry and exit: a stream with a work run three times longer
    # than any seen cannot be covered by durations up to 1.5 × the longest run
    x, _ = _ends_stream(1)
    model = HiddenSemiMarkov(1, ends=True, seed=0).fit_unsupervised([x])
    assert model.max_duration_ == 21  # 1.5 × the work run of 6 + 8 samples
    long = np.vstack([np.full((10, 1), 5.0), np.zeros((60, 1)), np.full((12, 1), 5.0)])
    pred, score = model.decode(long)
    np.testing.assert_array_equal(pred, np.repeat([0, 1, 2], [10, 60, 12]))
    assert np.isfinite(score)


def test_ends_on_a_stream_with_fewer_work_samples_than_states() -> None:
    # three samples: one for the entry, one for the work, one for the exit; the k-means
    # reseeding of two work states on one sample is skipped, the fit still completes
    model = HiddenSemiMarkov(2, ends=True).fit_unsupervised([np.array([[5.0], [0.0], [5.0]])])
    pred = model.predict(np.array([[5.0], [0.0], [0.0], [5.0]]))
    assert pred[0] == 0 and pred[-1] == 3 and set(pred[1:-1].tolist()) <= {1, 2}


def test_open_start_and_end_for_parts_cut_from_a_recording() -> None:
    (x1, l1), (x2, _) = _ends_stream(3), _ends_stream(2)
    model = HiddenSemiMarkov(2, ends=True, seed=0).fit_unsupervised([x1, x2])
    prefix, truth_p = x1[:40], l1[:40]  # entry, then strokes: no exit
    suffix, truth_s = x1[10:], l1[10:]  # strokes, then exit: no entry
    open_p = model.decode(prefix, open_end=True)[0]
    np.testing.assert_array_equal(open_p == 0, truth_p == 0)
    assert 3 not in open_p
    assert model.decode(prefix)[0][-1] == 3  # closed, it must end in the exit
    open_s = model.decode(suffix, open_start=True)[0]
    np.testing.assert_array_equal(open_s == 3, truth_s == 3)
    assert 0 not in open_s
    assert model.decode(suffix)[0][0] == 0  # closed, it must start in the entry
    # fitted on a prefix and a suffix with their open ends: the stroke states stay strokes
    cut = HiddenSemiMarkov(2, ends=True, seed=0).fit_unsupervised(
        [prefix, suffix], open_ends=[(False, True), (True, False)]
    )
    assert set(cut.decode(prefix, open_end=True)[0][truth_p > 0].tolist()) <= {1, 2}
    with pytest.raises(PrimitiveError, match="2 streams but 1 open-end flags"):
        HiddenSemiMarkov(2, ends=True).fit_unsupervised([x1, x2], open_ends=[(True, True)])


def test_adapt_is_a_fixed_point_on_the_fitted_streams_and_pools_a_new_one() -> None:
    durations = {1: 12, 2: 5, 3: 8}
    a, lab_a = _phased_stream([1, 2, 3, 2, 3, 2, 3, 1], durations)
    model = HiddenSemiMarkov(reg=1e-2).fit_labelled([a], [lab_a])
    means, mu = model.means_.copy(), model.dur_mu_.copy()
    # on the streams it was fitted on, the model's own parse is its labels: nothing moves
    model.adapt([a])
    np.testing.assert_array_equal(model.means_, means)
    np.testing.assert_array_equal(model.dur_mu_, mu)
    # a recording whose every channel reads 0.3 higher (a sensor offset): parsed right,
    # and each state's mean becomes the mean of its samples in both recordings
    b, lab_b = _phased_stream([1, 2, 3, 2, 3, 1], durations)
    b = b + 0.3
    model.adapt([a, b])
    assert list(model.states_) == [1, 2, 3]
    np.testing.assert_array_equal(model.predict(b), lab_b)
    for i, k in enumerate((1, 2, 3)):
        pooled = np.vstack([a[lab_a == k], b[lab_b == k]]).mean(axis=0)
        np.testing.assert_allclose(model.means_[i], pooled, rtol=0, atol=1e-12)


def test_adapt_needs_a_fitted_model() -> None:
    x, _ = _phased_stream([1, 2, 1], {1: 4, 2: 3})
    with pytest.raises(PrimitiveError, match="adapt needs a fitted model"):
        HiddenSemiMarkov(2).adapt([x])
