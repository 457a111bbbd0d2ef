"""Relational IRL: expert data, BLMRIL, RCSI, shaping, experiments, plans, CLI."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from thirdhand.relational.assembly import (
    learn_assembly,
    load_trajectory,
    part_names,
    plan_with_reward,
)
from thirdhand.relational.boosting import fit_boosted
from thirdhand.relational.cli import app
from thirdhand.relational.csi import advantage_targets, csi_targets, fit_rcsi, state_values
from thirdhand.relational.data import expert_pairs, random_pairs, wait_kind
from thirdhand.relational.domains.blocks import blocks_mdp, blocks_reward
from thirdhand.relational.domains.plans import (
    PlanModel,
    Step,
    Trajectory,
    expert_pairs_of,
    parts_of,
)
from thirdhand.relational.evaluate import perf_of_reward, perf_of_scores
from thirdhand.relational.logic import RelationalError
from thirdhand.relational.mdp import greedy, optimal_pairs, value_iteration
from thirdhand.relational.shaping import binned_entropy, fit_shaping, state_features


def test_expert_and_random_pairs() -> None:
    mdp = blocks_mdp(4)
    r = blocks_reward(mdp, "unstack")
    e = expert_pairs(mdp, r, 20, np.random.default_rng(0))
    _, q = value_iteration(mdp, r, 0.9)
    assert optimal_pairs(mdp, q)[e].all()
    waits = np.flatnonzero(mdp.pair_kind[e] == wait_kind(mdp))
    assert waits.size == 20 and waits[-1] == e.size - 1
    # Consecutive steps of an episode chain through the transitions.
    starts = np.r_[0, waits[:-1] + 1]
    for a, b in zip(starts, waits, strict=True):
        assert np.array_equal(mdp.pair_next[e[a:b]], mdp.pair_state[e[a + 1 : b + 1]])
    d = random_pairs(mdp, 500, np.random.default_rng(1))
    assert d.min() >= 0 and d.max() < mdp.n_pairs


def test_noisy_wait_does_not_end_the_episode() -> None:
    # The noise corrupts actions, not episodes: a wait drawn by the noise outside
    # the goal is recorded and the episode goes on from the same state; every
    # episode ends with the expert's own (optimal) wait.
    mdp = blocks_mdp(4)
    r = blocks_reward(mdp, "stack")
    e = expert_pairs(mdp, r, 40, np.random.default_rng(0), noise=0.5)
    _, q = value_iteration(mdp, r, 0.9)
    opt = optimal_pairs(mdp, q)
    is_wait = mdp.pair_kind[e] == wait_kind(mdp)
    noisy_waits = np.flatnonzero(is_wait & ~opt[e])
    assert noisy_waits.size > 0 and noisy_waits[-1] < e.size - 1
    assert np.array_equal(mdp.pair_state[e[noisy_waits + 1]], mdp.pair_state[e[noisy_waits]])
    assert int((is_wait & opt[e]).sum()) >= 40 and is_wait[-1] and opt[e[-1]]


def test_perf_of_true_reward_is_one() -> None:
    mdp = blocks_mdp(4)
    r = blocks_reward(mdp, "stack")
    states = mdp.sample_states(200, np.random.default_rng(0))
    assert perf_of_reward(mdp, r, r, 0.9, states) == pytest.approx(1.0)
    # A reward that prefers the opposite task does worse.
    assert perf_of_reward(mdp, blocks_reward(mdp, "unstack"), r, 0.9, states) < 0.5


def test_blmril_and_rcsi_unstack() -> None:
    mdp = blocks_mdp(5)
    r = blocks_reward(mdp, "unstack")
    rng = np.random.default_rng(3)
    e = expert_pairs(mdp, r, 15, rng)
    d = random_pairs(mdp, 300, rng)
    states = mdp.sample_states(500, rng)
    q = fit_boosted([(mdp, e)], n_trees=40)
    assert perf_of_scores(mdp, q.predict(mdp), r, 0.9, states) > 0.9
    model = fit_rcsi([(mdp, e)], [(mdp, d)], q=q)
    assert perf_of_reward(mdp, model.reward_of(mdp), r, 0.9, states) > 0.95
    # The targets are the classifier's implied rewards.
    t = csi_targets(q, mdp, e[:1], 0.9)
    nxt = mdp.pair_next[e[0]]
    best = q.predict(mdp, np.arange(mdp.ptr[nxt], mdp.ptr[nxt + 1])).max()
    assert t[0] == pytest.approx(q.predict(mdp, e[:1])[0] - 0.9 * best)


def test_rcsi_stack_with_structural_reward() -> None:
    # The fix of the stack gap: two-atom refinements in the reward tree and the
    # shaping f(s) = -max_a q(s,a). Plain RCSI with the old tree (one atom +
    # unary, weighted D_E) loops on this seed.
    mdp = blocks_mdp(5)
    r = blocks_reward(mdp, "stack")
    rng = np.random.default_rng(5017)
    e = expert_pairs(mdp, r, 15, rng)
    d = random_pairs(mdp, 300, rng)
    states = mdp.sample_states(1000, rng)
    q = fit_boosted([(mdp, e)], n_trees=40)
    old = fit_rcsi([(mdp, e)], [(mdp, d)], q=q)
    assert perf_of_reward(mdp, old.reward_of(mdp), r, 0.9, states) < 0.5
    kw = {"balance": False, "reward_lookahead": 2, "reward_distinct_from_args": False}
    new = fit_rcsi([(mdp, e)], [(mdp, d)], q=q, shaping="advantage", **kw)  # type: ignore[arg-type]
    assert perf_of_reward(mdp, new.reward_of(mdp), r, 0.9, states) > 0.95
    # Shaped targets = q'(s,a) - γ max q'(s',.) with q' = q - max_a q(s,a): the advantage.
    pairs = np.arange(mdp.n_pairs)
    adv = advantage_targets(q, mdp, pairs)
    full = q.predict(mdp)
    shaped = full - state_values(q, mdp, mdp.pair_state)
    best_next = np.maximum.reduceat(shaped, mdp.ptr[:-1])[mdp.pair_next]
    np.testing.assert_allclose(adv, shaped - 0.9 * best_next, atol=1e-12)
    assert adv.max() <= 1e-12
    agree = full[e] >= state_values(q, mdp, mdp.pair_state[e]) - 1e-12
    assert agree.mean() > 0.9 and np.allclose(adv[e][agree], 0.0)
    with pytest.raises(RelationalError, match="unknown shaping"):
        fit_rcsi([(mdp, e)], [(mdp, d)], q=q, shaping="bogus")


def test_cma_shaping_finds_the_zero_entropy_optimum() -> None:
    # The paper's shaping, f(s) = w·max_a q(s,a) by CMA-ES on the binned entropy
    # of the targets over D_E: on a transition where the classifier agrees with
    # the expert, q(s,a) = V(s), the shaped target is (1 + w)(V(s) − γ V(s')),
    # so w = −1 puts every agreed expert target at 0. CMA-ES must reach an
    # entropy no higher than that optimum's, and w must put the agreed targets
    # into one bin: |1 + w| · max |V(s) − γ V(s')| < width / 2.
    mdp = blocks_mdp(5)
    r = blocks_reward(mdp, "stack")
    rng = np.random.default_rng(5017)
    e = expert_pairs(mdp, r, 15, rng)
    d = random_pairs(mdp, 300, rng)
    states = mdp.sample_states(1000, rng)
    q = fit_boosted([(mdp, e)], n_trees=40)
    kw = {"balance": False, "reward_lookahead": 2, "reward_distinct_from_args": False}
    model = fit_rcsi(
        [(mdp, e)],
        [(mdp, d)],
        q=q,
        shaping="cma",
        shaping_features="value",
        shaping_samples="expert",
        **kw,  # type: ignore[arg-type]
    )
    (w,) = model.shaping
    pairs = np.concatenate([e, d])
    raw = csi_targets(q, mdp, pairs, 0.9)
    v, v_next = (
        state_values(q, mdp, mdp.pair_state[pairs]),
        state_values(q, mdp, mdp.pair_next[pairs]),
    )
    width = float(np.std(raw)) / 8.0
    on_e = np.r_[np.ones(e.size), np.zeros(d.size)]

    def entropy(wt: float) -> float:
        return binned_entropy(raw + wt * (v - 0.9 * v_next), width, on_e)

    assert entropy(w) <= entropy(-1.0) + 1e-12 < entropy(0.0)
    agree = q.predict(mdp, e) >= state_values(q, mdp, mdp.pair_state[e]) - 1e-12
    assert agree.mean() > 0.9
    gap = np.abs(v - 0.9 * v_next)[: e.size][agree].max()
    assert abs(1.0 + w) * gap < width / 2
    # On this seed plain RCSI cycles (perf < 0.5 with the old tree, see above);
    # with the CMA-ES shaping it stacks from most states (0.936 measured).
    assert perf_of_reward(mdp, model.reward_of(mdp), r, 0.9, states) > 0.9
    # The default (the tables' RCSI+cma-shaping): f on the value and the
    # relational counts, entropy over D_E ∪ D_NE. CMA-ES lowers that entropy
    # and, free to weigh every feature, takes the value's weight near −1
    # (−1.10 measured) to cancel the classifier's per-state offset.
    full = fit_rcsi([(mdp, e)], [(mdp, d)], q=q, shaping="cma", **kw)  # type: ignore[arg-type]
    phi = np.concatenate([v[:, None], state_features(mdp, mdp.pair_state[pairs])], axis=1)
    phi_n = np.concatenate([v_next[:, None], state_features(mdp, mdp.pair_next[pairs])], axis=1)
    assert full.shaping.shape == (phi.shape[1],)
    shaped = raw + (phi - 0.9 * phi_n) @ full.shaping
    assert binned_entropy(shaped, width) < binned_entropy(raw, width)
    assert -1.5 < full.shaping[0] < -0.5
    assert perf_of_reward(mdp, full.reward_of(mdp), r, 0.9, states) > 0.9
    for bad, match in (
        ("shaping_features", "unknown shaping features"),
        ("shaping_samples", "unknown shaping samples"),
    ):
        with pytest.raises(RelationalError, match=match):
            fit_rcsi([(mdp, e)], [(mdp, d)], q=q, shaping="cma", **{bad: "bogus"})  # type: ignore[arg-type]


def test_boosting_separates_expert_actions() -> None:
    mdp = blocks_mdp(4)
    r = blocks_reward(mdp, "stack")
    e = expert_pairs(mdp, r, 30, np.random.default_rng(0))
    q = fit_boosted([(mdp, e)], n_trees=40).predict(mdp)
    s = mdp.pair_state[e]
    best = np.maximum.reduceat(q, mdp.ptr[:-1])
    # The expert's action scores highest in most demonstrated states.
    assert np.mean(q[e] >= best[s] - 1e-9) > 0.9
    with pytest.raises(RelationalError, match="no expert example"):
        fit_boosted([(mdp, np.zeros(0, dtype=np.int64))])


@pytest.mark.slow
def test_weighted_expert_transitions_stop_the_goal_cycle() -> None:
    # A rare failure of RCSI+cma-shaping at 10 % noise (seed 30017, the
    # tables' data): unweighted, the depth-4 reward tree spends its tests on
    # the spread of the 300 random moves' targets (−5 … 0) and puts waiting in
    # the goal into a leaf with bad moves, so in every goal state the
    # learned policy leaves the tower (a cycle pays more than waiting).
    # Weighing D_E to D_NE's total (balance=True, also in CMA-ES's entropy)
    # keeps the expert's transitions apart on this seed: the policy waits in
    # every goal state and stacks. Not the tables' default: over the 100 runs
    # it lowers as many runs as it raises (research/notes/relational_results.md, "The
    # rare failures of RCSI+cma-shaping").
    mdp = blocks_mdp(5)
    r = blocks_reward(mdp, "stack")
    rng = np.random.default_rng(30017)
    e = expert_pairs(mdp, r, 15, rng, noise=0.1)
    d = random_pairs(mdp, 300, rng)
    q = fit_boosted([(mdp, e)], n_trees=40)
    states = mdp.sample_states(1000, rng)
    goal = np.flatnonzero(np.maximum.reduceat(r, mdp.ptr[:-1]) > 0)
    kw = {"reward_lookahead": 2, "reward_distinct_from_args": False, "shaping": "cma"}
    wait = wait_kind(mdp)
    waits_in_goal = {}
    for balance in (False, True):
        m = fit_rcsi([(mdp, e)], [(mdp, d)], q=q, seed=30017, balance=balance, **kw)  # type: ignore[arg-type]
        reward = m.reward_of(mdp)
        _, qh = value_iteration(mdp, reward, 0.9)
        policy = greedy(mdp, qh)
        waits_in_goal[balance] = float(np.mean(mdp.pair_kind[policy[goal]] == wait))
        p = perf_of_reward(mdp, reward, r, 0.9, states)
        assert (p < 0.2) if not balance else (p > 0.95), (balance, p)
    # Unweighted, it leaves every one of the 120 goal states (measured: waits in 0).
    assert waits_in_goal[False] < 0.5 and waits_in_goal[True] == 1.0


def test_entropy_and_shaping() -> None:
    assert binned_entropy(np.array([0.0, 0.0, 1.0, 1.0]), 0.5) == pytest.approx(np.log(2))
    rng = np.random.default_rng(0)
    phi = rng.random((200, 3))
    phi_n = rng.random((200, 3))
    w_true = np.array([1.0, -2.0, 0.5])
    # Targets = a two-valued signal distorted by a shaping term; CMA-ES undoes it.
    base = rng.integers(0, 2, 200).astype(float)
    targets = base - (phi - 0.9 * phi_n) @ w_true
    w = fit_shaping(phi, phi_n, targets, 0.9, seed=0, max_evals=2000)
    width = float(np.std(targets)) / 8
    after = binned_entropy(targets + (phi - 0.9 * phi_n) @ w, width)
    assert after < binned_entropy(targets, width)


CHAIR_PLANS = [
    ["leg2", "leg3", "leg1", "leg4", "back"],
    ["leg1", "leg4", "leg2", "leg3", "back"],
    ["leg3", "leg1", "leg4", "leg2", "back"],
]


def _chair(order: list[str], source: str = "demo") -> Trajectory:
    return Trajectory(tuple(Step("seating", c, f"c{i + 1}") for i, c in enumerate(order)), source)


def test_plans_learn_and_transfer() -> None:
    model = learn_assembly([_chair(o) for o in CHAIR_PLANS], n_trees=20)
    bench = plan_with_reward(model, part_names({"seating": 1, "leg": 4}))
    assert bench.complete and len(bench.steps) == 4 and bench.perf > 0.99
    three = plan_with_reward(model, part_names({"seating": 1, "leg": 3, "back": 1}))
    assert three.complete and three.steps[-1] == "action(seating,back,c)"
    assert sorted(three.steps[:3]) == [f"action(seating,leg{i},c)" for i in (1, 2, 3)]


def test_plans_malformed() -> None:
    good = _chair(CHAIR_PLANS[0])
    pm = PlanModel.from_trajectories([good])
    mdp, _ = pm.ground(parts_of(good))
    twice = Trajectory((Step("seating", "leg1", "c1"), Step("seating", "leg1", "c2")), "bad.json")
    with pytest.raises(
        RelationalError, match=r"bad.json step 1: action action\(seating,leg1,c\) is not applicable"
    ):
        expert_pairs_of(pm, mdp, twice)
    with pytest.raises(RelationalError, match="no step"):
        PlanModel.from_trajectories([Trajectory((), "empty")])


def _task(path: Path, order: list[str]) -> Path:
    doc = {
        "schema": "thirdhand.task/1",
        "objects": [{"name": n} for n in ["seating", *order]],
        "plan": [
            {"parent": "seating", "child": c, "symbol": f"c{i + 1}"} for i, c in enumerate(order)
        ],
    }
    path.write_text(json.dumps(doc))
    return path


def test_cli_learn_from_task_files(tmp_path: Path) -> None:
    files = [_task(tmp_path / f"t{i}.json", o) for i, o in enumerate(CHAIR_PLANS)]
    assert load_trajectory(files[0]).steps[0] == Step("seating", "leg2", "c1")
    out = tmp_path / "out.json"
    res = CliRunner().invoke(app, ["learn", *map(str, files), "--legs", "5", "--json", str(out)])
    assert res.exit_code == 0, res.output
    plans = json.loads(out.read_text())["plans"]
    assert plans["bench"]["complete"] and plans["chair with 5 legs"]["complete"]
    assert len(plans["chair with 5 legs"]["steps"]) == 6
    empty = tmp_path / "empty.json"
    empty.write_text(json.dumps({"schema": "thirdhand.task/1"}))
    res = CliRunner().invoke(app, ["learn", str(empty)])
    assert isinstance(res.exception, RelationalError) and "has no plan" in str(res.exception)
