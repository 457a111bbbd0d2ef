"""Planning with a learned relational reward where grounded enumeration is impossible.

For worlds too large to enumerate (10 blocks and more), the learned reward tree
is evaluated only on the states a search reaches: receding-horizon lookahead of
depth H over the deterministic successors, each leaf valued by waiting forever
there, ``R̂(s, wait) / (1 − γ)`` (an achievable value, so the search never counts
on an unreachable loop).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from thirdhand.relational.logic import Atom
from thirdhand.relational.mdp import Domain, GroundMDP, State, state_tables

RewardFn = Callable[[GroundMDP], NDArray[np.float64]]


def expand(domain: Domain, states: Sequence[State]) -> tuple[GroundMDP, list[State]]:
    """A partial grounded MDP holding ``states`` and all their pairs.

    Returns
    -------
    mdp : GroundMDP
        ``pair_next`` indexes the returned successor list, not ``mdp.states``.
    successors : list of frozenset
        The state each pair leads to, shape (P,).
    """
    kinds = {a.name: k for k, a in enumerate(domain.actions)}
    obj = {o: i for i, o in enumerate(domain.objects)}
    arity = max(1, max(len(a.params) for a in domain.actions))
    succ = [domain.successors(s) for s in states]
    counts = np.array([len(x) for x in succ], dtype=np.int64)
    ptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    flat = [pair for lst in succ for pair in lst]
    pair_args = np.full((len(flat), arity), -1, dtype=np.int64)
    for p, (act, _) in enumerate(flat):
        pair_args[p, : len(act.args)] = [obj[x] for x in act.args]
    mdp = GroundMDP(
        domain,
        list(states),
        {s: i for i, s in enumerate(states)},
        ptr,
        np.repeat(np.arange(len(states), dtype=np.int64), counts),
        np.arange(len(flat), dtype=np.int64),
        np.array([kinds[a.pred] for a, _ in flat], dtype=np.int64),
        pair_args,
        state_tables(domain, states),
    )
    return mdp, [s for _, s in flat]


def lookahead_action(
    domain: Domain, reward: RewardFn, state: State, *, depth: int = 2, gamma: float = 0.9
) -> Atom:
    """The first action of the best depth-``depth`` plan under the learned reward."""
    wait = next(k for k, a in enumerate(domain.actions) if a.name == "wait")
    levels: list[tuple[GroundMDP, NDArray[np.float64], list[State]]] = []
    frontier = [state]
    for _ in range(depth):
        mdp, nxt = expand(domain, frontier)
        levels.append((mdp, reward(mdp), nxt))
        frontier = nxt
    mdp_leaf, _ = expand(domain, frontier)
    q = _first_q(levels, reward(mdp_leaf), mdp_leaf, wait, gamma)
    return levels[0][0].action(int(np.argmax(q)))


def rollout(
    domain: Domain,
    reward: RewardFn,
    state: State,
    *,
    depth: int = 2,
    gamma: float = 0.9,
    max_steps: int = 50,
) -> tuple[list[State], bool]:
    """States visited by the lookahead policy from ``state``, and whether it ended by waiting.

    The rollout stops at the first ``wait`` (the policy is deterministic, so it
    would wait there forever) or after ``max_steps`` moves.
    """
    out = [state]
    for _ in range(max_steps):
        act = lookahead_action(domain, reward, out[-1], depth=depth, gamma=gamma)
        if act.pred == "wait":
            return out, True
        out.append(domain.apply(out[-1], act))
    return out, False


def rollout_value(
    path: Sequence[State], waited: bool, goal: Callable[[State], bool], gamma: float
) -> float:
    """True value of a rollout under the reward 1 in goal states, 0 elsewhere.

    ``Σ_t γ^t R(s_t)``, the last state counting forever when the policy waited there.
    """
    r = np.array([float(goal(s)) for s in path])
    disc = gamma ** np.arange(len(path))
    if waited:
        return float((r[:-1] * disc[:-1]).sum() + r[-1] * disc[-1] / (1 - gamma))
    return float((r * disc).sum())


def _first_q(
    levels: list[tuple[GroundMDP, NDArray[np.float64], list[State]]],
    r_leaf: NDArray[np.float64],
    mdp_leaf: GroundMDP,
    wait: int,
    gamma: float,
) -> NDArray[np.float64]:
    """Q of the root's pairs by backing values up the levels, shape (P_0,)."""
    v = r_leaf[mdp_leaf.pair_kind == wait] / (1 - gamma)
    q = np.zeros(0)
    for mdp, r, _ in reversed(levels):
        q = r + gamma * v
        v = np.maximum.reduceat(q, mdp.ptr[:-1])
    return q
