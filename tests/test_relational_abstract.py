"""Planning over relational configurations: exact cross-checks against grounded value iteration."""

from __future__ import annotations

import zlib
from collections.abc import Callable

import numpy as np
import pytest

from thirdhand.relational.abstract import (
    abstract_mdp,
    abstract_perf,
    abstract_values,
    ground_action,
    plan_perf,
    policy_values,
    quickest_policy,
)
from thirdhand.relational.domains.blocks import (
    blocks_configs,
    blocks_domain,
    blocks_grounding,
    blocks_mdp,
    blocks_reward,
    optimal_steps,
    tower_heights,
)
from thirdhand.relational.domains.chair import (
    chair_configs,
    chair_domain,
    chair_grounding,
    chair_mdp,
    chair_reward,
    chair_signature,
)
from thirdhand.relational.logic import Atom, RelationalError
from thirdhand.relational.mdp import GroundMDP, value_iteration
from thirdhand.relational.mdp import policy_values as ground_policy_values

GAMMA = 0.9


def _blocks_reward(kind: str) -> Callable[[GroundMDP], np.ndarray]:
    return lambda mdp: blocks_reward(mdp, kind)


def _lumped_reward(mdp: GroundMDP) -> np.ndarray:
    """A reward in [-1, 0], a function of (configuration, action schema, next configuration)."""
    out = np.empty(mdp.n_pairs)
    for p in range(mdp.n_pairs):
        s = mdp.states[int(mdp.pair_state[p])]
        nxt = mdp.domain.apply(s, mdp.action(p))
        key = repr((tower_heights(s), int(mdp.pair_kind[p]), tower_heights(nxt)))
        out[p] = -(zlib.crc32(key.encode()) % 1000) / 1000.0
    return out


@pytest.mark.parametrize("kind", ["stack", "unstack"])
def test_abstract_optimal_values_match_value_iteration(kind: str) -> None:
    # 5 blocks: V* of the lumped MDP equals grounded V* in every one of the 501
    # states, and the closed form gamma^k* / (1 - gamma).
    mdp = blocks_mdp(5)
    v, _ = value_iteration(mdp, blocks_reward(mdp, kind), GAMMA)
    amdp = abstract_mdp(
        blocks_domain(5),
        blocks_configs(5),
        blocks_grounding,
        _blocks_reward(kind),
        _blocks_reward(kind),
        np.random.default_rng(0),
        n_groundings=3,
    )
    va, _ = abstract_values(amdp, amdp.true_reward, GAMMA)
    idx = {c: i for i, c in enumerate(amdp.configs)}
    got = np.array([va[idx[tower_heights(s)]] for s in mdp.states])
    np.testing.assert_allclose(got, v, atol=1e-8)
    closed = np.array([GAMMA ** optimal_steps(s, kind) / (1 - GAMMA) for s in mdp.states])
    np.testing.assert_allclose(got, closed, atol=1e-8)
    assert plan_perf(amdp, GAMMA) == pytest.approx(1.0, abs=1e-9)


def test_perf_of_a_wrong_reward_is_low() -> None:
    # The unstack reward planned, measured against stack on 5 blocks: only the
    # one-tower configuration (1 of 7) scores, and only its first step (it
    # unstacks at once): perf = (1 / 10) / 7 exactly.
    amdp = abstract_mdp(
        blocks_domain(5),
        blocks_configs(5),
        blocks_grounding,
        _blocks_reward("unstack"),
        _blocks_reward("stack"),
        np.random.default_rng(1),
        n_groundings=2,
    )
    assert plan_perf(amdp, GAMMA) == pytest.approx(1 / 70, abs=1e-9)


def test_lumped_reward_values_and_grounded_policy_match() -> None:
    # A reward of (configuration, action, next configuration) lumps exactly:
    # abstract V equals grounded V state by state; the abstract policy, grounded
    # by ground_action, has on the grounded MDP the abstract policy's true values.
    mdp = blocks_mdp(5)
    r = _lumped_reward(mdp)
    v, _ = value_iteration(mdp, r, GAMMA)
    amdp = abstract_mdp(
        blocks_domain(5),
        blocks_configs(5),
        blocks_grounding,
        _lumped_reward,
        _blocks_reward("stack"),
        np.random.default_rng(1),
        n_groundings=2,
    )
    va, qa = abstract_values(amdp, amdp.reward, GAMMA)
    idx = {c: i for i, c in enumerate(amdp.configs)}
    np.testing.assert_allclose([va[idx[tower_heights(s)]] for s in mdp.states], v, atol=1e-8)
    pol = quickest_policy(amdp, qa)
    ground_pol = np.array(
        [
            mdp.pair_of(i, ground_action(amdp, pol, _lumped_reward, s))
            for i, s in enumerate(mdp.states)
        ]
    )
    v_pi = ground_policy_values(mdp, ground_pol, blocks_reward(mdp, "stack"), GAMMA)
    va_pi = policy_values(amdp, pol, amdp.true_reward, GAMMA)
    np.testing.assert_allclose([va_pi[idx[tower_heights(s)]] for s in mdp.states], v_pi, atol=1e-8)


def test_quickest_policy_breaks_ties_towards_rest() -> None:
    # Every move pays 0 and waiting pays 0 only in the goal: every policy that
    # never waits outside the goal is optimal (cycles included); the quickest one
    # reaches the goal in the fewest moves, so its perf is exactly 1.
    def flat(mdp: GroundMDP) -> np.ndarray:
        wait = [a.name for a in mdp.domain.actions].index("wait")
        goal = blocks_reward(mdp, "stack") > 0
        return np.where(mdp.pair_kind == wait, np.where(goal, 0.0, -1.0), 0.0)

    amdp = abstract_mdp(
        blocks_domain(6),
        blocks_configs(6),
        blocks_grounding,
        flat,
        _blocks_reward("stack"),
        np.random.default_rng(2),
        n_groundings=1,
    )
    _, q = abstract_values(amdp, amdp.reward, GAMMA)
    assert abstract_perf(amdp, quickest_policy(amdp, q), GAMMA) == pytest.approx(1.0)


def _on_red_reward(mdp: GroundMDP) -> np.ndarray:
    """-1 for moving a block that stands on a red block, else 0 (a colour test, as learned)."""
    out = np.zeros(mdp.n_pairs)
    for p in range(mdp.n_pairs):
        a = mdp.action(p)
        if a.pred == "move":
            s = mdp.states[int(mdp.pair_state[p])]
            under = [f.args[1] for f in s if f.pred == "on" and f.args[0] == a.args[0]]
            out[p] = -1.0 if any(Atom("red", (u,)) in s for u in under) else 0.0
    return out


def test_lumped_reward_is_the_mean_over_groundings() -> None:
    # R̄(c, a) is a sample mean over uniform groundings of the best ground action
    # of the class; against the exact mean over every grounding of 5 blocks it is
    # within 4 standard errors (values in [-1, 0]: s.e. <= 0.5 / sqrt(n)).
    mdp = blocks_mdp(5)
    r = _on_red_reward(mdp)
    sig = [tower_heights(s) for s in mdp.states]
    exact: dict[tuple[tuple[int, ...], int, tuple[int, ...]], list[float]] = {}
    for si in range(mdp.n_states):
        best: dict[tuple[int, tuple[int, ...]], float] = {}
        for p in range(int(mdp.ptr[si]), int(mdp.ptr[si + 1])):
            key = (int(mdp.pair_kind[p]), sig[int(mdp.pair_next[p])])
            best[key] = max(best.get(key, -np.inf), float(r[p]))
        for (kind, nxt), v in best.items():
            exact.setdefault((sig[si], kind, nxt), []).append(v)
    n = 200
    amdp = abstract_mdp(
        blocks_domain(5),
        blocks_configs(5),
        blocks_grounding,
        _on_red_reward,
        _blocks_reward("stack"),
        np.random.default_rng(3),
        n_groundings=n,
    )
    spread = 0
    for p in range(amdp.n_pairs):
        key = (
            amdp.configs[int(amdp.pair_config[p])],
            int(amdp.pair_kind[p]),
            amdp.configs[int(amdp.pair_next[p])],
        )
        want = float(np.mean(exact[key]))
        spread += int(0.0 > want > -1.0)
        assert abs(amdp.reward[p] - want) <= 4 * 0.5 / np.sqrt(n), key
    assert spread > 5  # the reward does differ between groundings of a configuration


@pytest.mark.parametrize("kind", ["stack", "unstack"])
def test_large_size_smoke_true_reward_is_solved_exactly(kind: str) -> None:
    # 8 blocks (22 configurations, 1 grounding each): with the true reward the
    # planner's policy is optimal, V^pi = gamma^k* / (1 - gamma) per configuration.
    amdp = abstract_mdp(
        blocks_domain(8),
        blocks_configs(8),
        blocks_grounding,
        _blocks_reward(kind),
        _blocks_reward(kind),
        np.random.default_rng(3),
        n_groundings=1,
    )
    _, q = abstract_values(amdp, amdp.reward, GAMMA)
    pol = quickest_policy(amdp, q)
    v_pi = policy_values(amdp, pol, amdp.true_reward, GAMMA)
    k = [sum(c) - (max(c) if kind == "stack" else len(c)) for c in amdp.configs]
    np.testing.assert_allclose(v_pi, GAMMA ** np.array(k) / (1 - GAMMA), atol=1e-8)
    # the grounded policy stacks a random 8-block state in exactly k* moves
    rng = np.random.default_rng(4)
    s = blocks_grounding((2, 3, 3), rng)
    dom = blocks_domain(8)
    for _ in range(optimal_steps(s, kind)):
        s = dom.apply(s, ground_action(amdp, pol, _blocks_reward(kind), s))
    assert optimal_steps(s, kind) == 0
    assert ground_action(amdp, pol, _blocks_reward(kind), s).pred == "wait"


def test_chair_abstract_matches_grounded_value_iteration() -> None:
    mdp = chair_mdp(4)
    v, _ = value_iteration(mdp, chair_reward(mdp), GAMMA)
    amdp = abstract_mdp(
        chair_domain(4),
        chair_configs(4),
        lambda c, g: chair_grounding(4, c, g),  # type: ignore[arg-type]
        chair_reward,
        chair_reward,
        np.random.default_rng(5),
        n_groundings=3,
    )
    va, _ = abstract_values(amdp, amdp.true_reward, GAMMA)
    idx = {c: i for i, c in enumerate(amdp.configs)}
    np.testing.assert_allclose([va[idx[chair_signature(s)]] for s in mdp.states], v, atol=1e-8)
    assert plan_perf(amdp, GAMMA) == pytest.approx(1.0)


def test_groundings_are_uniform_and_have_their_configuration() -> None:
    rng = np.random.default_rng(6)
    for c in blocks_configs(6):
        assert tower_heights(blocks_grounding(c, rng)) == c
    for c in chair_configs(5):
        assert chair_signature(chair_grounding(5, c, rng)) == c
    with pytest.raises(RelationalError, match="impossible"):
        chair_grounding(3, (4, 0), rng)
    with pytest.raises(RelationalError, match="positive"):
        blocks_grounding((2, 0), rng)


def test_dynamics_that_do_not_lump_are_rejected() -> None:
    # b1 unmovable: groundings of one configuration have different successors.
    with pytest.raises(RelationalError, match=r"do not lump|not listed"):
        abstract_mdp(
            blocks_domain(4, unmovable=("b1",)),
            blocks_configs(4),
            lambda c, g: blocks_grounding(c, g) - {Atom("movable", ("b1",))},  # type: ignore[arg-type]
            _blocks_reward("stack"),
            _blocks_reward("stack"),
            np.random.default_rng(7),
        )


def test_fast_blocks_successors_equal_the_rules() -> None:
    for mdp in (blocks_mdp(5), blocks_mdp(4, unmovable=("b1",))):
        dom = mdp.domain
        for s in mdp.states:
            assert dom.successors(s) == dom.rule_successors(s)
    dom = blocks_domain(3)
    odd = blocks_grounding((3,), np.random.default_rng(0)) | {Atom("on", ("b1", "floor"))}
    assert dom.successors(odd) == dom.rule_successors(odd)
