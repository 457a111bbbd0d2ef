"""Dynamic programmes over cut points: segment marginals and the most likely segmentation.

A trajectory with ``M`` candidate cuts has nodes ``0 … M+1`` (its start, the cuts,
its end); a segmentation is a subset of the cuts, i.e. a path ``0 = a_0 < a_1 <
… < a_m = M+1`` through the nodes, with probability proportional to
``Π_h exp(score[a_h, a_{h+1}])`` under a uniform prior over the ``2^M`` subsets.
The marginal of segment ``(a, b)`` — the sum of the posteriors of the
segmentations that contain it, ``u_h = Σ_j γ_j [S_h ∈ D_j]`` — comes from one
forward and one backward pass, ``O(M²)`` for given scores.
"""

from __future__ import annotations

import itertools

import numpy as np
from scipy.special import logsumexp

from thirdhand.arrays import FloatArray
from thirdhand.primitives.checks import PrimitiveError


def _check_scores(scores: FloatArray) -> int:
    if scores.ndim != 2 or scores.shape[0] != scores.shape[1] or scores.shape[0] < 2:
        raise PrimitiveError(
            f"segment scores must be a square (M+2, M+2) array, got {scores.shape}"
        )
    if np.isnan(scores).any():
        raise PrimitiveError("segment scores contain NaN")
    return scores.shape[0]


def _lse(x: FloatArray) -> float:
    """``log Σ exp x`` of a 1-D array (−inf when every entry is): the DP's inner sum.

    scipy's ``logsumexp`` costs ~0.3 ms a call in input handling, and the DP
    makes one call per node of every track in every EM iteration.
    """
    m = float(x.max())
    if m == -np.inf:
        return m
    return m + float(np.log(np.exp(x - m).sum()))


def segment_marginals(scores: FloatArray) -> tuple[FloatArray, float]:
    """Posterior probability of every segment, by forward–backward over the cuts.

    Parameters
    ----------
    scores : ndarray, shape (M+2, M+2)
        ``scores[a, b]`` = log-likelihood of the segment from node ``a`` to node
        ``b`` (only ``a < b`` is read; ``−inf`` forbids a segment).

    Returns
    -------
    marginals : ndarray, shape (M+2, M+2)
        ``u[a, b]``, zero below the diagonal.
    log_z : float
        ``log Σ_j Π_{h ∈ D_j} exp(score_h)`` over all segmentations.
    """
    n = _check_scores(scores)
    upper = np.triu(np.ones((n, n), dtype=bool), k=1)
    s = np.where(upper, scores, -np.inf)
    alpha = np.full(n, -np.inf)
    alpha[0] = 0.0
    for b in range(1, n):
        alpha[b] = _lse(alpha[:b] + s[:b, b])
    beta = np.full(n, -np.inf)
    beta[-1] = 0.0
    for a in range(n - 2, -1, -1):
        beta[a] = _lse(s[a, a + 1 :] + beta[a + 1 :])
    log_z = float(alpha[-1])
    if not np.isfinite(log_z):
        raise PrimitiveError("no segmentation has a finite score (every path is forbidden)")
    with np.errstate(invalid="ignore"):
        u = np.exp(alpha[:, None] + s + beta[None, :] - log_z)
    return np.where(upper, np.nan_to_num(u, nan=0.0), 0.0), log_z


def best_segmentation(scores: FloatArray) -> tuple[list[int], float]:
    """Most likely segmentation (Viterbi over the cuts).

    Returns
    -------
    nodes : list of int
        The path ``0 = a_0 < … < a_m = M+1``.
    score : float
        Its summed score.
    """
    n = _check_scores(scores)
    upper = np.triu(np.ones((n, n), dtype=bool), k=1)
    s = np.where(upper, scores, -np.inf)
    best = np.full(n, -np.inf)
    best[0] = 0.0
    back = np.zeros(n, dtype=np.int64)
    for b in range(1, n):
        cand = best[:b] + s[:b, b]
        back[b] = int(np.argmax(cand))
        best[b] = cand[back[b]]
    if not np.isfinite(best[-1]):
        raise PrimitiveError("no segmentation has a finite score (every path is forbidden)")
    path = [n - 1]
    while path[-1] != 0:
        path.append(int(back[path[-1]]))
    return path[::-1], float(best[-1])


def best_labelled_segmentation(
    scores: FloatArray, switch_penalty: float
) -> tuple[list[int], list[int], float]:
    """Most likely segmentation and skill labels when a change of skill costs ``switch_penalty``.

    A semi-Markov Viterbi over (node, skill of the segment ending there):
    ``best[b, k] = max_a max_k' best[a, k'] − λ [k' ≠ k] + scores[a, b, k]``,
    ``O(M² K)``.

    Parameters
    ----------
    scores : ndarray, shape (M+2, M+2, K)
        ``scores[a, b, k]`` = log-likelihood of segment ``(a, b)`` as skill ``k``.
    switch_penalty : float
        ``λ ≥ 0``, nats.

    Returns
    -------
    nodes : list of int
    labels : list of int
        Skill of each segment.
    score : float
    """
    if scores.ndim != 3:
        raise PrimitiveError(f"labelled segment scores must be (M+2, M+2, K), got {scores.shape}")
    n = _check_scores(scores[:, :, 0])
    k_n = scores.shape[2]
    lam = float(switch_penalty)
    if not np.isfinite(lam) or lam < 0:
        raise PrimitiveError(f"switch penalty must be a non-negative number, got {lam}")
    best = np.full((n, k_n), -np.inf)
    back_a = np.zeros((n, k_n), dtype=np.int64)
    back_k = np.zeros((n, k_n), dtype=np.int64)
    for b in range(1, n):
        if b == 1:
            prev = np.zeros((1, k_n))
            prev_k = np.zeros((1, k_n), dtype=np.int64)
        else:
            inner = best[1:b]
            top = np.argmax(inner, axis=1)
            stay = inner
            move = inner[np.arange(b - 1), top][:, None] - lam
            take_move = move > stay
            prev = np.vstack([np.zeros((1, k_n)), np.where(take_move, move, stay)])
            prev_k = np.vstack(
                [
                    np.zeros((1, k_n), dtype=np.int64),
                    np.where(take_move, top[:, None], np.arange(k_n)[None, :]),
                ]
            )
        cand = prev + scores[:b, b, :]
        a = np.argmax(cand, axis=0)
        best[b] = cand[a, np.arange(k_n)]
        back_a[b] = a
        back_k[b] = prev_k[a, np.arange(k_n)]
    k = int(np.argmax(best[-1]))
    total = float(best[-1, k])
    if not np.isfinite(total):
        raise PrimitiveError("no segmentation has a finite score (every path is forbidden)")
    nodes, labels = [n - 1], [k]
    b = n - 1
    while True:
        a = int(back_a[b, k])
        if a == 0:
            break
        k_prev = int(back_k[b, k])
        nodes.append(a)
        labels.append(k_prev)
        b, k = a, k_prev
    nodes.append(0)
    return nodes[::-1], labels[::-1], total


def brute_force_marginals(scores: FloatArray) -> tuple[FloatArray, float]:
    """Same as :func:`segment_marginals` by enumerating all ``2^M`` segmentations (M ≤ 16)."""
    n = _check_scores(scores)
    m = n - 2
    if m > 16:
        raise PrimitiveError(f"brute force over 2^{m} segmentations refused (M ≤ 16)")
    logs, paths = [], []
    for mask in itertools.product((False, True), repeat=m):
        nodes = [0, *[i + 1 for i in range(m) if mask[i]], n - 1]
        logs.append(sum(float(scores[a, b]) for a, b in itertools.pairwise(nodes)))
        paths.append(nodes)
    la = np.array(logs)
    log_z = float(logsumexp(la))
    gamma = np.exp(la - log_z)
    u = np.zeros((n, n))
    for g, nodes in zip(gamma, paths, strict=True):
        for a, b in itertools.pairwise(nodes):
            u[a, b] += g
    return u, log_z
