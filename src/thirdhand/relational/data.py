"""Training data: expert trajectories of the optimal policy and random transitions."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from thirdhand.relational.mdp import GroundMDP, optimal_pairs, value_iteration


def wait_kind(mdp: GroundMDP) -> int:
    """Index of the ``wait`` action schema (-1 when the domain has none)."""
    names = [a.name for a in mdp.domain.actions]
    return names.index("wait") if "wait" in names else -1


def expert_pairs(
    mdp: GroundMDP,
    reward: NDArray[np.float64],
    n_episodes: int,
    rng: np.random.Generator,
    *,
    gamma: float = 0.9,
    noise: float = 0.0,
    max_steps: int = 100,
) -> NDArray[np.int64]:
    """Pairs visited by ``n_episodes`` expert episodes, concatenated, shape (n,).

    Each episode starts in a state drawn from P_state and follows an optimal
    action (uniformly among the optimal ones) until the expert's first ``wait``
    (included); with probability ``noise`` an action is drawn uniformly among
    the applicable ones instead. The noise corrupts actions, not the episode:
    a ``wait`` drawn by the noise is recorded and the episode goes on (the
    expert has not finished the task), so a noisy episode still ends where the
    expert rests.
    """
    _, q = value_iteration(mdp, reward, gamma)
    opt = optimal_pairs(mdp, q, tol=1e-9)
    wait = wait_kind(mdp)
    out: list[int] = []
    for s in mdp.sample_states(n_episodes, rng):
        for _ in range(max_steps):
            lo, hi = int(mdp.ptr[s]), int(mdp.ptr[s + 1])
            noisy = noise > 0 and rng.random() < noise
            if noisy:
                p = int(rng.integers(lo, hi))
            else:
                best = lo + np.flatnonzero(opt[lo:hi])
                p = int(best[rng.integers(best.size)])
            out.append(p)
            if mdp.pair_kind[p] == wait and not noisy:
                break
            s = int(mdp.pair_next[p])
    return np.asarray(out, dtype=np.int64)


def random_pairs(mdp: GroundMDP, n: int, rng: np.random.Generator) -> NDArray[np.int64]:
    """``n`` one-step transitions, shape (n,).

    Each: a state from P_state, then an applicable action uniformly.
    """
    s = mdp.sample_states(n, rng)
    lo, hi = mdp.ptr[s], mdp.ptr[s + 1]
    return (lo + np.floor(rng.random(n) * (hi - lo))).astype(np.int64)
