"""Bagged reward trees and the choice of a learned reward by the demonstrations alone."""

from __future__ import annotations

import numpy as np
import pytest

from thirdhand.relational.bagging import TreeEnsemble, bootstrap_weights, fit_bagged_tree
from thirdhand.relational.boosting import fit_boosted
from thirdhand.relational.csi import fit_rcsi
from thirdhand.relational.data import expert_pairs, random_pairs, wait_kind
from thirdhand.relational.domains.blocks import blocks_mdp, blocks_reward, tower_heights
from thirdhand.relational.logic import RelationalError
from thirdhand.relational.mdp import GroundMDP
from thirdhand.relational.selection import demo_episodes, demo_score, select_reward

GAMMA = 0.9


def _noisy_stack_targets(mdp: GroundMDP, seed: int) -> np.ndarray:
    return blocks_reward(mdp, "stack") + 0.3 * np.random.default_rng(seed).standard_normal(
        mdp.n_pairs
    )


def test_bootstrap_weights_are_draw_counts() -> None:
    w = np.linspace(0.5, 2.0, 50)
    bw = bootstrap_weights(w, np.random.default_rng(0))
    counts = bw / w
    np.testing.assert_allclose(counts, np.round(counts))
    assert counts.min() >= 0 and counts.sum() == pytest.approx(50)
    assert (counts == 0).any()  # P(every example drawn) = 50!/50^50


def test_ensemble_is_the_mean_of_its_trees() -> None:
    # The shared evaluation of common paths must give each tree's own value.
    mdp = blocks_mdp(4)
    pairs = np.arange(mdp.n_pairs)
    ens = fit_bagged_tree(
        [(mdp, pairs)],
        _noisy_stack_targets(mdp, 1),
        n_trees=6,
        rng=np.random.default_rng(2),
        max_depth=3,
        max_vars=3,
        lookahead=2,
        distinct_from_args=False,
    )
    assert len(ens.trees) == 6 and ens.depth() == 3
    # Bootstrap samples differ, so do some trees; they share their root test.
    assert len({str(t) for t in ens.trees}) > 1
    assert len({t.root.test for t in ens.trees}) < 6
    for mdp_eval in (mdp, blocks_mdp(5)):
        each = np.mean([t.predict(mdp_eval) for t in ens.trees], axis=0)
        np.testing.assert_allclose(ens.predict(mdp_eval), each, rtol=0, atol=1e-12)
    some = np.arange(3, mdp.n_pairs, 7)
    np.testing.assert_allclose(ens.predict(mdp, some), ens.predict(mdp)[some], atol=1e-12)
    assert str(ens).startswith("mean of 6 bagged trees")


def test_bagging_bad_input() -> None:
    mdp = blocks_mdp(3)
    pairs = np.arange(mdp.n_pairs)
    with pytest.raises(RelationalError, match="n_trees must be >= 1"):
        fit_bagged_tree(
            [(mdp, pairs)], np.zeros(mdp.n_pairs), n_trees=0, rng=np.random.default_rng(0)
        )
    with pytest.raises(RelationalError, match="examples but 3 targets"):
        fit_bagged_tree([(mdp, pairs)], np.zeros(3), n_trees=2, rng=np.random.default_rng(0))
    with pytest.raises(RelationalError, match="no tree"):
        TreeEnsemble().predict(mdp)


def test_fit_rcsi_bags_the_reward_tree() -> None:
    mdp = blocks_mdp(4)
    r = blocks_reward(mdp, "unstack")
    rng = np.random.default_rng(3)
    e, d = expert_pairs(mdp, r, 10, rng), random_pairs(mdp, 100, rng)
    q = fit_boosted([(mdp, e)], n_trees=10)
    kw = {"q": q, "shaping": "advantage", "seed": 7}
    one = fit_rcsi([(mdp, e)], [(mdp, d)], **kw)  # type: ignore[arg-type]
    bag = fit_rcsi([(mdp, e)], [(mdp, d)], reward_bagging=4, **kw)  # type: ignore[arg-type]
    assert isinstance(bag.reward, TreeEnsemble) and len(bag.reward.trees) == 4
    assert not isinstance(one.reward, TreeEnsemble)
    again = fit_rcsi([(mdp, e)], [(mdp, d)], reward_bagging=4, **kw)  # type: ignore[arg-type]
    np.testing.assert_array_equal(again.reward_of(mdp), bag.reward_of(mdp))  # seeded
    with pytest.raises(RelationalError, match="reward_bagging must be >= 0"):
        fit_rcsi([(mdp, e)], [(mdp, d)], reward_bagging=-1, **kw)  # type: ignore[arg-type]


def _expert(n: int, task: str, seed: int, noise: float = 0.0) -> tuple[GroundMDP, np.ndarray]:
    mdp = blocks_mdp(n)
    return mdp, expert_pairs(
        mdp, blocks_reward(mdp, task), 15, np.random.default_rng(seed), noise=noise
    )


def test_demo_episodes_follow_the_transitions() -> None:
    for noise in (0.0, 0.4):
        mdp, e = _expert(4, "stack", 11, noise)
        eps = demo_episodes(mdp, e)
        np.testing.assert_array_equal(np.concatenate(eps), e)
        wait = wait_kind(mdp)
        for ep in eps:
            assert np.array_equal(mdp.pair_next[ep[:-1]], mdp.pair_state[ep[1:]])
            assert mdp.pair_kind[ep[-1]] == wait
        # An episode is cut only where the next pair does not start where the last one led
        # (an expert that starts again in the goal it just rested in continues the episode).
        assert 1 <= len(eps) <= 15
        inner_waits = sum(int((mdp.pair_kind[ep[:-1]] == wait).sum()) for ep in eps)
        assert (inner_waits > 0) == (noise > 0)
    assert demo_episodes(mdp, np.zeros(0, dtype=np.int64)) == []


def test_demo_score_reference_values() -> None:
    mdp, e = _expert(4, "stack", 5)
    eps = demo_episodes(mdp, e)
    # The task's own reward reproduces every demonstration as fast as the expert: 1.
    score, n = demo_score(mdp, blocks_reward(mdp, "stack"), e, GAMMA)
    assert (score, n) == (pytest.approx(1.0), len(eps))
    # The opposite task rests on the floor, where the expert never rested: 0.
    assert demo_score(mdp, blocks_reward(mdp, "unstack"), e, GAMMA)[0] == 0.0
    # A reward for waiting anywhere: only episodes that start in a single tower score
    # (then t = t_E = 0), by brute force over the episodes.
    waits = (mdp.pair_kind == wait_kind(mdp)).astype(float)
    start_done = [len(tower_heights(mdp.states[int(mdp.pair_state[ep[0]])])) == 1 for ep in eps]
    assert demo_score(mdp, waits, e, GAMMA)[0] == pytest.approx(np.mean(start_done))
    assert 0.0 < np.mean(start_done) < 1.0
    # A detour costs γ per extra move: waiting is paid only in the tower of b1 on b2 on ….
    ordered = _ordered_tower_reward(mdp)
    want = []
    for ep in eps:
        s = mdp.states[int(mdp.pair_state[ep[0]])]
        t_e = int((mdp.pair_kind[ep] != wait_kind(mdp)).sum())
        want.append(GAMMA ** max(0, _moves_to_ordered_tower(mdp, mdp.index[s], 4) - t_e))
    assert demo_score(mdp, ordered, e, GAMMA)[0] == pytest.approx(np.mean(want))
    assert np.mean(want) < 1.0


def _ordered_tower_reward(mdp: GroundMDP) -> np.ndarray:
    wait = wait_kind(mdp)
    goal = [
        all(f"on(b{k},b{k + 1})" in {str(a) for a in mdp.states[s]} for k in range(1, 4))
        for s in range(mdp.n_states)
    ]
    return np.array(
        [
            float(mdp.pair_kind[p] == wait and goal[int(mdp.pair_state[p])])
            for p in range(mdp.n_pairs)
        ]
    )


def _moves_to_ordered_tower(mdp: GroundMDP, start: int, n: int) -> int:
    """Fewest moves to the tower b1 on b2 on … on bn (bn on the floor), by breadth-first search."""
    target = {f"on(b{k},b{k + 1})" for k in range(1, n)}
    dist = {start: 0}
    frontier = [start]
    while frontier:
        nxt = []
        for s in frontier:
            if target <= {str(a) for a in mdp.states[s]}:
                return dist[s]
            for p in range(int(mdp.ptr[s]), int(mdp.ptr[s + 1])):
                s2 = int(mdp.pair_next[p])
                if s2 not in dist:
                    dist[s2] = dist[s] + 1
                    nxt.append(s2)
        frontier = nxt
    raise AssertionError("the ordered tower is reachable from every state")


def test_select_reward_prefers_the_demonstrated_task_and_ties_go_first() -> None:
    expert = [_expert(3, "stack", 1), _expert(4, "stack", 2)]

    def stack(m: GroundMDP) -> np.ndarray:
        return blocks_reward(m, "stack")

    def unstack(m: GroundMDP) -> np.ndarray:
        return blocks_reward(m, "unstack")

    best, scores = select_reward([unstack, stack, stack], expert, GAMMA)
    assert best == 1 and scores == pytest.approx([0.0, 1.0, 1.0])
    best, _ = select_reward([stack, unstack], expert, GAMMA)
    assert best == 0
    with pytest.raises(RelationalError, match="no candidate"):
        select_reward([], expert, GAMMA)
    mdp = expert[0][0]
    no_wait = np.array([p for p in expert[0][1] if mdp.pair_kind[p] != wait_kind(mdp)][:1])
    with pytest.raises(RelationalError, match="no expert episode"):
        select_reward([stack], [(mdp, no_wait)], GAMMA)
