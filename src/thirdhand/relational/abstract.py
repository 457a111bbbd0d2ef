"""Planning with a learned relational reward over relational configurations.

Worlds of 10 blocks and more cannot be grounded (10 blocks: 58 786 states,
15 blocks: ~10^12), but their *relational configurations* (a state up to
renaming of objects: the domain's ``signature``, e.g. the sorted tower heights)
are few: 42 for 10 blocks, 176 for 15, 627 for 20. When every grounding of a
configuration has the same successor configurations (true of the blocks and
chair worlds, whose dynamics ignore names and colours), the grounded MDP
*lumps* into an abstract MDP over configurations:

- an abstract action of configuration ``c`` is a pair (action schema, next
  configuration ``c'``): every ground action of that schema leading to ``c'``;
- its reward is ``R̄(c, a) = E_g[max R̂(s_g, α)]``, the learned reward tree R̂
  of the best ground action α of that class, averaged over ``n_groundings``
  groundings ``s_g`` of ``c`` drawn uniformly (P_state's second stage). R̂ is
  evaluated on the groundings' successors only, never on a whole grounded MDP;
- a reward that is a function of the configuration (the true stack, unstack,
  build rewards) lumps exactly, so V* of the abstract MDP is the grounded V*.

The policy is the optimal policy of R̄ (value iteration), ties among optimal
actions broken by the fewest steps to a configuration where waiting is optimal
(:func:`quickest_policy`). Grounded, it takes in state ``s`` the best ground
action (under R̂ in ``s``) of the abstract action of ``c = signature(s)``, so
its configuration path, hence its true value, is that of the abstract policy:
perf over P_state (a configuration uniformly, then a grounding) is computed
exactly on the abstract MDP (:func:`abstract_perf`).
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from thirdhand.relational.logic import Atom, RelationalError
from thirdhand.relational.mdp import Domain, State
from thirdhand.relational.search import RewardFn, expand

Sampler = Callable[[Hashable, np.random.Generator], State]


@dataclass(frozen=True)
class AbstractMDP:
    """A lumped MDP over relational configurations.

    Attributes
    ----------
    configs : list of hashable
        The C configurations.
    ptr : ndarray, shape (C + 1,), int64
        Abstract actions of configuration ``c`` are ``ptr[c]:ptr[c+1]``.
    pair_config, pair_next : ndarray, shape (A,), int64
        Configuration and next configuration of every abstract action.
    pair_kind : ndarray, shape (A,), int64
        Action schema index (into ``domain.actions``).
    reward : ndarray, shape (A,)
        ``R̄``: the learned reward of the best ground action, averaged over groundings.
    true_reward : ndarray, shape (A,)
        The true reward (constant over the groundings, checked).
    """

    domain: Domain
    configs: list[Hashable]
    ptr: NDArray[np.int64]
    pair_config: NDArray[np.int64]
    pair_next: NDArray[np.int64]
    pair_kind: NDArray[np.int64]
    reward: NDArray[np.float64]
    true_reward: NDArray[np.float64]

    @property
    def n_pairs(self) -> int:
        """Number of abstract actions A."""
        return int(self.pair_config.size)


def abstract_mdp(
    domain: Domain,
    configs: Sequence[Hashable],
    sample: Sampler,
    reward: RewardFn,
    true_reward: RewardFn,
    rng: np.random.Generator,
    *,
    n_groundings: int = 8,
) -> AbstractMDP:
    """Lump ``domain`` over ``configs`` with the learned ``reward`` and the ``true_reward``.

    Parameters
    ----------
    configs : sequence of hashable
        Every configuration (values of ``domain.signature``); successors must stay among them.
    sample : callable
        ``(config, rng) -> state``: a uniformly random grounding of a configuration.
    reward, true_reward : callable
        ``GroundMDP -> ndarray (P,)``; evaluated on the groundings and their pairs only.
    n_groundings : int
        Groundings drawn per configuration.

    Raises
    ------
    RelationalError
        No signature, a successor outside ``configs``, groundings of one
        configuration with different abstract actions (the dynamics do not
        lump), or a true reward that differs between groundings.
    """
    sig = domain.signature
    if sig is None:
        raise RelationalError(f"domain {domain.name}: no signature to lump the states by")
    if n_groundings < 1:
        raise RelationalError(f"abstract MDP: n_groundings must be >= 1, got {n_groundings}")
    index = {c: i for i, c in enumerate(configs)}
    states = [sample(c, rng) for c in configs for _ in range(n_groundings)]
    for k, s in enumerate(states):
        if sig(s) != configs[k // n_groundings]:
            raise RelationalError(
                f"abstract MDP: a grounding of {configs[k // n_groundings]} has signature {sig(s)}"
            )
    mdp, succ = expand(domain, states)
    r_hat, r_true = reward(mdp), true_reward(mdp)
    nxt = []
    for s in succ:
        c = sig(s)
        if c not in index:
            raise RelationalError(f"abstract MDP: successor configuration {c} is not listed")
        nxt.append(index[c])
    nxt_a = np.asarray(nxt, dtype=np.int64)
    ptr, p_conf, p_next, p_kind, rew, rtrue = [0], [], [], [], [], []
    for ci, c in enumerate(configs):
        per_g: list[dict[tuple[int, int], tuple[float, float]]] = []
        for g in range(n_groundings):
            si = ci * n_groundings + g
            best: dict[tuple[int, int], tuple[float, float]] = {}
            for p in range(int(mdp.ptr[si]), int(mdp.ptr[si + 1])):
                key = (int(mdp.pair_kind[p]), int(nxt_a[p]))
                old = best.get(key)
                if old is not None and old[1] != r_true[p]:
                    raise RelationalError(
                        f"abstract MDP: the true reward is not a function of the configuration {c}"
                    )
                if old is None or r_hat[p] > old[0]:
                    best[key] = (float(r_hat[p]), float(r_true[p]))
            per_g.append(best)
        keys = sorted(per_g[0])
        for g, best in enumerate(per_g[1:], start=1):
            if sorted(best) != keys:
                raise RelationalError(
                    f"abstract MDP: groundings 0 and {g} of configuration {c} have different "
                    "successor configurations (the dynamics do not lump)"
                )
            if any(best[key][1] != per_g[0][key][1] for key in keys):
                raise RelationalError(
                    f"abstract MDP: the true reward is not a function of the configuration {c}"
                )
        for key in keys:
            p_conf.append(ci)
            p_kind.append(key[0])
            p_next.append(key[1])
            rew.append(float(np.mean([b[key][0] for b in per_g])))
            rtrue.append(per_g[0][key][1])
        ptr.append(len(p_conf))
    return AbstractMDP(
        domain,
        list(configs),
        np.asarray(ptr, dtype=np.int64),
        np.asarray(p_conf, dtype=np.int64),
        np.asarray(p_next, dtype=np.int64),
        np.asarray(p_kind, dtype=np.int64),
        np.asarray(rew, dtype=np.float64),
        np.asarray(rtrue, dtype=np.float64),
    )


def abstract_values(
    amdp: AbstractMDP, reward: NDArray[np.float64], gamma: float, *, tol: float = 1e-10
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Value iteration on the abstract MDP: V shape (C,), Q shape (A,)."""
    v = np.zeros(len(amdp.configs))
    while True:
        q = reward + gamma * v[amdp.pair_next]
        nv = np.maximum.reduceat(q, amdp.ptr[:-1])
        if np.max(np.abs(nv - v)) < tol:
            return nv, q
        v = nv


def quickest_policy(
    amdp: AbstractMDP, q: NDArray[np.float64], *, tol: float = 1e-9
) -> NDArray[np.int64]:
    """An optimal policy (abstract action per configuration, shape (C,)) that rests soonest.

    Among the actions within ``tol`` of the best, a configuration where
    ``wait`` is optimal waits; elsewhere the optimal action with the fewest
    optimal steps to such a configuration is taken (the first one when tied,
    or when no optimal path rests). With a learned reward, many actions are
    often equally optimal (a reward tree of 3 variables cannot tell a tower of
    height 3 from a taller one), and the first-in-order choice can cycle
    forever among them; this rule picks, among the optimal policies, the one
    that stops soonest.
    """
    n = len(amdp.configs)
    best = np.maximum.reduceat(q, amdp.ptr[:-1])
    opt = q >= best[amdp.pair_config] - tol
    wait = _wait_kind(amdp.domain)
    is_wait = amdp.pair_kind == wait
    dist = np.full(n, np.inf)
    rest = np.zeros(n, dtype=bool)
    rest[amdp.pair_config[opt & is_wait]] = True
    dist[rest] = 0.0
    move = opt & ~is_wait
    for _ in range(n):
        cand = np.full(n, np.inf)
        np.minimum.at(cand, amdp.pair_config[move], 1.0 + dist[amdp.pair_next[move]])
        nd = np.minimum(dist, cand)
        if np.array_equal(nd, dist):
            break
        dist = nd
    policy = np.empty(n, dtype=np.int64)
    for c in range(n):
        lo, hi = int(amdp.ptr[c]), int(amdp.ptr[c + 1])
        ok = [p for p in range(lo, hi) if opt[p]]
        if rest[c]:
            policy[c] = next(p for p in ok if is_wait[p])
            continue
        after = [dist[amdp.pair_next[p]] if not is_wait[p] else np.inf for p in ok]
        policy[c] = ok[int(np.argmin(after))]
    return policy


def policy_values(
    amdp: AbstractMDP,
    policy: NDArray[np.int64],
    reward: NDArray[np.float64],
    gamma: float,
    *,
    tol: float = 1e-10,
) -> NDArray[np.float64]:
    """Values of a deterministic abstract policy under ``reward``, shape (C,)."""
    r, nxt = reward[policy], amdp.pair_next[policy]
    v = np.zeros(len(amdp.configs))
    while True:
        nv = r + gamma * v[nxt]
        if np.max(np.abs(nv - v)) < tol:
            return nv
        v = nv


def abstract_perf(amdp: AbstractMDP, policy: NDArray[np.int64], gamma: float) -> float:
    """perf over P_state: mean over configurations (uniform) of V^π / V* under the true reward.

    Exact (no sampling): the grounded policy's true value depends on the state's
    configuration only, and P_state draws the configuration uniformly.
    Configurations with V* = 0 are left out.
    """
    v_star, _ = abstract_values(amdp, amdp.true_reward, gamma)
    v_pi = policy_values(amdp, policy, amdp.true_reward, gamma)
    ok = v_star > 1e-12
    return float(np.mean(v_pi[ok] / v_star[ok])) if ok.any() else float("nan")


def plan_perf(amdp: AbstractMDP, gamma: float) -> float:
    """perf of the quickest optimal policy of the learned reward ``amdp.reward``."""
    _, q = abstract_values(amdp, amdp.reward, gamma)
    return abstract_perf(amdp, quickest_policy(amdp, q), gamma)


def ground_action(
    amdp: AbstractMDP, policy: NDArray[np.int64], reward: RewardFn, state: State
) -> Atom:
    """The grounded policy: the best ground action (under ``reward``) of the abstract action.

    Raises
    ------
    RelationalError
        When the state's configuration is not in the abstract MDP.
    """
    sig = amdp.domain.signature
    assert sig is not None
    c = sig(state)
    if c not in amdp.configs:
        raise RelationalError(f"abstract policy: configuration {c} is not in the abstract MDP")
    p = int(policy[amdp.configs.index(c)])
    mdp, succ = expand(amdp.domain, [state])
    r = reward(mdp)
    want_next = amdp.configs[int(amdp.pair_next[p])]
    ok = [
        i
        for i in range(mdp.n_pairs)
        if mdp.pair_kind[i] == amdp.pair_kind[p] and sig(succ[i]) == want_next
    ]
    return mdp.action(max(ok, key=lambda i: (r[i], -i)))


def _wait_kind(domain: Domain) -> int:
    names = [a.name for a in domain.actions]
    return names.index("wait") if "wait" in names else -1
