"""Primitive-library parser: DP marginals vs brute force, candidate cuts, the sine experiment."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from thirdhand.datasets.primitive_shapes import sine_tracks
from thirdhand.primitives import PrimitiveError, PrimitiveLibrary
from thirdhand.primitives.segment_features import candidate_cuts, normalise_segments
from thirdhand.primitives.segmentation_dp import (
    best_segmentation,
    brute_force_marginals,
    segment_marginals,
)


@pytest.mark.parametrize("m", [0, 1, 3, 7, 12])
def test_dp_marginals_equal_brute_force(m: int, rng: np.random.Generator) -> None:
    scores = rng.normal(0.0, 3.0, (m + 2, m + 2))
    scores[rng.random(scores.shape) < 0.1] = -np.inf  # some forbidden segments
    scores[0, m + 1] = 0.0  # keep at least one path
    u, log_z = segment_marginals(scores)
    u_bf, log_z_bf = brute_force_marginals(scores)
    assert log_z == pytest.approx(log_z_bf, rel=1e-12, abs=1e-12)
    np.testing.assert_allclose(u, u_bf, atol=1e-12)


def test_viterbi_equals_best_enumerated_path(rng: np.random.Generator) -> None:
    scores = rng.normal(0.0, 2.0, (10, 10))
    path, best = best_segmentation(scores)
    # the best path beats every path that differs in one cut
    cuts = set(path[1:-1])
    for c in range(1, 9):
        other = sorted(cuts ^ {c})
        nodes = [0, *other, 9]
        alt = sum(scores[a, b] for a, b in itertools.pairwise(nodes))
        assert alt <= best + 1e-12
    assert best == pytest.approx(sum(scores[a, b] for a, b in itertools.pairwise(path)))


def test_dp_rejects_bad_scores() -> None:
    with pytest.raises(PrimitiveError, match="square"):
        segment_marginals(np.zeros((3, 4)))
    with pytest.raises(PrimitiveError, match="NaN"):
        segment_marginals(np.full((4, 4), np.nan))
    with pytest.raises(PrimitiveError, match="no segmentation"):
        segment_marginals(np.full((4, 4), -np.inf))


def test_candidate_cuts_at_zero_velocity() -> None:
    _t, y, bounds, labels = sine_tracks(1, seed=4)[0]
    cuts = candidate_cuts(y, dt=0.01, threshold=0.05)
    # every true boundary (and each bump's top) is a candidate, within 2 samples
    for b in bounds[1:-1]:
        assert np.min(np.abs(cuts - b)) <= 2
    n_bumps = len(labels) - 2
    assert cuts.size == (len(bounds) - 2) + n_bumps


def test_normalisation_rotates_start_to_end_on_x() -> None:
    seg = np.array([[[1.0, 1.0], [1.5, 1.5], [2.0, 2.0]]])
    out, ang = normalise_segments(seg)
    np.testing.assert_allclose(out[0, 0], 0.0)
    np.testing.assert_allclose(out[0, -1], [np.sqrt(2.0), 0.0], atol=1e-12)
    assert ang[0] == pytest.approx(np.pi / 4)


def test_library_bad_input() -> None:
    t = np.linspace(0, 1, 50)
    y = np.sin(t)[:, None]
    y[10] = np.nan
    with pytest.raises(PrimitiveError, match="track 0: sample 10 is not finite"):
        PrimitiveLibrary(2, threshold=0.1).fit([(t, y)])
    with pytest.raises(PrimitiveError, match="no demonstration"):
        PrimitiveLibrary(2, threshold=0.1).fit([])
    with pytest.raises(PrimitiveError, match=r"at least 5 samples .*window.*got 2"):
        PrimitiveLibrary(2, threshold=0.1).fit([(t[:2], y[:2])])


def test_library_e_step_equals_enumeration_on_a_real_track() -> None:
    """The marginals used by the outer EM, with the learnt mixture's scores, vs brute force."""
    train = sine_tracks(6, seed=3)
    lib = PrimitiveLibrary(3, threshold=0.05, seed=0, n_init=2).fit(
        [(t, y) for t, y, _, _ in train]
    )
    t, y, _, _ = max(train, key=lambda tr: tr[1].shape[0])
    tr = lib.prepare(t, y, "track")
    assert 3 <= tr.nodes.size - 2 <= 12
    scores, _ = lib.segment_scores(tr, lib.mixture_)
    u, log_z = segment_marginals(scores)
    u_bf, log_z_bf = brute_force_marginals(scores)
    assert log_z == pytest.approx(log_z_bf, rel=1e-12)
    np.testing.assert_allclose(u, u_bf, atol=1e-10)
    # each node's outgoing marginals sum to the probability that the node is a cut
    cut_prob = u.sum(axis=1)[1:-1]
    np.testing.assert_allclose(cut_prob, u.sum(axis=0)[1:-1], atol=1e-10)


@pytest.mark.parametrize("lam", [0.0, 1.5, 50.0])
def test_labelled_viterbi_with_switch_penalty_equals_enumeration(
    lam: float, rng: np.random.Generator
) -> None:
    from thirdhand.primitives.segmentation_dp import best_labelled_segmentation

    m, k = 6, 3
    scores = rng.normal(0.0, 2.0, (m + 2, m + 2, k))
    best = -np.inf
    for mask in itertools.product((False, True), repeat=m):
        nodes = [0, *[i + 1 for i in range(m) if mask[i]], m + 1]
        for labs in itertools.product(range(k), repeat=len(nodes) - 1):
            v = sum(
                scores[a, b, c] for (a, b), c in zip(itertools.pairwise(nodes), labs, strict=True)
            )
            v -= lam * sum(x != y for x, y in itertools.pairwise(labs))
            best = max(best, v)
    nodes, labels, score = best_labelled_segmentation(scores, lam)
    assert score == pytest.approx(best, abs=1e-9)
    again = sum(
        scores[a, b, c] for (a, b), c in zip(itertools.pairwise(nodes), labels, strict=True)
    )
    again -= lam * sum(x != y for x, y in itertools.pairwise(labels))
    assert again == pytest.approx(score, abs=1e-9)
    assert nodes[0] == 0 and nodes[-1] == m + 1 and len(labels) == len(nodes) - 1
