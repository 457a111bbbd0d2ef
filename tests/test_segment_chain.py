"""Dynamic programs, the CRF objective and the logistic baseline against references."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.optimize import check_grad, minimize

from thirdhand.segment.chain import (
    binary_expectations,
    binary_marginals,
    forward_backward,
    pairwise_marginals,
    viterbi,
)
from thirdhand.segment.crf import PairCRF, _Data
from thirdhand.segment.features import SegmentationError
from thirdhand.segment.logistic import LogisticSegmenter, fit_logistic_newton, logistic_loss


def _brute(unary: np.ndarray, trans: np.ndarray) -> tuple[np.ndarray, list[tuple[int, ...]]]:
    n, s = unary.shape
    paths = list(itertools.product(range(s), repeat=n))
    scores = np.array(
        [
            sum(unary[t, y[t]] for t in range(n)) + sum(trans[y[t], y[t - 1]] for t in range(1, n))
            for y in paths
        ]
    )
    return scores, paths


@pytest.mark.parametrize("n_states", [2, 3])
@pytest.mark.parametrize("n", [1, 2, 5])
def test_forward_backward_matches_enumeration(
    rng: np.random.Generator, n_states: int, n: int
) -> None:
    unary = 3 * rng.standard_normal((n, n_states))
    trans = 3 * rng.standard_normal((n_states, n_states))
    scores, paths = _brute(unary, trans)
    log_z_ref = np.logaddexp.reduce(scores)
    prob = np.exp(scores - log_z_ref)
    marg_ref = np.zeros((n, n_states))
    pair_ref = np.zeros((max(n - 1, 0), n_states, n_states))
    for p, y in zip(prob, paths, strict=True):
        for t in range(n):
            marg_ref[t, y[t]] += p
            if t:
                pair_ref[t - 1, y[t], y[t - 1]] += p
    log_z, marg, pair_sum = forward_backward(unary, trans)
    np.testing.assert_allclose(log_z[0], log_z_ref, rtol=1e-12)
    np.testing.assert_allclose(marg, marg_ref, atol=1e-12)
    np.testing.assert_allclose(pair_sum, pair_ref.sum(axis=0), atol=1e-12)
    np.testing.assert_allclose(pairwise_marginals(unary, trans), pair_ref, atol=1e-12)
    path, best = viterbi(unary, trans)
    assert tuple(path) == paths[int(np.argmax(scores))]
    np.testing.assert_allclose(best[0], scores.max(), rtol=1e-12)


def test_batched_chains_equal_separate_chains(rng: np.random.Generator) -> None:
    u1, u2 = rng.standard_normal((7, 2)), rng.standard_normal((4, 2))
    trans = rng.standard_normal((2, 2))
    log_z, marg, _ = forward_backward(np.vstack([u1, u2]), trans, np.array([0, 7, 11]))
    for u, lz, m in ((u1, log_z[0], marg[:7]), (u2, log_z[1], marg[7:])):
        lz1, m1, _ = forward_backward(u, trans)
        np.testing.assert_allclose(lz, lz1[0], rtol=1e-13)
        np.testing.assert_allclose(m, m1, atol=1e-13)
    path, _ = viterbi(np.vstack([u1, u2]), trans, np.array([0, 7, 11]))
    np.testing.assert_array_equal(path[:7], viterbi(u1, trans)[0])
    np.testing.assert_array_equal(path[7:], viterbi(u2, trans)[0])


def test_extreme_potentials_stay_finite() -> None:
    unary = np.array([[0.0, 800.0], [0.0, -900.0], [0.0, 1000.0]])
    trans = np.array([[0.0, -700.0], [-700.0, 0.0]])
    log_z, marg, pair_sum = forward_backward(unary, trans)
    assert np.isfinite(log_z).all() and np.isfinite(marg).all() and np.isfinite(pair_sum).all()
    np.testing.assert_allclose(marg.sum(axis=1), 1.0)


def _random_sequences(rng: np.random.Generator, n_seq: int = 3) -> tuple[list, list]:
    xs, ys = [], []
    for _ in range(n_seq):
        n = int(rng.integers(3, 9))
        xs.append(rng.standard_normal((n, 3)))
        ys.append(rng.integers(0, 2, n))
    return xs, ys


def test_crf_nll_matches_enumeration(rng: np.random.Generator) -> None:
    xs, ys = _random_sequences(rng)
    crf = PairCRF().set_params_theta(rng.standard_normal(7))
    total = 0.0
    for x, y in zip(xs, ys, strict=True):
        unary = np.stack([np.zeros(len(x)), x @ crf.coef_state_], axis=1)
        scores, paths = _brute(unary, crf.coef_transition_)
        total += np.logaddexp.reduce(scores) - scores[paths.index(tuple(y))]
    np.testing.assert_allclose(crf.nll(xs, ys), total, rtol=1e-12)


@pytest.mark.parametrize("l2", [0.0, 0.7])
def test_crf_gradient_equals_finite_differences(rng: np.random.Generator, l2: float) -> None:
    xs, ys = _random_sequences(rng, 4)
    crf = PairCRF(l2=l2)
    data = _Data(xs, ys)
    theta = rng.standard_normal(7)
    err = check_grad(
        lambda th: crf.objective(th, data)[0], lambda th: crf.objective(th, data)[1], theta
    )
    assert err < 1e-5 * max(1.0, float(np.linalg.norm(crf.objective(theta, data)[1])))


def test_crf_fit_reaches_the_optimum(rng: np.random.Generator) -> None:
    xs, ys = _random_sequences(rng, 6)
    crf = PairCRF(l2=0.5).fit(xs, ys)
    data = _Data(xs, ys)
    ref = minimize(lambda th: crf.objective(th, data)[0], np.zeros(7), method="BFGS")
    np.testing.assert_allclose(crf.objective(crf.theta_, data)[0], ref.fun, rtol=1e-6)
    np.testing.assert_allclose(crf.theta_, ref.x, atol=1e-3)
    assert np.linalg.norm(crf.objective(crf.theta_, data)[1]) < 1e-3


def test_logistic_newton_matches_scipy(rng: np.random.Generator) -> None:
    x = np.column_stack([np.ones(60), rng.standard_normal((60, 3))])
    y = (x @ np.array([0.3, 1.0, -2.0, 0.5]) + rng.standard_normal(60) > 0).astype(float)
    w = fit_logistic_newton(x, y, l2=0.1)
    ref = minimize(logistic_loss, np.zeros(4), args=(x, y, 0.1), method="BFGS", tol=1e-10)
    np.testing.assert_allclose(w, ref.x, atol=1e-5)


def test_logistic_separable_data_stays_finite() -> None:
    x = np.column_stack([np.ones(6), np.arange(6.0)])
    y = np.array([0, 0, 0, 1, 1, 1])
    model = LogisticSegmenter(l2=1e-3).fit([x], [y])
    assert np.isfinite(model.coef_).all()
    np.testing.assert_array_equal(model.predict([x])[0], y)


def test_bad_sequences_raise() -> None:
    with pytest.raises(SegmentationError, match="3 feature rows but 2 labels"):
        PairCRF().fit([np.zeros((3, 2))], [np.zeros(2, int)])
    with pytest.raises(SegmentationError, match="labels must be 0 or 1"):
        PairCRF().fit([np.zeros((3, 2))], [np.array([0, 2, 1])])
    with pytest.raises(SegmentationError, match="non-finite"):
        PairCRF().fit([np.full((3, 2), np.nan)], [np.zeros(3, int)])
    with pytest.raises(SegmentationError, match="init must be"):
        PairCRF(init="magic").fit([np.zeros((3, 2))], [np.zeros(3, int)])


@pytest.mark.parametrize("scale", [1.0, 300.0, 2000.0])
def test_scaled_binary_kernel_matches_log_space(rng: np.random.Generator, scale: float) -> None:
    x = rng.standard_normal((300, 3))
    offsets = np.array([0, 120, 121, 300])
    w = scale * rng.standard_normal(3)
    trans = scale * rng.standard_normal((2, 2))
    log_z, e_state, e_trans = binary_expectations(x, offsets, w, trans)
    unary = np.column_stack([np.zeros(300), x @ w])
    lz_ref, marg, pair_sum = forward_backward(unary, trans, offsets)
    np.testing.assert_allclose(log_z, lz_ref.sum(), rtol=1e-10)
    np.testing.assert_allclose(e_state, marg[:, 1] @ x, rtol=1e-8, atol=1e-8)
    np.testing.assert_allclose(e_trans, pair_sum, rtol=1e-8, atol=1e-8)
    np.testing.assert_allclose(
        binary_marginals(x @ w, trans, offsets), marg[:, 1], rtol=1e-8, atol=1e-10
    )


def test_decode_equals_predict_proba_and_predict(rng: np.random.Generator) -> None:
    crf = PairCRF().set_params_theta(rng.standard_normal(7) * 2.0)
    x = rng.standard_normal((200, 3))
    prob, label = crf.decode(x)
    np.testing.assert_allclose(prob, crf.predict_proba([x])[0], rtol=1e-12, atol=1e-15)
    np.testing.assert_array_equal(label, crf.predict([x])[0])
