"""Choosing among learned rewards by the demonstrations alone (no true reward).

A learned reward is judged by what its optimal policy does from where the
expert started: the expert's episodes end where the expert rests (its own
``wait``), so a reward that carries the task brings every demonstrated start
state to such a state, as quickly as the expert did. The *demonstration
score* of a reward is the mean over the expert's episodes of

    γ^max(0, t − t_E)   if the policy first waits after t moves in a state
                        of a configuration the expert rested in,
    0                   otherwise (it rests elsewhere, or never rests),

where t_E is the expert's number of moves in that episode; the policy is the
one the perf measure evaluates (value iteration on the grounded training
world, the first optimal pair, :func:`.mdp.greedy`). States are compared up to
renaming of the objects (the domain's ``signature``, when it has one; else
exactly). Only the demonstrations are used: where the expert started and
where it rested, never the task's reward.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Sequence

import numpy as np
from numpy.typing import NDArray

from thirdhand.relational.data import wait_kind
from thirdhand.relational.logic import RelationalError
from thirdhand.relational.mdp import GroundMDP, greedy, value_iteration

RewardFn = Callable[[GroundMDP], NDArray[np.float64]]


def demo_episodes(mdp: GroundMDP, expert: NDArray[np.int64]) -> list[NDArray[np.int64]]:
    """The expert's pairs split into episodes, where a pair does not continue the previous one.

    A pair continues the previous one when it starts in the state the previous
    pair leads to (a wait drawn by the expert's noise leads back to its state,
    so a noisy episode is not cut there).
    """
    p = np.asarray(expert, dtype=np.int64)
    if p.size == 0:
        return []
    cut = np.flatnonzero(mdp.pair_next[p[:-1]] != mdp.pair_state[p[1:]]) + 1
    return [e for e in np.split(p, cut) if e.size]


def demo_score(
    mdp: GroundMDP,
    reward: NDArray[np.float64],
    expert: NDArray[np.int64],
    gamma: float,
    *,
    max_steps: int = 100,
) -> tuple[float, int]:
    """The demonstration score of ``reward`` (shape (P,)) on one training world.

    Returns
    -------
    score : float
        Mean over the episodes (see the module docstring), in [0, 1].
    n : int
        Number of episodes scored (those that end with the expert's ``wait``).
    """
    wait = wait_kind(mdp)
    sig: Callable[[frozenset[object]], Hashable] = mdp.domain.signature or (lambda s: s)  # type: ignore[assignment]
    episodes = [e for e in demo_episodes(mdp, expert) if mdp.pair_kind[e[-1]] == wait]
    if not episodes:
        return 0.0, 0
    rest = {sig(mdp.states[int(mdp.pair_state[e[-1]])]) for e in episodes}
    _, q = value_iteration(mdp, reward, gamma)
    policy = greedy(mdp, q)
    total = 0.0
    for e in episodes:
        s = int(mdp.pair_state[e[0]])
        t_expert = int(np.sum(mdp.pair_kind[e] != wait))
        for t in range(max_steps + 1):
            p = int(policy[s])
            if mdp.pair_kind[p] == wait:
                if sig(mdp.states[s]) in rest:
                    total += gamma ** max(0, t - t_expert)
                break
            s = int(mdp.pair_next[p])
    return total / len(episodes), len(episodes)


def select_reward(
    rewards: Sequence[RewardFn],
    expert: Sequence[tuple[GroundMDP, NDArray[np.int64]]],
    gamma: float,
) -> tuple[int, list[float]]:
    """The reward with the best demonstration score over the training worlds.

    Parameters
    ----------
    rewards : sequence of callable
        Candidate learned rewards, ``GroundMDP -> ndarray (P,)``, in order of
        preference: ties go to the first.
    expert : sequence of (GroundMDP, ndarray of int)
        The expert's pairs per training world (``D_E``).

    Returns
    -------
    best : int
        Index of the chosen reward.
    scores : list of float
        Each candidate's score: the mean over all scored episodes of all worlds.

    Raises
    ------
    RelationalError
        No candidate, or no expert episode ending in the expert's ``wait``.
    """
    if not rewards:
        raise RelationalError("reward selection: no candidate reward")
    scores = []
    for fn in rewards:
        total, count = 0.0, 0
        for mdp, pairs in expert:
            sc, n = demo_score(mdp, fn(mdp), pairs, gamma)
            total += sc * n
            count += n
        if count == 0:
            raise RelationalError("reward selection: no expert episode ends with the expert's wait")
        scores.append(total / count)
    best = max(range(len(scores)), key=lambda i: (scores[i] > max(scores) - 1e-12, -i))
    return best, scores
