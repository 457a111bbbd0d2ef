"""Bagged relational regression trees: the mean of trees fit to bootstrap samples.

Each tree is :func:`.tilde.fit_tree` on a bootstrap sample of the examples
(drawn with replacement, as many as there are; a drawn example's weight is
multiplied by the number of times it is drawn). The ensemble's value,
``R̂(s, a) = (1/B) Σ_b T_b(s, a)``, is still a relational function of the
pair (every tree is), so it is evaluated on pairs of any grounded MDP, of any
size. A single greedy tree fit to a few hundred transitions often picks a
test that only happens to separate the sample (a colour test, a test that
holds for towers of height 3 on 5 blocks but not the tallest tower on 15);
averaging trees fit to resampled data keeps what most samples agree on
(Breiman 1996, "Bagging predictors").
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from thirdhand.relational.logic import RelationalError
from thirdhand.relational.mdp import GroundMDP
from thirdhand.relational.tilde import Batch, Node, RelationalTree, extend, fit_tree, satisfied

#: A node's place: the tests and their answers on the path from the root.
_Path = tuple[tuple[tuple[object, ...], bool], ...]


@dataclass
class TreeEnsemble:
    """The mean of relational regression trees, evaluated as :class:`.tilde.RelationalTree`."""

    trees: list[RelationalTree] = field(default_factory=list)

    def predict(
        self, mdp: GroundMDP, pairs: NDArray[np.int64] | None = None
    ) -> NDArray[np.float64]:
        """The trees' mean value for each pair, shape (n,) (all pairs of ``mdp`` by default).

        Trees fit to bootstrap samples of the same data mostly share their
        upper tests; a test reached by the same path (the same tests, answered
        the same way) splits the same pairs with the same bindings in every
        tree, so it is evaluated once per call and shared.
        """
        if not self.trees:
            raise RelationalError("tree ensemble: no tree to evaluate")
        p = np.arange(mdp.n_pairs) if pairs is None else np.asarray(pairs, dtype=np.int64)
        out = np.zeros(p.size)
        chunk = max(1, 2_000_000 // max(1, len(mdp.domain.objects) ** 3))
        for lo in range(0, p.size, chunk):
            sl = slice(lo, lo + chunk)
            root = Batch.start(mdp, p[sl])
            cache: dict[tuple[_Path, tuple[object, ...]], tuple[Any, ...]] = {}
            for tree in self.trees:
                out[sl] += self._eval(tree, tree.root, root, [], (), cache)
        return out / len(self.trees)

    @staticmethod
    def _eval(
        tree: RelationalTree,
        node: Node,
        batch: Batch,
        vars_: list[str],
        path: _Path,
        cache: dict[tuple[_Path, tuple[object, ...]], tuple[Any, ...]],
    ) -> NDArray[np.float64]:
        """As :meth:`.tilde.RelationalTree._eval`, the splits memoised by path and test."""
        if node.test is None or node.yes is None or node.no is None:
            return np.full(batch.pairs.size, node.value)
        key = (path, (tree.distinct_from_args, *node.test))
        if key not in cache:
            b, v = batch.bindings, list(vars_)
            for atom in node.test:
                b, v = extend(
                    batch.with_bindings(b), v, atom, distinct_from_args=tree.distinct_from_args
                )
            ok = satisfied(b)
            cache[key] = (ok, batch.subset(ok, b), v, batch.subset(~ok))
        ok, yes, v, no = cache[key]
        out = np.empty(batch.pairs.size)
        test = key[1]
        if ok.any():
            out[ok] = TreeEnsemble._eval(tree, node.yes, yes, v, (*path, (test, True)), cache)
        if (~ok).any():
            out[~ok] = TreeEnsemble._eval(
                tree, node.no, no, list(vars_), (*path, (test, False)), cache
            )
        return out

    def depth(self) -> int:
        """Number of tests on the longest path of any tree."""
        return max((t.depth() for t in self.trees), default=0)

    def __str__(self) -> str:
        parts = [f"mean of {len(self.trees)} bagged trees"]
        for k, tree in enumerate(self.trees):
            parts.append(f"tree {k}:\n{tree}")
        return "\n".join(parts)


def bootstrap_weights(
    weights: NDArray[np.float64], rng: np.random.Generator
) -> NDArray[np.float64]:
    """``weights`` times the draw count of each example in one bootstrap sample, shape (n,)."""
    n = weights.size
    counts = np.bincount(rng.integers(0, n, n), minlength=n)
    return weights * counts


def fit_bagged_tree(
    examples: Sequence[tuple[GroundMDP, NDArray[np.int64]]],
    y: NDArray[np.float64],
    *,
    n_trees: int,
    rng: np.random.Generator,
    weights: NDArray[np.float64] | None = None,
    **tree: Any,
) -> TreeEnsemble:
    """``n_trees`` trees (:func:`.tilde.fit_tree` with the options ``tree``) on bootstrap samples.

    Parameters
    ----------
    examples : sequence of (GroundMDP, ndarray of int, shape (n_g,))
        Pairs of one or several grounded MDPs.
    y : ndarray, shape (sum n_g,)
        Targets, in the order of ``examples``.
    n_trees : int
        Bootstrap samples B (≥ 1).
    rng : numpy.random.Generator
        Draws the samples.
    weights : ndarray, shape (sum n_g,), optional
        Example weights before resampling (ones by default).

    Raises
    ------
    RelationalError
        If ``n_trees`` < 1 or ``y`` does not match the examples.
    """
    if n_trees < 1:
        raise RelationalError(f"bagging: n_trees must be >= 1, got {n_trees}")
    n = sum(np.asarray(p).size for _, p in examples)
    y = np.asarray(y, dtype=np.float64)
    if y.shape != (n,):
        raise RelationalError(f"bagging: {n} examples but {y.size} targets")
    w = np.ones(n) if weights is None else np.asarray(weights, dtype=np.float64)
    trees = [
        fit_tree(examples, y, weights=bootstrap_weights(w, rng), **tree) for _ in range(n_trees)
    ]
    return TreeEnsemble(trees)
