"""Boosted large-margin classifier over relational trees (Ratliff et al.), BLMRIL.

Minimises ``J(q) = 1/N Σ_i [max_a (q(s_i,a) + l(s_i,a_i,a)) − q(s_i,a_i)]`` with
``l = 1`` for ``a ≠ a_i`` by functional gradient descent: each round,
``a_i* = argmax_a q(s_i,a) + l(s_i,a_i,a)``, a relational classification tree
``k*`` is fit to ``((s_i,a_i), −1) ∪ ((s_i,a_i*), +1)`` and ``q ← q − ξ_t k*``.
Used alone as a policy (argmax of q), this is BLMRIL.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from thirdhand.relational.logic import RelationalError
from thirdhand.relational.mdp import GroundMDP
from thirdhand.relational.tilde import RelationalTree, fit_tree

Examples = Sequence[tuple[GroundMDP, NDArray[np.int64]]]


@dataclass
class BoostedQ:
    """``q(s,a) = Σ_t w_t k_t(s,a)``: a weighted sum of relational trees."""

    trees: list[RelationalTree] = field(default_factory=list)
    weights: list[float] = field(default_factory=list)

    def predict(
        self, mdp: GroundMDP, pairs: NDArray[np.int64] | None = None
    ) -> NDArray[np.float64]:
        """Score of each pair, shape (n,) (all pairs of ``mdp`` by default)."""
        n = mdp.n_pairs if pairs is None else np.asarray(pairs).size
        out = np.zeros(n)
        for w, t in zip(self.weights, self.trees, strict=True):
            out += w * t.predict(mdp, pairs)
        return out


@dataclass
class _Group:
    """Expert examples of one MDP with every alternative action of their states."""

    mdp: GroundMDP
    expert: NDArray[np.int64]  # (N,) expert pairs
    cand: NDArray[np.int64]  # (M,) pairs of the expert states, one segment per expert
    ptr: NDArray[np.int64]  # (N + 1,) segment bounds in cand
    is_expert: NDArray[np.bool_]  # (M,)
    q: NDArray[np.float64]  # (M,) current score of cand

    @classmethod
    def make(cls, mdp: GroundMDP, expert: NDArray[np.int64]) -> _Group:
        e = np.asarray(expert, dtype=np.int64)
        if e.size and (e.min() < 0 or e.max() >= mdp.n_pairs):
            raise RelationalError(f"boosting: expert pair index out of range 0..{mdp.n_pairs - 1}")
        s = mdp.pair_state[e]
        lo, hi = mdp.ptr[s], mdp.ptr[s + 1]
        ptr = np.concatenate([[0], np.cumsum(hi - lo)]).astype(np.int64)
        cand = (
            np.concatenate([np.arange(a, b) for a, b in zip(lo, hi, strict=True)])
            if e.size
            else np.zeros(0, np.int64)
        )
        is_expert = cand == np.repeat(e, hi - lo)
        return cls(mdp, e, cand, ptr, is_expert, np.zeros(cand.size))

    def violators(self) -> NDArray[np.int64]:
        """``a_i*`` per expert example (loss-augmented argmax; ties go to a non-expert action)."""
        v = self.q + np.where(self.is_expert, -1e-9, 1.0)
        m = np.maximum.reduceat(v, self.ptr[:-1])
        owner = np.repeat(np.arange(self.expert.size), np.diff(self.ptr))
        hit = np.where(v >= m[owner], np.arange(v.size), v.size)
        return self.cand[np.minimum.reduceat(hit, self.ptr[:-1])]


def fit_boosted(
    expert: Examples,
    *,
    n_trees: int = 40,
    max_depth: int = 4,
    max_vars: int = 3,
    step: float = 1.0,
    min_leaf: int = 1,
    lookahead: int = 1,
) -> BoostedQ:
    """Fit the boosted large-margin score function ``q_C`` on expert (s, a) pairs.

    Parameters
    ----------
    expert : sequence of (GroundMDP, ndarray of int, shape (N_g,))
        Expert pairs per grounded MDP.
    n_trees : int
        Boosting rounds T.
    max_depth, max_vars : int
        Of each classification tree.
    step : float
        Step size ξ_t = step / sqrt(t + 1).
    min_leaf, lookahead : int
        Of each classification tree (see :func:`.tilde.fit_tree`).

    Raises
    ------
    RelationalError
        If there is no expert example.
    """
    groups = [_Group.make(m, e) for m, e in expert if np.asarray(e).size]
    if not groups:
        raise RelationalError("boosting: no expert example")
    model = BoostedQ()
    for t in range(n_trees):
        examples: list[tuple[GroundMDP, NDArray[np.int64]]] = []
        labels: list[NDArray[np.float64]] = []
        for g in groups:
            star = g.violators()
            bad = star != g.expert
            if bad.any():
                examples.append((g.mdp, np.concatenate([g.expert[bad], star[bad]])))
                labels.append(np.concatenate([-np.ones(int(bad.sum())), np.ones(int(bad.sum()))]))
        if not examples:
            break
        tree = fit_tree(
            examples,
            np.concatenate(labels),
            max_depth=max_depth,
            max_vars=max_vars,
            classification=True,
            min_leaf=min_leaf,
            lookahead=lookahead,
        )
        if tree.root.test is None:
            break
        xi = step / np.sqrt(t + 1.0)
        model.trees.append(tree)
        model.weights.append(-xi)
        for g in groups:
            g.q -= xi * tree.predict(g.mdp, g.cand)
    return model
