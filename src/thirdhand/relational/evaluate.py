"""The perf measure: ``perf(r̂) = 1/n Σ_i V_r^{π_r̂}(s_i) / V_r*(s_i)``, s_i ∼ P_state."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from thirdhand.relational.mdp import GroundMDP, greedy, policy_values, value_iteration


def perf_of_policy(
    mdp: GroundMDP,
    policy: NDArray[np.int64],
    true_reward: NDArray[np.float64],
    gamma: float,
    states: NDArray[np.int64],
) -> float:
    """Mean over ``states`` of the policy's true value over the optimal value.

    States whose optimal value is 0 (the goal is unreachable) are left out.

    Parameters
    ----------
    policy : ndarray of int, shape (S,)
        Pair chosen in each state.
    true_reward : ndarray, shape (P,)
    states : ndarray of int, shape (n,)
        Sampled state indices.
    """
    v_star, _ = value_iteration(mdp, true_reward, gamma)
    v_pi = policy_values(mdp, policy, true_reward, gamma)
    s = np.asarray(states)
    s = s[v_star[s] > 1e-12]
    return float(np.mean(v_pi[s] / v_star[s])) if s.size else float("nan")


def perf_of_reward(
    mdp: GroundMDP,
    reward: NDArray[np.float64],
    true_reward: NDArray[np.float64],
    gamma: float,
    states: NDArray[np.int64],
) -> float:
    """perf of the policy optimal for the learned ``reward`` (shape (P,))."""
    _, q = value_iteration(mdp, reward, gamma)
    return perf_of_policy(mdp, greedy(mdp, q), true_reward, gamma, states)


def perf_of_scores(
    mdp: GroundMDP,
    scores: NDArray[np.float64],
    true_reward: NDArray[np.float64],
    gamma: float,
    states: NDArray[np.int64],
) -> float:
    """perf of the policy greedy in the score function ``scores`` (shape (P,), e.g. BLMRIL's q)."""
    return perf_of_policy(mdp, greedy(mdp, scores), true_reward, gamma, states)
