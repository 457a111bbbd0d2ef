"""Relational classification and regression trees (TILDE, Blockeel & De Raedt 1998).

An example is a (state, ground action) pair of a grounded MDP. Each inner node
tests a first-order conjunction: the conjunction on the path from the root (the
tests answered *yes*) extended by the node's atoms must be satisfiable in the
state. Variables ``A0, A1...`` are the action's arguments; ``X0, X1...`` are
existentially quantified, introduced by the node that first uses them; distinct
variables bind distinct objects (object identity, as in the action rules). The
special atom ``@action(name)`` tests the action's name.

Tests are evaluated on whole batches of pairs at once: a node keeps, per pair,
the boolean tensor of the bindings of its free variables that satisfy its
conjunction, shape ``(n_pairs,) + (n_objects,) * n_vars``; adding an atom is one
fancy-indexing of the predicate's truth table of the grounded MDP.

A classification tree (labels ±1, Gini impurity) is the regression tree of the
labels: for two classes the Gini impurity is half the variance of ±1 labels, and
the leaf's value, the mean label, is its class-vote margin.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from itertools import product

import numpy as np
from numpy.typing import NDArray
from scipy import stats

from thirdhand.relational.logic import Atom, RelationalError
from thirdhand.relational.mdp import GroundMDP

Bindings = NDArray[np.bool_]


@dataclass
class Node:
    """A tree node: a leaf when ``test`` is None.

    Attributes
    ----------
    test : tuple of Atom or None
        Atoms added to the conjunction of the path (the *yes* branch keeps them).
    value : float
        Weighted mean target of the training examples that reached the node.
    yes, no : Node or None
    n : int
        Training examples that reached the node.
    """

    test: tuple[Atom, ...] | None
    value: float
    yes: Node | None = None
    no: Node | None = None
    n: int = 0


@dataclass
class Batch:
    """Pairs of one grounded MDP and the bindings of the current conjunction's variables.

    ``states``, ``kinds`` (shape (n,)) and ``args`` (shape (n, max_arity)) are the
    pairs' state, action kind and argument indices, gathered once.
    """

    mdp: GroundMDP
    pairs: NDArray[np.int64]
    bindings: Bindings
    states: NDArray[np.int64] | None = None
    kinds: NDArray[np.int64] | None = None
    args: NDArray[np.int64] | None = None

    def __post_init__(self) -> None:
        if self.states is None:
            self.states = self.mdp.pair_state[self.pairs]
        if self.kinds is None:
            self.kinds = self.mdp.pair_kind[self.pairs]
        if self.args is None:
            self.args = self.mdp.pair_args[self.pairs]

    @classmethod
    def start(cls, mdp: GroundMDP, pairs: NDArray[np.int64]) -> Batch:
        """The root batch: no variable, every pair satisfies the empty conjunction."""
        p = np.asarray(pairs, dtype=np.int64)
        return cls(mdp, p, np.ones(p.size, dtype=bool))

    def with_bindings(self, bindings: Bindings) -> Batch:
        """The same pairs with other bindings."""
        return Batch(self.mdp, self.pairs, bindings, self.states, self.kinds, self.args)

    def subset(self, mask: NDArray[np.bool_], bindings: Bindings | None = None) -> Batch:
        """The pairs where ``mask`` holds, with new or current bindings."""
        b = self.bindings if bindings is None else bindings
        assert self.states is not None and self.kinds is not None and self.args is not None
        return Batch(
            self.mdp,
            self.pairs[mask],
            b[mask],
            self.states[mask],
            self.kinds[mask],
            self.args[mask],
        )


def _new_vars(atom: Atom, vars_: Sequence[str]) -> list[str]:
    out: list[str] = []
    for a in atom.args:
        if a.startswith("X") and a not in vars_ and a not in out:
            out.append(a)
    return out


def extend(
    batch: Batch, vars_: Sequence[str], atom: Atom, *, distinct_from_args: bool = True
) -> tuple[Bindings, list[str]]:
    """Bindings after adding ``atom`` to the conjunction, and the new variable list.

    Parameters
    ----------
    batch : Batch
        Bindings of shape ``(n,) + (n_objects,) * len(vars_)``.
    vars_ : sequence of str
        Free variables, in axis order.
    atom : Atom
        Arguments are ``A<j>`` (action argument j), existing or new ``X<k>`` variables.
    distinct_from_args : bool
        Object identity also between the new variables and the action's
        arguments (else only among the ``X`` variables, so that a test of the
        state alone, such as ``on(X0,X1), on(X2,X1)``, means the same for every
        action).

    Returns
    -------
    bindings : ndarray of bool, shape ``(n,) + (n_objects,) * len(new_vars)``
    new_vars : list of str
    """
    mdp, n = batch.mdp, batch.pairs.size
    assert batch.states is not None and batch.kinds is not None and batch.args is not None
    new = _new_vars(atom, vars_)
    all_vars = [*vars_, *new]
    k = len(all_vars)
    shape = (n,) + (1,) * k
    b = batch.bindings.reshape(batch.bindings.shape + (1,) * len(new))
    if atom.pred == "@action":
        names = [a.name for a in mdp.domain.actions]
        kind = names.index(atom.args[0]) if atom.args[0] in names else -1
        return b & (batch.kinds == kind).reshape(shape), all_vars
    table = mdp.tables.get(atom.pred)
    if table is None or table.ndim != len(atom.args) + 1:
        return np.zeros(b.shape[:1] + b.shape[1:], dtype=bool), all_vars
    n_obj = len(mdp.domain.objects)
    idx: list[NDArray[np.int64]] = [batch.states.reshape(shape)]
    valid: NDArray[np.bool_] | None = None
    for arg in atom.args:
        if arg.startswith("A"):
            j = int(arg[1:])
            col = batch.args[:, j] if j < batch.args.shape[1] else np.full(n, -1)
            ok = (col >= 0).reshape(shape)
            valid = ok if valid is None else valid & ok
            idx.append(np.maximum(col, 0).reshape(shape))
        else:
            ax = all_vars.index(arg)
            sh = [1] * (k + 1)
            sh[ax + 1] = n_obj
            idx.append(np.arange(n_obj).reshape(sh))
    out = b & table[tuple(idx)]
    if valid is not None:
        out &= valid
    # Object identity: a new variable binds an object distinct from every other
    # variable's and from the action's arguments.
    for v in new:
        ax = all_vars.index(v)
        sh = [1] * (k + 1)
        sh[ax + 1] = n_obj
        mine = np.arange(n_obj).reshape(sh)
        for other in all_vars:
            if other != v:
                sh2 = [1] * (k + 1)
                sh2[all_vars.index(other) + 1] = n_obj
                out &= mine != np.arange(n_obj).reshape(sh2)
        if distinct_from_args:
            for j in range(batch.args.shape[1]):
                out &= mine != batch.args[:, j].reshape(shape)
    return out, all_vars


def satisfied(bindings: Bindings) -> NDArray[np.bool_]:
    """Per pair: does some binding satisfy the conjunction, shape (n,)."""
    if bindings.shape[0] == 0:
        return np.zeros(0, dtype=bool)
    return np.asarray(bindings.reshape(bindings.shape[0], -1).any(axis=1), dtype=bool)


def candidates(
    predicates: dict[str, int],
    actions: Sequence[str],
    n_action_args: int,
    vars_: Sequence[str],
    max_vars: int,
    *,
    lookahead: int = 1,
) -> list[tuple[Atom, ...]]:
    """Refinements of a conjunction with free variables ``vars_``.

    One atom with arguments among the action's, the existing variables and up to
    ``max_vars - len(vars_)`` new ones. For an atom introducing variables, also
    its conjunction with a second atom on a new variable (TILDE's lookahead):
    ``lookahead=1`` a unary atom on each new variable, ``lookahead=2`` any atom
    that uses a new variable (its other arguments: the action's, the bound
    variables, the atom's new variables or, within ``max_vars``, one more new
    variable), so that a chain such as ``on(X0,X1), on(X1,X2)`` or a test
    ``on(A1,X0), on(X0,X1)`` takes one node. ``lookahead=0``: single atoms only.
    """
    return list(
        _candidates(
            tuple(predicates.items()),
            tuple(actions),
            n_action_args,
            tuple(vars_),
            max_vars,
            lookahead,
        )
    )


@lru_cache(maxsize=256)
def _candidates(
    pred_items: tuple[tuple[str, int], ...],
    actions: tuple[str, ...],
    n_action_args: int,
    vars_: tuple[str, ...],
    max_vars: int,
    lookahead: int,
) -> tuple[tuple[Atom, ...], ...]:
    # Every node of every tree asks for the same few lists (they depend on the
    # bound variables only): built once per process.
    predicates = dict(pred_items)
    out: list[tuple[Atom, ...]] = [(Atom("@action", (a,)),) for a in actions]
    act = [f"A{j}" for j in range(n_action_args)]
    unary = [p for p, k in predicates.items() if k == 1]
    k0 = len(vars_)
    for pred, arity in sorted(predicates.items()):
        for args in product([*act, *vars_, "new1", "new2"], repeat=arity):
            if "new2" in args and "new1" not in args:
                continue
            n_new = ("new1" in args) + ("new2" in args)
            if k0 + n_new > max_vars:
                continue
            if (
                len(set(a for a in args if a.startswith("new"))) != n_new
                or args.count("new1") > 1
                or args.count("new2") > 1
            ):
                continue
            names = {"new1": f"X{k0}", "new2": f"X{k0 + 1}"}
            atom = Atom(pred, tuple(names.get(a, a) for a in args))
            out.append((atom,))
            if n_new == 0 or lookahead <= 0:
                continue
            fresh = [names[nv] for nv in ("new1", "new2")[:n_new]]
            if lookahead == 1:
                out.extend((atom, Atom(u, (v,))) for v in fresh for u in unary if u != pred)
                continue
            bound = [*vars_, *fresh]
            extra = [f"X{k0 + n_new}"] if k0 + n_new < max_vars else []
            seen = {atom}
            for pred2, arity2 in sorted(predicates.items()):
                for args2 in product([*act, *bound, *extra], repeat=arity2):
                    if not set(args2) & set(fresh) or len(set(args2)) != arity2:
                        continue
                    second = Atom(pred2, args2)
                    if second not in seen:
                        seen.add(second)
                        out.append((atom, second))
    return tuple(out)


@dataclass
class RelationalTree:
    """A fitted relational tree; :meth:`predict` evaluates it on pairs of any grounded MDP."""

    root: Node
    distinct_from_args: bool = True

    def predict(
        self, mdp: GroundMDP, pairs: NDArray[np.int64] | None = None
    ) -> NDArray[np.float64]:
        """The tree's value for each pair, shape (n,) (all pairs of ``mdp`` by default)."""
        p = np.arange(mdp.n_pairs) if pairs is None else np.asarray(pairs, dtype=np.int64)
        out = np.empty(p.size)
        chunk = max(1, 2_000_000 // max(1, len(mdp.domain.objects) ** 3))
        for lo in range(0, p.size, chunk):
            sl = slice(lo, lo + chunk)
            out[sl] = self._eval(self.root, Batch.start(mdp, p[sl]), [])
        return out

    def _eval(self, node: Node, batch: Batch, vars_: list[str]) -> NDArray[np.float64]:
        if node.test is None or node.yes is None or node.no is None:
            return np.full(batch.pairs.size, node.value)
        b, v = batch.bindings, list(vars_)
        for atom in node.test:
            b, v = extend(
                batch.with_bindings(b), v, atom, distinct_from_args=self.distinct_from_args
            )
        ok = satisfied(b)
        out = np.empty(batch.pairs.size)
        if ok.any():
            out[ok] = self._eval(node.yes, batch.subset(ok, b), v)
        if (~ok).any():
            out[~ok] = self._eval(node.no, batch.subset(~ok), list(vars_))
        return out

    def depth(self) -> int:
        """Number of tests on the longest path."""

        def d(n: Node | None) -> int:
            return 0 if n is None or n.test is None else 1 + max(d(n.yes), d(n.no))

        return d(self.root)

    def __str__(self) -> str:
        lines: list[str] = []

        def rec(n: Node, indent: str) -> None:
            if n.test is None or n.yes is None or n.no is None:
                lines.append(f"{indent}-> {n.value:.4g} (n={n.n})")
                return
            lines.append(f"{indent}{', '.join(map(str, n.test))} ?")
            rec(n.yes, indent + "  yes: ")
            rec(n.no, indent + "  no:  ")

        rec(self.root, "")
        return "\n".join(lines)


def _split_sse(
    m: NDArray[np.bool_],
    w: NDArray[np.float64],
    wy: NDArray[np.float64],
    sq: float,
    total_w: float,
    total_s: float,
) -> float:
    """Weighted sum of squared deviations from each side's mean for the split ``m``.

    ``wy`` is ``w * y``; ``sq``, ``total_w``, ``total_s`` are Σ w y², Σ w and Σ w y.
    """
    mf = m.astype(np.float64)
    w1, s1 = float(w @ mf), float(wy @ mf)
    w0, s0 = total_w - w1, total_s - s1
    out = sq
    if w1 > 0:
        out -= s1 * s1 / w1
    if w0 > 0:
        out -= s0 * s0 / w0
    return out


def _significant(sse_before: float, sse_after: float, n: int, alpha: float) -> bool:
    """F-test of a binary split: does it explain significantly more than the mean?"""
    if n <= 2 or sse_before <= 0:
        return False
    if sse_after <= 1e-12 * sse_before:
        return True
    f = (sse_before - sse_after) / (sse_after / (n - 2))
    return bool(stats.f.sf(f, 1, n - 2) < alpha)


def fit_tree(
    examples: Sequence[tuple[GroundMDP, NDArray[np.int64]]],
    y: NDArray[np.float64],
    *,
    weights: NDArray[np.float64] | None = None,
    max_depth: int = 4,
    max_vars: int = 3,
    min_leaf: int = 1,
    classification: bool = False,
    lookahead: int = 1,
    significance: float | None = None,
    distinct_from_args: bool = True,
) -> RelationalTree:
    """Top-down induction of a relational regression (or classification) tree.

    Parameters
    ----------
    examples : sequence of (GroundMDP, ndarray of int, shape (n_g,))
        Pairs of one or several grounded MDPs (sharing predicate names).
    y : ndarray, shape (sum n_g,)
        Targets (classification: labels ±1), in the order of ``examples``.
    weights : ndarray, shape (sum n_g,), optional
    max_depth : int
        Tests on the longest path.
    max_vars : int
        Most free variables in a conjunction.
    min_leaf : int
        Fewest examples in a leaf.
    classification : bool
        Check that the labels are ±1 (the split criterion, Gini, is then variance).
    lookahead : int
        Second atom a node may add with an atom introducing variables
        (see :func:`candidates`).
    significance : float, optional
        TILDE's stopping criterion for regression trees: keep the best split
        only when an F-test of its variance reduction is significant at this
        level (F(1, n − 2) on the node's n examples); None: any reduction.
    distinct_from_args : bool
        Object identity between the tests' variables and the action's arguments
        (see :func:`extend`).

    Raises
    ------
    RelationalError
        If ``y`` does not match the examples, or a classification label is not ±1.
    """
    y = np.asarray(y, dtype=np.float64)
    n = sum(np.asarray(p).size for _, p in examples)
    if y.shape != (n,):
        raise RelationalError(f"tree: {n} examples but {y.size} targets")
    if classification and not np.all(np.isin(y, (-1.0, 1.0))):
        raise RelationalError("classification tree: labels must be -1 or +1")
    w = np.ones(n) if weights is None else np.asarray(weights, dtype=np.float64)
    if not examples:
        raise RelationalError("tree: no examples")
    predicates = dict(examples[0][0].domain.predicates)
    actions: list[str] = []
    n_args = 0
    for mdp, _ in examples:
        predicates.update(mdp.domain.predicates)
        actions += [a.name for a in mdp.domain.actions if a.name not in actions]
        n_args = max(n_args, max(len(a.params) for a in mdp.domain.actions))
    batches = [Batch.start(m, p) for m, p in examples]
    oi = distinct_from_args

    def leaf(yy: NDArray[np.float64], ww: NDArray[np.float64]) -> Node:
        return Node(None, float((ww * yy).sum() / ww.sum()) if ww.sum() > 0 else 0.0, n=yy.size)

    def grow(
        bs: list[Batch],
        vars_: list[str],
        yy: NDArray[np.float64],
        ww: NDArray[np.float64],
        depth: int,
    ) -> Node:
        node = leaf(yy, ww)
        if depth >= max_depth or yy.size < 2 * min_leaf or np.ptp(yy) == 0:
            return node
        wy = ww * yy
        total_w, total_s = float(ww.sum()), float(wy.sum())
        sq = float((wy * yy).sum())
        base = sq - total_s**2 / total_w if total_w > 0 else 0.0
        best: (
            tuple[float, tuple[Atom, ...], list[Bindings], list[str], NDArray[np.bool_]] | None
        ) = None
        # Lookahead candidates follow their first atom: keep its bindings.
        prefix: tuple[tuple[Atom, ...], list[Bindings], list[str]] = (
            (),
            [b.bindings for b in bs],
            vars_,
        )
        for cand in candidates(predicates, actions, n_args, vars_, max_vars, lookahead=lookahead):
            if cand[:-1] != prefix[0]:
                pb, pv = [b.bindings for b in bs], list(vars_)
                for atom in cand[:-1]:
                    nb = []
                    for bt, b in zip(bs, pb, strict=True):
                        b2, v2 = extend(bt.with_bindings(b), pv, atom, distinct_from_args=oi)
                        nb.append(b2)
                    pb, pv = nb, v2
                prefix = (cand[:-1], pb, pv)
            new_b: list[Bindings] = []
            v: list[str] = list(prefix[2])
            for bt, b in zip(bs, prefix[1], strict=True):
                b2, v = extend(bt.with_bindings(b), prefix[2], cand[-1], distinct_from_args=oi)
                new_b.append(b2)
            m = np.concatenate([satisfied(b) for b in new_b])
            k = int(m.sum())
            if k < min_leaf or yy.size - k < min_leaf:
                continue
            score = _split_sse(m, ww, wy, sq, total_w, total_s)
            if score < base - 1e-9 and (best is None or score < best[0] - 1e-9):
                best = (score, cand, new_b, v, m)
        if best is None:
            return node
        if significance is not None and not _significant(base, best[0], yy.size, significance):
            return node
        _, cand, new_b, v, m = best
        yes_bs, no_bs, lo = [], [], 0
        for bt, b in zip(bs, new_b, strict=True):
            mm = m[lo : lo + bt.pairs.size]
            lo += bt.pairs.size
            yes_bs.append(bt.subset(mm, b))
            no_bs.append(bt.subset(~mm))
        node.test = cand
        node.yes = grow(yes_bs, v, yy[m], ww[m], depth + 1)
        node.no = grow(no_bs, list(vars_), yy[~m], ww[~m], depth + 1)
        return node

    return RelationalTree(grow(batches, [], y, w, 0), distinct_from_args=oi)
