"""Cascaded supervised IRL with relational trees (RCSI; Klein et al. 2013).

(1) the boosted score function ``q_C`` on expert pairs (:mod:`.boosting`);
(2) a relational regression tree fit to ``r̂ = q_C(s,a) − γ max_a' q_C(s',a')``
over ``D_E ∪ D_NE`` (expert and random one-step transitions), optionally shaped
(:mod:`.shaping`), gives the reward R̂(s, a).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from thirdhand.relational.bagging import TreeEnsemble, fit_bagged_tree
from thirdhand.relational.boosting import BoostedQ, Examples, fit_boosted
from thirdhand.relational.logic import RelationalError
from thirdhand.relational.mdp import GroundMDP
from thirdhand.relational.shaping import fit_shaping, state_features
from thirdhand.relational.tilde import RelationalTree, fit_tree


@dataclass
class RCSIModel:
    """A learned score function and reward tree.

    Attributes
    ----------
    q : BoostedQ
        The classifier's score function (BLMRIL's policy is its argmax).
    reward : RelationalTree or TreeEnsemble
        R̂(s, a): one tree, or the mean of bagged trees (``reward_bagging``).
    shaping : ndarray, shape (d,)
        Weights of the shaping function f(s) = w·φ(s) (zeros without shaping).
    """

    q: BoostedQ
    reward: RelationalTree | TreeEnsemble
    shaping: NDArray[np.float64]

    def reward_of(self, mdp: GroundMDP) -> NDArray[np.float64]:
        """R̂ on every pair of ``mdp``, shape (P,)."""
        return self.reward.predict(mdp)


def state_values(q: BoostedQ, mdp: GroundMDP, states: NDArray[np.int64]) -> NDArray[np.float64]:
    """``max_a q(s,a)`` for each of ``states``, shape (n,)."""
    u, inv = np.unique(states, return_inverse=True)
    lo, hi = mdp.ptr[u], mdp.ptr[u + 1]
    sub = np.concatenate([np.arange(a, b) for a, b in zip(lo, hi, strict=True)])
    best = np.maximum.reduceat(q.predict(mdp, sub), np.concatenate([[0], np.cumsum(hi - lo)[:-1]]))
    return best[inv]


def csi_targets(
    q: BoostedQ, mdp: GroundMDP, pairs: NDArray[np.int64], gamma: float
) -> NDArray[np.float64]:
    """``q(s,a) − γ max_a' q(s',a')`` for each pair, shape (n,)."""
    return q.predict(mdp, pairs) - gamma * state_values(q, mdp, mdp.pair_next[pairs])


def advantage_targets(q: BoostedQ, mdp: GroundMDP, pairs: NDArray[np.int64]) -> NDArray[np.float64]:
    """The targets after shaping by ``f(s) = −max_a q(s,a)``, shape (n,).

    With ``q'(s,a) = q(s,a) − max_b q(s,b)``, ``max_a' q'(s',a') = 0`` in every
    state, so ``q'(s,a) − γ max_a' q'(s',a') = q(s,a) − max_b q(s,b)`` ≤ 0.
    """
    return q.predict(mdp, pairs) - state_values(q, mdp, mdp.pair_state[pairs])


def shaping_basis(
    q: BoostedQ, mdp: GroundMDP, states: NDArray[np.int64], features: str
) -> NDArray[np.float64]:
    """Features φ(s) of the CMA-ES shaping ``f(s) = w·φ(s)``, shape (n, d).

    ``"value"``: the classifier's state value ``max_a q(s,a)`` (d = 1);
    ``"counts"``: :func:`.shaping.state_features`; ``"value+counts"``: both.
    """
    cols = []
    if "value" in features:
        cols.append(state_values(q, mdp, states)[:, None])
    if "counts" in features:
        cols.append(state_features(mdp, states))
    return np.concatenate(cols, axis=1)


def fit_rcsi(
    expert: Examples,
    random: Examples,
    *,
    gamma: float = 0.9,
    n_trees: int = 40,
    max_depth: int = 4,
    reward_depth: int = 4,
    max_vars: int = 3,
    shaping: bool | str = False,
    balance: bool = True,
    seed: int = 0,
    q: BoostedQ | None = None,
    reward_lookahead: int = 1,
    reward_min_leaf: int = 1,
    reward_significance: float | None = None,
    reward_distinct_from_args: bool = True,
    shaping_features: str = "value+counts",
    shaping_samples: str = "all",
    reward_bagging: int = 0,
) -> RCSIModel:
    """RCSI: the boosted classifier, then the regression of its implied rewards.

    Parameters
    ----------
    expert, random : sequence of (GroundMDP, ndarray of int)
        Expert pairs ``D_E`` and random one-step transitions ``D_NE`` per MDP; the
        reward is regressed on both.
    gamma : float
        Discount.
    n_trees, max_depth : int
        Boosting rounds and classification tree depth.
    reward_depth : int
        Depth of the reward tree.
    shaping : bool or {"advantage", "cma"}
        Shape the score function, ``q'(s,a) = q(s,a) + f(s)`` (same classifier
        policy), before computing the targets. ``"advantage"``: the closed form
        ``f(s) = −max_a q(s,a)``, whose targets are the advantages
        ``q(s,a) − max_a' q(s,a')`` (0 on every transition the classifier
        agrees with, the lowest-entropy targets on ``D_E``); ``"cma"`` (or
        True): the paper's shaping, f linear in relational state features
        (``shaping_features``), its weights by CMA-ES on the binned entropy of
        the targets (:mod:`.shaping`).
    balance : bool
        Weigh the regression so that ``D_E`` and ``D_NE`` count as much (the
        expert transitions are few but carry the task).
    seed : int
        Of CMA-ES.
    q : BoostedQ, optional
        An already fitted score function (step 1 is then skipped).
    reward_lookahead : int
        Lookahead of the reward tree's refinements (see :func:`.tilde.candidates`).
    reward_min_leaf : int
        Fewest transitions in a leaf of the reward tree.
    reward_significance : float, optional
        F-test level at which the reward tree stops splitting (None: never).
    reward_distinct_from_args : bool
        Object identity between the reward tree's variables and the action's
        arguments (see :func:`.tilde.extend`).
    shaping_features : {"value", "value+counts", "counts"}
        Features of the CMA-ES shaping: ``"value"`` the classifier's state value
        ``max_a q(s,a)`` (a relational function of the state: a sum of the
        boosted trees' leaves), ``"counts"`` the relational counts of
        :func:`.shaping.state_features` (the first version), or both.
    shaping_samples : {"expert", "all"}
        Transitions whose target entropy CMA-ES minimises: ``D_E`` only, or
        ``D_E ∪ D_NE`` (the regression data).
    reward_bagging : int
        With B > 1, the reward is the mean of B trees, each fit to a bootstrap
        sample of the regression data (:mod:`.bagging`, drawn with ``seed``);
        0 or 1: one tree on all of it (the paper's).
    """
    if q is None:
        q = fit_boosted(expert, n_trees=n_trees, max_depth=max_depth, max_vars=max_vars)
    by_mdp: dict[
        int,
        tuple[
            GroundMDP, list[NDArray[np.int64]], list[NDArray[np.float64]], list[NDArray[np.bool_]]
        ],
    ] = {}
    n_e = sum(np.asarray(p).size for _, p in expert)
    n_r = sum(np.asarray(p).size for _, p in random)
    w_e = n_r / n_e if balance and n_e and n_r else 1.0
    for (mdp, pairs), wk, is_e in [
        *((x, w_e, True) for x in expert),
        *((x, 1.0, False) for x in random),
    ]:
        item = by_mdp.setdefault(id(mdp), (mdp, [], [], []))
        n = np.asarray(pairs).size
        item[1].append(np.asarray(pairs, dtype=np.int64))
        item[2].append(np.full(n, wk))
        item[3].append(np.full(n, is_e))
    kept = [v for v in by_mdp.values() if sum(p.size for p in v[1])]
    data = [(m, np.concatenate(ps)) for m, ps, _, _ in kept]
    if not data:
        raise RelationalError("RCSI: no transition to regress the reward on")
    weights = np.concatenate([np.concatenate(ws) for _, _, ws, _ in kept])
    from_expert = np.concatenate([np.concatenate(fs) for _, _, _, fs in kept])
    if shaping not in (False, True, "advantage", "cma"):
        raise RelationalError(f"RCSI: unknown shaping {shaping!r}, expected advantage or cma")
    w = np.zeros(0)
    if shaping == "advantage":
        targets = np.concatenate([advantage_targets(q, m, p) for m, p in data])
    else:
        targets = np.concatenate([csi_targets(q, m, p, gamma) for m, p in data])
    if shaping is True or shaping == "cma":
        if shaping_features not in ("value", "value+counts", "counts"):
            raise RelationalError(
                f"RCSI: unknown shaping features {shaping_features!r}, "
                "expected value, value+counts or counts"
            )
        if shaping_samples not in ("expert", "all"):
            raise RelationalError(
                f"RCSI: unknown shaping samples {shaping_samples!r}, expected expert or all"
            )
        phi = np.concatenate(
            [shaping_basis(q, m, m.pair_state[p], shaping_features) for m, p in data]
        )
        phi_n = np.concatenate(
            [shaping_basis(q, m, m.pair_next[p], shaping_features) for m, p in data]
        )
        on = weights * from_expert if shaping_samples == "expert" else weights
        w = fit_shaping(phi, phi_n, targets, gamma, weights=on, seed=seed)
        targets = targets + (phi - gamma * phi_n) @ w
    if reward_bagging < 0:
        raise RelationalError(f"RCSI: reward_bagging must be >= 0, got {reward_bagging}")
    tree_options: dict[str, Any] = {
        "max_depth": reward_depth,
        "max_vars": max_vars,
        "lookahead": reward_lookahead,
        "min_leaf": reward_min_leaf,
        "significance": reward_significance,
        "distinct_from_args": reward_distinct_from_args,
    }
    reward: RelationalTree | TreeEnsemble
    if reward_bagging > 1:
        reward = fit_bagged_tree(
            data,
            targets,
            n_trees=reward_bagging,
            rng=np.random.default_rng(seed),
            weights=weights,
            **tree_options,
        )
    else:
        reward = fit_tree(data, targets, weights=weights, **tree_options)
    return RCSIModel(q, reward, w)
