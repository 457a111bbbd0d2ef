"""Relational MDPs: abstract actions with rules, grounding, exact value iteration.

An abstract action ``name(params)`` has rules ``(c_i, o_i)``: under a grounding σ
with ``c_iσ ⊆ s`` it leads to ``s' = (s \\ c_iσ) ∪ o_iσ`` (the first applicable
rule wins; distinct variables bind distinct objects). :func:`ground` enumerates
the states reachable from given ones and stores the grounded MDP as flat index
arrays: the (state, action) *pairs* of state ``s`` are ``ptr[s]:ptr[s+1]``.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Hashable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from thirdhand.relational.logic import Atom, RelationalError, index_state, is_variable, match

State = frozenset[Atom]


@dataclass(frozen=True)
class Rule:
    """One rule ``(c, o)`` of an abstract action: preconditions and outcome."""

    c: tuple[Atom, ...]
    o: tuple[Atom, ...]


@dataclass(frozen=True)
class ActionSchema:
    """An abstract action ``name(params)`` with its rules, tried in order."""

    name: str
    params: tuple[str, ...]
    rules: tuple[Rule, ...]


@dataclass(frozen=True)
class Domain:
    """A relational domain: predicates with arities, objects, abstract actions.

    Attributes
    ----------
    name : str
    predicates : dict of str to int
        Arity of every predicate a state or rule may use.
    objects : tuple of str
    actions : tuple of ActionSchema
    signature : callable or None
        ``state -> hashable``: the relational configuration of a state (the state
        up to renaming of objects), used by :meth:`GroundMDP.sample_states`.
    successor_fn : callable or None
        ``state -> list of (action, state)``: a faster equivalent of the rules'
        generic matching for :meth:`successors` (it may return None for a state
        it does not handle, which then goes through the rules).
    """

    name: str
    predicates: Mapping[str, int]
    objects: tuple[str, ...]
    actions: tuple[ActionSchema, ...]
    signature: Callable[[State], Hashable] | None = field(default=None, compare=False)
    successor_fn: Callable[[State], list[tuple[Atom, State]] | None] | None = field(
        default=None, compare=False
    )

    def __post_init__(self) -> None:
        if len(set(self.objects)) != len(self.objects):
            raise RelationalError(f"domain {self.name}: duplicate object names")
        for act in self.actions:
            for k, rule in enumerate(act.rules):
                where = f"domain {self.name}, action {act.name} rule {k}"
                for a in (*rule.c, *rule.o):
                    self._check_atom(a, where=where, ground=False)
                bound = {v for a in rule.c for v in a.args if is_variable(v)}
                missing = [p for p in act.params if p not in bound]
                free_o = {v for a in rule.o for v in a.args if is_variable(v)} - bound
                if missing:
                    raise RelationalError(
                        f"{where}: parameter {missing[0]} does not occur in the preconditions"
                    )
                if free_o:
                    raise RelationalError(
                        f"{where}: outcome variable {sorted(free_o)[0]} "
                        "is not bound by the preconditions"
                    )

    def _check_atom(self, a: Atom, *, where: str, ground: bool) -> None:
        if a.pred not in self.predicates:
            known = ", ".join(sorted(self.predicates))
            raise RelationalError(f"{where}: unknown predicate {a.pred!r} in {a} (known: {known})")
        if len(a.args) != self.predicates[a.pred]:
            raise RelationalError(
                f"{where}: {a} has {len(a.args)} arguments, "
                f"{a.pred} expects {self.predicates[a.pred]}"
            )
        if ground:
            objs = set(self.objects)
            for x in a.args:
                if x not in objs:
                    raise RelationalError(f"{where}: unknown object {x!r} in {a}")

    def check_state(self, state: Iterable[Atom], *, where: str = "state") -> State:
        """Validate a state (known predicates, arities and objects) and freeze it."""
        s = frozenset(state)
        for a in sorted(s):
            self._check_atom(a, where=where, ground=True)
        return s

    def schema(self, name: str) -> ActionSchema:
        """The abstract action called ``name``."""
        for a in self.actions:
            if a.name == name:
                return a
        raise RelationalError(
            f"domain {self.name}: unknown action {name!r} "
            f"(known: {', '.join(a.name for a in self.actions)})"
        )

    def successors(self, state: State) -> list[tuple[Atom, State]]:
        """Every applicable ground action and the state it leads to (sorted by action)."""
        if self.successor_fn is not None:
            fast = self.successor_fn(state)
            if fast is not None:
                return fast
        return self.rule_successors(state)

    def rule_successors(self, state: State) -> list[tuple[Atom, State]]:
        """:meth:`successors` by matching the rules' preconditions (the definition)."""
        idx = index_state(state)
        out: dict[Atom, State] = {}
        for act in self.actions:
            for rule in act.rules:
                for theta in match(rule.c, idx):
                    ground = Atom(act.name, tuple(theta[p] for p in act.params))
                    if ground in out:
                        continue
                    cs = {a.substitute(theta) for a in rule.c}
                    os_ = {a.substitute(theta) for a in rule.o}
                    out[ground] = frozenset((state - cs) | os_)
        return sorted(out.items())

    def apply(self, state: State, action: Atom, *, where: str = "step") -> State:
        """The state after ``action``; raises when it is not applicable.

        Raises
        ------
        RelationalError
            Unknown action, wrong arity, or no rule whose preconditions hold.
        """
        act = self.schema(action.pred)
        if len(action.args) != len(act.params):
            raise RelationalError(
                f"{where}: {action} has {len(action.args)} arguments, "
                f"{act.name} expects {len(act.params)}"
            )
        theta = dict(zip(act.params, action.args, strict=True))
        idx = index_state(state)
        for rule in act.rules:
            for th in match(rule.c, idx, theta):
                cs = {a.substitute(th) for a in rule.c}
                return frozenset((state - cs) | {a.substitute(th) for a in rule.o})
        raise RelationalError(
            f"{where}: action {action} is not applicable in state "
            f"{{{', '.join(map(str, sorted(state)))}}}"
        )


@dataclass
class GroundMDP:
    """A grounded relational MDP as flat arrays.

    Attributes
    ----------
    domain : Domain
    states : list of frozenset of Atom
        ``S`` states; ``index`` maps a state to its number.
    ptr : ndarray, shape (S + 1,), int64
        Pairs of state ``s`` are ``ptr[s]:ptr[s+1]``.
    pair_state, pair_next, pair_kind : ndarray, shape (P,), int64
        State, successor state and action schema index of every pair.
    pair_args : ndarray, shape (P, max_arity), int64
        Object indices of the action's arguments, -1 past its arity.
    tables : dict of str to ndarray of bool, shape (S,) + (n_objects,) * arity
        Truth of every ground atom in every state.
    """

    domain: Domain
    states: list[State]
    index: dict[State, int]
    ptr: NDArray[np.int64]
    pair_state: NDArray[np.int64]
    pair_next: NDArray[np.int64]
    pair_kind: NDArray[np.int64]
    pair_args: NDArray[np.int64]
    tables: dict[str, NDArray[np.bool_]]

    @property
    def n_states(self) -> int:
        """Number of states S."""
        return len(self.states)

    @property
    def n_pairs(self) -> int:
        """Number of (state, action) pairs P."""
        return int(self.pair_state.size)

    def action(self, pair: int) -> Atom:
        """The ground action of a pair."""
        act = self.domain.actions[int(self.pair_kind[pair])]
        return Atom(
            act.name,
            tuple(self.domain.objects[int(i)] for i in self.pair_args[pair, : len(act.params)]),
        )

    def pair_of(self, state: int, action: Atom, *, where: str = "step") -> int:
        """The pair index of ``action`` in state number ``state``; raises when not applicable."""
        for p in range(int(self.ptr[state]), int(self.ptr[state + 1])):
            if self.action(p) == action:
                return p
        self.domain.apply(self.states[state], action, where=where)
        raise RelationalError(f"{where}: action {action} leads outside the enumerated states")

    def sample_states(self, n: int, rng: np.random.Generator) -> NDArray[np.int64]:
        """``n`` state indices from P_state: a configuration uniformly, then a grounding uniformly.

        Without a domain signature, states are drawn uniformly.
        """
        if self.domain.signature is None:
            return rng.integers(0, self.n_states, size=n)
        groups: dict[Hashable, list[int]] = {}
        for i, s in enumerate(self.states):
            groups.setdefault(self.domain.signature(s), []).append(i)
        keys = list(groups)
        g = rng.integers(0, len(keys), size=n)
        return np.array(
            [groups[keys[k]][rng.integers(len(groups[keys[k]]))] for k in g], dtype=np.int64
        )


def ground(
    domain: Domain, initial: Iterable[Iterable[Atom]], *, max_states: int = 500_000
) -> GroundMDP:
    """Enumerate every state reachable from ``initial`` and ground all actions.

    Raises
    ------
    RelationalError
        If an initial state is malformed, or more than ``max_states`` states are reachable.
    """
    obj = {o: i for i, o in enumerate(domain.objects)}
    states: list[State] = []
    index: dict[State, int] = {}
    for k, s in enumerate(initial):
        fs = domain.check_state(s, where=f"initial state {k}")
        if fs not in index:
            index[fs] = len(states)
            states.append(fs)
    succ: list[list[tuple[Atom, State]]] = []
    queue = deque(range(len(states)))
    while queue:
        i = queue.popleft()
        while len(succ) <= i:
            succ.append([])
        succ[i] = domain.successors(states[i])
        for _, nxt in succ[i]:
            if nxt not in index:
                if len(states) >= max_states:
                    raise RelationalError(
                        f"domain {domain.name}: more than {max_states} reachable states"
                    )
                index[nxt] = len(states)
                states.append(nxt)
                queue.append(len(states) - 1)
    kinds = {a.name: k for k, a in enumerate(domain.actions)}
    arity = max((len(a.params) for a in domain.actions), default=0)
    counts = np.array([len(x) for x in succ], dtype=np.int64)
    if np.any(counts == 0):
        bad = int(np.flatnonzero(counts == 0)[0])
        raise RelationalError(
            f"domain {domain.name}: no applicable action in state {sorted(map(str, states[bad]))}"
        )
    ptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    n_pairs = int(ptr[-1])
    pair_state = np.repeat(np.arange(len(states), dtype=np.int64), counts)
    pair_next = np.empty(n_pairs, dtype=np.int64)
    pair_kind = np.empty(n_pairs, dtype=np.int64)
    pair_args = np.full((n_pairs, max(arity, 1)), -1, dtype=np.int64)
    p = 0
    for lst in succ:
        for act, nxt in lst:
            pair_next[p] = index[nxt]
            pair_kind[p] = kinds[act.pred]
            pair_args[p, : len(act.args)] = [obj[x] for x in act.args]
            p += 1
    return GroundMDP(
        domain,
        states,
        index,
        ptr,
        pair_state,
        pair_next,
        pair_kind,
        pair_args,
        state_tables(domain, states),
    )


def state_tables(domain: Domain, states: Sequence[State]) -> dict[str, NDArray[np.bool_]]:
    """Truth tables of every predicate, shape ``(S,) + (n_objects,) * arity``."""
    obj = {o: i for i, o in enumerate(domain.objects)}
    n = len(domain.objects)
    tables = {
        p: np.zeros((len(states),) + (n,) * k, dtype=bool) for p, k in domain.predicates.items()
    }
    for i, s in enumerate(states):
        for a in s:
            tables[a.pred][(i, *(obj[x] for x in a.args))] = True
    return tables


def segment_max(mdp: GroundMDP, values: NDArray[np.float64]) -> NDArray[np.float64]:
    """Max of a per-pair array over each state's pairs, shape (S,)."""
    return np.maximum.reduceat(values, mdp.ptr[:-1])


def value_iteration(
    mdp: GroundMDP,
    reward: NDArray[np.float64],
    gamma: float,
    *,
    tol: float = 1e-10,
    max_iter: int = 100_000,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Optimal values of ``Q(s,a) = R(s,a) + γ V(s')``, ``V(s) = max_a Q(s,a)``.

    Parameters
    ----------
    reward : ndarray, shape (P,)
        Reward of each pair.
    gamma : float
        Discount in [0, 1).

    Returns
    -------
    V : ndarray, shape (S,)
    Q : ndarray, shape (P,)
    """
    v = np.zeros(mdp.n_states)
    q = reward.astype(np.float64)
    for _ in range(max_iter):
        q = reward + gamma * v[mdp.pair_next]
        nv = segment_max(mdp, q)
        if np.max(np.abs(nv - v)) < tol:
            return nv, q
        v = nv
    return v, q


def greedy(mdp: GroundMDP, q: NDArray[np.float64], *, tol: float = 1e-9) -> NDArray[np.int64]:
    """The greedy policy: per state, the first pair within ``tol`` of the best, shape (S,)."""
    m = segment_max(mdp, q)
    ok = q >= m[mdp.pair_state] - tol
    cand = np.where(ok, np.arange(mdp.n_pairs), mdp.n_pairs)
    return np.minimum.reduceat(cand, mdp.ptr[:-1]).astype(np.int64)


def optimal_pairs(
    mdp: GroundMDP, q: NDArray[np.float64], *, tol: float = 1e-9
) -> NDArray[np.bool_]:
    """Which pairs are optimal (within ``tol``), shape (P,)."""
    return q >= segment_max(mdp, q)[mdp.pair_state] - tol


def policy_values(
    mdp: GroundMDP,
    policy: NDArray[np.int64],
    reward: NDArray[np.float64],
    gamma: float,
    *,
    tol: float = 1e-10,
) -> NDArray[np.float64]:
    """Values of a deterministic policy (pair index per state) under ``reward``, shape (S,)."""
    r = reward[policy]
    nxt = mdp.pair_next[policy]
    v = np.zeros(mdp.n_states)
    while True:
        nv = r + gamma * v[nxt]
        if np.max(np.abs(nv - v)) < tol:
            return nv
        v = nv
