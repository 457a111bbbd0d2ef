"""Relational MDP core: logic, domains, grounding, value iteration, TILDE."""

from __future__ import annotations

import numpy as np
import pytest

from thirdhand.relational.domains.blocks import (
    blocks_domain,
    blocks_mdp,
    blocks_reward,
    floor_state,
)
from thirdhand.relational.domains.chair import chair_mdp, chair_reward
from thirdhand.relational.logic import Atom, RelationalError, match, parse_atom, subsumes
from thirdhand.relational.mdp import (
    ActionSchema,
    Domain,
    Rule,
    greedy,
    policy_values,
    value_iteration,
)
from thirdhand.relational.tilde import fit_tree


def test_parse_and_match() -> None:
    assert parse_atom("on(X, b1)") == Atom("on", ("X", "b1"))
    assert parse_atom("wait()") == Atom("wait") == parse_atom("wait")
    state = {parse_atom(t) for t in ("on(a,b)", "on(b,floor)", "clear(a)")}
    subs = list(match([parse_atom("on(X,Y)"), parse_atom("clear(X)")], state))
    assert subs == [{"X": "a", "Y": "b"}]
    assert subsumes([parse_atom("on(X,Y)"), parse_atom("on(Y,Z)")], state)
    # Object identity: X and Y may not both bind a.
    assert not subsumes([parse_atom("clear(X)"), parse_atom("clear(Y)")], state)
    assert subsumes([parse_atom("clear(X)"), parse_atom("clear(Y)")], state, distinct=False)


@pytest.mark.parametrize("text", ["on(X,", "on X", "on(X,,Y)", "(X)"])
def test_malformed_atom(text: str) -> None:
    with pytest.raises(RelationalError, match="atom"):
        parse_atom(text)


@pytest.mark.parametrize(("n", "count"), [(1, 1), (2, 3), (3, 13), (4, 73), (5, 501)])
def test_blocks_state_count(n: int, count: int) -> None:
    mdp = blocks_mdp(n)
    assert mdp.n_states == count
    assert sum(np.all(mdp.tables["on"][:, :n, n], axis=1)) == 1  # one all-on-floor state
    # Every state has wait; pairs are grouped by state.
    assert np.all(np.diff(mdp.ptr) >= 1)
    assert np.array_equal(mdp.pair_state, np.repeat(np.arange(count), np.diff(mdp.ptr)))


def test_blocks_rules() -> None:
    dom = blocks_domain(3)
    s = floor_state(3)
    s1 = dom.apply(s, parse_atom("move(b1,b2)"))
    assert Atom("on", ("b1", "b2")) in s1 and Atom("clear", ("b2",)) not in s1
    s2 = dom.apply(s1, parse_atom("move(b1,floor)"))
    assert s2 == s
    assert dom.apply(s, parse_atom("wait()")) == s
    with pytest.raises(RelationalError, match=r"move\(b2,b2\) is not applicable"):
        dom.apply(s, parse_atom("move(b2,b2)"))
    with pytest.raises(RelationalError, match=r"move\(b2,b1\) is not applicable"):
        dom.apply(s1, parse_atom("move(b2,b1)"))
    with pytest.raises(RelationalError, match="unknown action 'jump'"):
        dom.apply(s, parse_atom("jump(b1)"))
    with pytest.raises(RelationalError, match="1 arguments, move expects 2"):
        dom.apply(s, parse_atom("move(b1)"))


def test_unmovable_block() -> None:
    mdp = blocks_mdp(3, unmovable=("b1",))
    assert mdp.n_states == 13
    moved = {mdp.action(p).args[0] for p in range(mdp.n_pairs) if mdp.action(p).pred == "move"}
    assert moved == {"b2", "b3"}


def test_malformed_domain_and_state() -> None:
    with pytest.raises(RelationalError, match="unknown predicate 'onn'"):
        Domain(
            "d",
            {"on": 2},
            ("a",),
            (ActionSchema("x", ("X",), (Rule((parse_atom("onn(X,Y)"),), ()),)),),
        )
    with pytest.raises(RelationalError, match="parameter Y does not occur"):
        Domain(
            "d",
            {"on": 2},
            ("a",),
            (ActionSchema("x", ("X", "Y"), (Rule((parse_atom("on(X,Z)"),), ()),)),),
        )
    with pytest.raises(RelationalError, match="outcome variable W"):
        Domain(
            "d",
            {"on": 2},
            ("a",),
            (
                ActionSchema(
                    "x", ("X",), (Rule((parse_atom("on(X,Z)"),), (parse_atom("on(W,X)"),)),)
                ),
            ),
        )
    dom = blocks_domain(2)
    with pytest.raises(RelationalError, match="unknown predicate 'green'"):
        dom.check_state({parse_atom("green(b1)")})
    with pytest.raises(RelationalError, match="unknown object 'b9'"):
        dom.check_state({parse_atom("clear(b9)")})
    with pytest.raises(RelationalError, match="3 arguments"):
        dom.check_state({parse_atom("on(b1,b2,b3)")})


def test_value_iteration_hand_computed() -> None:
    # Two blocks, stack: both towers are goals (V = 1 / (1 - γ) = 10); from the
    # floor state one move reaches a tower: V = 0 + γ 10 = 9.
    mdp = blocks_mdp(2)
    r = blocks_reward(mdp, "stack")
    v, q = value_iteration(mdp, r, 0.9)
    floor = mdp.index[floor_state(2)]
    expected = np.full(3, 10.0)
    expected[floor] = 9.0
    np.testing.assert_allclose(v, expected, atol=1e-8)
    pi = greedy(mdp, q)
    assert mdp.action(int(pi[floor])).pred == "move"
    np.testing.assert_allclose(policy_values(mdp, pi, r, 0.9), expected, atol=1e-8)
    # Unstack from a tower: one move, then the goal forever: 0 + 0.9 * 10.
    v, _ = value_iteration(mdp, blocks_reward(mdp, "unstack"), 0.9)
    assert np.allclose(sorted(v), [9.0, 9.0, 10.0])


def test_value_iteration_brute_force() -> None:
    # Against the Bellman equation solved exactly for the optimal policy.
    mdp = blocks_mdp(3)
    r = blocks_reward(mdp, "stack")
    v, q = value_iteration(mdp, r, 0.8)
    pi = greedy(mdp, q)
    p = np.zeros((mdp.n_states, mdp.n_states))
    p[np.arange(mdp.n_states), mdp.pair_next[pi]] = 1
    exact = np.linalg.solve(np.eye(mdp.n_states) - 0.8 * p, r[pi])
    np.testing.assert_allclose(v, exact, atol=1e-8)
    # No pair beats its state's value.
    assert np.all(q <= v[mdp.pair_state] + 1e-9)


def test_chair_world() -> None:
    mdp = chair_mdp(4)
    # Partial matchings of 4 legs to 4 slots (209) times back on/off.
    assert mdp.n_states == 418
    assert chair_reward(mdp).reshape(-1)[mdp.ptr[:-1]].sum() == 24
    small = chair_mdp(1, with_back=False)
    assert small.n_states == 2


def test_tilde_recovers_planted_rule() -> None:
    mdp = blocks_mdp(5)
    rng = np.random.default_rng(0)
    pairs = rng.choice(mdp.n_pairs, 400, replace=False)
    f = mdp.domain.objects.index("floor")

    def rule(p: np.ndarray) -> np.ndarray:
        # move X onto a block Y that stands on the floor
        y = mdp.pair_args[p, 1]
        ok = (mdp.pair_kind[p] == 0) & (y != f)
        return ok & mdp.tables["on"][mdp.pair_state[p], np.maximum(y, 0), f]

    labels = np.where(rule(pairs), 1.0, -1.0)
    tree = fit_tree([(mdp, pairs)], labels, max_depth=3, classification=True)
    every = np.arange(mdp.n_pairs)
    assert np.array_equal(tree.predict(mdp) > 0, rule(every))
    assert tree.depth() == 1
    assert [str(a) for a in tree.root.test or ()] == ["on(A1,X0)", "floor(X0)"]
    # The same tree applies to another number of blocks.
    other = blocks_mdp(4)
    f4 = other.domain.objects.index("floor")
    y = other.pair_args[:, 1]
    truth = (
        (other.pair_kind == 0)
        & (y != f4)
        & other.tables["on"][other.pair_state, np.maximum(y, 0), f4]
    )
    assert np.array_equal(tree.predict(other) > 0, truth)


def test_tilde_regression_and_errors() -> None:
    mdp = blocks_mdp(4)
    pairs = np.arange(mdp.n_pairs)
    # Planted regression target: 3 for wait, + 2 when some block stands on a block.
    tower = mdp.tables["on"][:, :4, :4].any(axis=(1, 2))
    target = 3.0 * (mdp.pair_kind == 1) + 2.0 * tower[mdp.pair_state]
    tree = fit_tree([(mdp, pairs)], target, max_depth=4)
    np.testing.assert_allclose(tree.predict(mdp), target)
    with pytest.raises(RelationalError, match="targets"):
        fit_tree([(mdp, pairs)], target[:-1])
    with pytest.raises(RelationalError, match="-1 or \\+1"):
        fit_tree([(mdp, pairs)], target, classification=True)


def test_tilde_lookahead_reaches_tower_test() -> None:
    # Stack reward on 3 coloured blocks: 1 in the one-tower states. "Not a
    # single tower" is "two distinct blocks stand on the same object (the
    # floor)": on(X0,X1), on(X2,X1), a conjunction of two binary atoms that
    # one-atom (or atom + unary) refinements cannot reach in one node.
    mdp = blocks_mdp(3)
    pairs = np.arange(mdp.n_pairs)
    target = blocks_reward(mdp, "stack")
    assert 0 < target.sum() < target.size
    for lookahead in (0, 1):
        weak = fit_tree([(mdp, pairs)], target, max_depth=1, lookahead=lookahead)
        assert not np.allclose(weak.predict(mdp), target)
    # Object identity among the test's variables only: with identity to the
    # action's arguments too, X1 could not be the floor in move(X, floor).
    kw = {"max_depth": 1, "lookahead": 2, "distinct_from_args": False}
    tree = fit_tree([(mdp, pairs)], target, **kw)
    np.testing.assert_allclose(tree.predict(mdp), target)
    assert [str(a) for a in tree.root.test or ()] == ["on(X0,X1)", "on(X2,X1)"]
    # Structural, not colour: exact on 4 and 5 blocks too.
    for n in (4, 5):
        other = blocks_mdp(n)
        np.testing.assert_allclose(tree.predict(other), blocks_reward(other, "stack"))
    # The F-test stop keeps a significant split and refuses a useless one.
    stopped = fit_tree([(mdp, pairs)], target, significance=0.05, **kw)
    np.testing.assert_allclose(stopped.predict(mdp), target)
    noise = np.random.default_rng(0).normal(size=pairs.size)
    flat = fit_tree([(mdp, pairs)], noise, max_depth=2, significance=1e-6)
    assert flat.depth() == 0
