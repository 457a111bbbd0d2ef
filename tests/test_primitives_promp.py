"""ProMPs: recovery of the weight distribution, conditioning, sampling, EM, bad input."""

from __future__ import annotations

import numpy as np
import pytest

from thirdhand.primitives import PrimitiveError, ProMP
from thirdhand.primitives.promp import rbf_features


def demos(rng: np.random.Generator, n: int = 30) -> list[tuple[np.ndarray, np.ndarray]]:
    out = []
    for i in range(n):
        t = np.linspace(0.0, 1.0 + 0.05 * i, 80 + i)  # different durations and lengths
        z = (t - t[0]) / (t[-1] - t[0])
        a = 1.0 + 0.2 * rng.standard_normal()
        b = 0.1 * rng.standard_normal()
        out.append((t, np.stack([a * np.sin(np.pi * z) + b * z, z], axis=1)))
    return out


def test_exact_weights_are_recovered(rng: np.random.Generator) -> None:
    w_true = rng.normal(size=(3, 10))
    z = np.linspace(0, 1, 200)
    y = rbf_features(z, 10) @ w_true.T
    p = ProMP(10, regularization=1e-12).fit([(z, y), (z * 2, y)])
    np.testing.assert_allclose(p.mean_, w_true.reshape(-1), atol=1e-6)
    np.testing.assert_allclose(p.mean_trajectory(z), y, atol=1e-6)


@pytest.mark.parametrize("method", ["ridge", "em"])
def test_mean_std_and_conditioning(method: str, rng: np.random.Generator) -> None:
    p = ProMP(15).fit(demos(rng), method=method)  # type: ignore[arg-type]
    mid = p.mean_trajectory([0.5])[0]
    assert mid[0] == pytest.approx(1.0, abs=0.1)
    assert p.std_trajectory([0.5])[0, 0] == pytest.approx(0.2, rel=0.35)
    c = p.condition(0.5, [1.5, 0.5])
    np.testing.assert_allclose(c.mean_trajectory([0.5])[0], [1.5, 0.5], atol=1e-3)
    assert c.std_trajectory([0.5])[0, 0] < 1e-3
    goal = p.condition(1.0, [0.2, 1.0])
    np.testing.assert_allclose(goal.mean_trajectory([1.0])[0], [0.2, 1.0], atol=1e-3)
    samples = goal.sample(np.linspace(0, 1, 11), 50, rng=1)
    assert samples.shape == (50, 11, 2)
    assert np.abs(samples[:, -1, 0] - 0.2).max() < 0.01


def test_from_params_round_trip(rng: np.random.Generator) -> None:
    p = ProMP(8).fit(demos(rng, 5))
    q = ProMP.from_params(p.mean_, p.cov_, dims=2, noise=p.noise_, duration=p.duration_)
    z = np.linspace(0, 1, 7)
    np.testing.assert_allclose(q.mean_trajectory(z), p.mean_trajectory(z))
    with pytest.raises(PrimitiveError, match="do not fit 3 dims"):
        ProMP.from_params(p.mean_, p.cov_, dims=3)


def test_bad_input(rng: np.random.Generator) -> None:
    with pytest.raises(PrimitiveError, match="no demonstration"):
        ProMP().fit([])
    d = demos(rng, 3)
    d[1] = (d[1][0], d[1][1][:, :1])
    with pytest.raises(PrimitiveError, match="demonstration 1 has 1 dimensions, expected 2"):
        ProMP().fit(d)
    p = ProMP(5).fit(demos(rng, 3))
    with pytest.raises(PrimitiveError, match="phase must be in"):
        p.condition(1.5, [0, 0])
