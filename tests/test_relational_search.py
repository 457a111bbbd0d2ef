"""Planning by lookahead with a relational reward, on worlds not enumerated."""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable

import numpy as np
import pytest

from thirdhand.relational.domains.blocks import (
    blocks_domain,
    blocks_mdp,
    blocks_reward,
    optimal_steps,
    partitions,
    random_state,
    tower_heights,
)
from thirdhand.relational.mdp import GroundMDP, value_iteration
from thirdhand.relational.search import expand, lookahead_action, rollout, rollout_value


def test_partitions_and_random_states() -> None:
    assert len(partitions(5)) == 7 and len(partitions(10)) == 42
    rng = np.random.default_rng(0)
    states = [random_state(5, rng) for _ in range(700)]
    mdp = blocks_mdp(5)
    assert all(s in mdp.index for s in states)
    counts = Counter(tower_heights(s) for s in states)
    assert len(counts) == 7 and min(counts.values()) > 70  # uniform over configurations


@pytest.mark.parametrize("kind", ["stack", "unstack"])
def test_optimal_steps_match_value_iteration(kind: str) -> None:
    mdp = blocks_mdp(5)
    v, _ = value_iteration(mdp, blocks_reward(mdp, kind), 0.9)
    steps = np.round(np.log(v * 0.1) / np.log(0.9)).astype(int)
    assert [optimal_steps(s, kind) for s in mdp.states] == steps.tolist()


def _goal_reward(kind: str) -> Callable[[GroundMDP], np.ndarray]:
    def reward(mdp: GroundMDP) -> np.ndarray:
        return blocks_reward(mdp, kind)

    return reward


@pytest.mark.parametrize("kind", ["stack", "unstack"])
def test_lookahead_with_true_reward_is_optimal(kind: str) -> None:
    # With the true reward and the goal within the horizon (4 blocks: at most 3
    # moves), lookahead plus waiting forever at the leaves is optimal.
    rng = np.random.default_rng(1)
    dom = blocks_domain(4)
    for _ in range(3):
        s = random_state(4, rng)
        path, waited = rollout(dom, _goal_reward(kind), s, depth=3, max_steps=20)
        assert waited and optimal_steps(path[-1], kind) == 0
        assert len(path) - 1 == optimal_steps(s, kind)
        value = rollout_value(path, waited, lambda x: optimal_steps(x, kind) == 0, 0.9)
        assert value == pytest.approx(0.9 ** (len(path) - 1) / 0.1)


def test_expand_matches_grounded_mdp() -> None:
    full = blocks_mdp(4)
    states = full.states[:5]
    part, succ = expand(full.domain, states)
    for i in range(5):
        a, b = full.ptr[i], full.ptr[i + 1]
        assert [full.action(p) for p in range(a, b)] == [
            part.action(p) for p in range(part.ptr[i], part.ptr[i + 1])
        ]
        assert [full.states[int(n)] for n in full.pair_next[a:b]] == succ[
            part.ptr[i] : part.ptr[i + 1]
        ]
    act = lookahead_action(full.domain, _goal_reward("unstack"), full.states[0], depth=1)
    assert act.pred == "wait"  # the all-on-floor state is the unstack goal
