"""The live loop's causal CRF: the same features and the same chain as offline."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from thirdhand.demonstration import Demonstration
from thirdhand.live.features import CausalFeatures, feature_lag
from thirdhand.live.filter import ChainFilter, OnlinePhases
from thirdhand.live.source import ReplaySource
from thirdhand.segment.chain import forward_backward
from thirdhand.segment.design import DemoFeatures, FeatureConfig
from thirdhand.segment.model import default_model
from thirdhand.segment.pipeline import default_pairs
from thirdhand.synth import make_scene


@pytest.fixture(scope="module")
def chair() -> Demonstration:
    demo = make_scene("chair", seed=21)
    n = 1500  # 12.5 s: the first leg
    names = demo.body_names
    return Demonstration(
        demo.t[:n],
        demo.bodies,
        {b: demo.pos(b)[:n] for b in names},
        {b: demo.quat(b)[:n] for b in names},
        valid={b: demo.valid(b)[:n] for b in names},
        meta=demo.meta,
    )


def _offline_filtered(score: np.ndarray, trans: np.ndarray) -> np.ndarray:
    """p(y_t = 1 | x_1..t) from the offline forward-backward pass on every prefix."""
    u = np.zeros((score.size, 2))
    u[:, 1] = score
    return np.array([forward_backward(u[: t + 1], trans)[1][t, 1] for t in range(score.size)])


def test_filter_equals_offline_forward_pass_on_every_prefix() -> None:
    rng = np.random.default_rng(0)
    n, d, chains = 120, 5, 3
    x = rng.normal(size=(n, chains, d))
    x[40:55] = 0.0  # a gap without evidence: zero rows
    w = rng.normal(size=(chains, d))
    trans = rng.normal(scale=2.0, size=(chains, 2, 2))
    lag = 4
    filt = ChainFilter(w, trans, lag=lag)
    got = np.array([filt.update(x[t]) for t in range(n)])
    smoothed = []
    filt2 = ChainFilter(w, trans, lag=lag)
    for t in range(n):
        filt2.update(x[t])
        smoothed.append(filt2.smoothed())
    for c in range(chains):
        score = x[:, c] @ w[c]
        np.testing.assert_allclose(got[:, c], _offline_filtered(score, trans[c]), atol=1e-9)
        u = np.zeros((n, 2))
        u[:, 1] = score
        for t in (0, 3, 10, 47, n - 1):
            step, prob = smoothed[t]
            assert step == max(t - lag, 0)
            want = forward_backward(u[: t + 1], trans[c])[1][step, 1]
            assert prob[c] == pytest.approx(want, abs=1e-9)


def test_lag_zero_smoother_is_the_filter() -> None:
    rng = np.random.default_rng(1)
    filt = ChainFilter(rng.normal(size=(2, 3)), rng.normal(size=(2, 2, 2)), lag=0)
    for _ in range(20):
        p = filt.update(rng.normal(size=(2, 3)))
        step, q = filt.smoothed()
        assert step == filt.n_steps - 1
        np.testing.assert_allclose(p, q, atol=1e-12)


def test_causal_rows_equal_offline_rows(chair: Demonstration) -> None:
    """Without the two whole-track steps (noise floor, static gap fill) the rows are the same."""
    cfg = dataclasses.replace(default_model().features, adaptive_eps=False, fill_gaps_s=0.0)
    pairs = default_pairs(chair)
    names = chair.body_names
    feats = CausalFeatures(
        names, [(names.index(a), names.index(b)) for a, b in pairs], cfg, chair.meta
    )
    rows = []
    for fr in ReplaySource(chair, 0):
        rows += feats.push(fr.t, fr.pos, fr.quat, fr.valid)
    rows += feats.flush()
    offline = DemoFeatures(chair, cfg)
    assert len(rows) == offline.axis.n_steps
    assert [r.step for r in rows] == list(range(len(rows)))
    for i, (a, b) in enumerate(pairs):
        x, ev = offline.pair(a, b)
        np.testing.assert_allclose(np.stack([r.x[i] for r in rows]), x, rtol=0, atol=1e-9)
        np.testing.assert_array_equal(np.array([r.evidence[i] for r in rows]), ev)


def test_feature_lag_of_the_shipped_model() -> None:
    cfg = default_model().features
    assert cfg.windows == (5, 10, 2)
    assert feature_lag(cfg) == 4  # 0.2 s at 20 Hz
    assert feature_lag(FeatureConfig(window=1)) == 0


def test_online_phases_filter_is_the_offline_forward_pass_on_its_rows(chair: Demonstration) -> None:
    """The loop's filtered probabilities are the offline chain's on the rows it computed."""
    online = OnlinePhases(chair.bodies, chair.meta)
    rows: list[np.ndarray] = []
    probs: list[np.ndarray] = []
    orig = online.filter.update

    def spy(x: np.ndarray) -> np.ndarray:
        rows.append(x.copy())
        p = orig(x)
        probs.append(p.copy())
        return p

    online.filter.update = spy  # type: ignore[method-assign]
    for fr in ReplaySource(chair, 0):
        online.push(fr.t, fr.pos, fr.quat, fr.valid)
    i = online.pairs.index(("rh_index", "leg3")) if ("rh_index", "leg3") in online.pairs else 0
    crf = default_model().crf(online.kinds[i])
    score = np.stack(rows)[:, i] @ crf.coef_state_
    want = _offline_filtered(score[:150], crf.coef_transition_)
    np.testing.assert_allclose(np.stack(probs)[:150, i], want, atol=1e-9)
