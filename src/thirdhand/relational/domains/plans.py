"""A relational domain built from assembly plans (relational trajectories).

A demonstration's plan is a list of steps ``action(parent, child, symbol)``; its
states are ``s_0`` (only the static facts) and ``s_{i+1} = s_i ∪
{is_constraint(parent, child, symbol)}``. Object and symbol *types* come from
their names without trailing digits (``leg3`` → ``leg``, ``c5`` → ``c``); symbols
are replaced by their type, so that demonstrations with different constraint
ids share states. Static facts give each object its type (``leg(leg3)``) and
``loose(X)`` marks a part of a child type not yet attached. The abstract action
``action(P, C, S)`` has one rule per (parent type, child type, symbol type) seen
in the demonstrations: it attaches a loose child; ``wait()`` ends the task.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from thirdhand.relational.logic import Atom, RelationalError
from thirdhand.relational.mdp import ActionSchema, Domain, GroundMDP, Rule, State, ground

SPECIAL = ("loose", "is_constraint")


@dataclass(frozen=True)
class Step:
    """One plan step ``action(parent, child, symbol)``."""

    parent: str
    child: str
    symbol: str


@dataclass(frozen=True)
class Trajectory:
    """The plan of one demonstration and where it came from (for error messages)."""

    steps: tuple[Step, ...]
    source: str = "trajectory"


def type_of(name: str) -> str:
    """An object's type: its name without trailing digits (``leg12`` → ``leg``)."""
    t = re.sub(r"\d+$", "", name) or name
    t = re.sub(r"\W", "_", t)
    if not t[0].isalpha():
        t = "t_" + t
    t = t[0].lower() + t[1:]
    return "t_" + t if t in SPECIAL or t in ("wait", "action") else t


def counted_parts(parts: Sequence[str]) -> dict[str, list[str]]:
    """The part types whose instances are counted: named ``<type>1`` … ``<type>n``, n ≥ 2.

    Only such parts are interchangeable copies whose number can vary (``leg1`` …
    ``leg4``); trailing digits that are identities (AR tags ``ar_0`` and ``ar_13``,
    a table and its leg) do not count parts.

    Parameters
    ----------
    parts : sequence of str
        Part names.

    Returns
    -------
    dict of str to list of str
        Type to its part names, in the order of ``parts``.
    """
    by_type: dict[str, list[str]] = {}
    for p in parts:
        by_type.setdefault(type_of(p), []).append(p)
    out: dict[str, list[str]] = {}
    for t, names in by_type.items():
        numbers = []
        for name in names:
            m = re.fullmatch(rf"{re.escape(t)}(\d+)", name, re.I)
            if m is None:
                break
            numbers.append(int(m.group(1)))
        if len(numbers) == len(names) >= 2 and sorted(numbers) == list(range(1, len(names) + 1)):
            out[t] = names
    return out


@dataclass(frozen=True)
class PlanModel:
    """The types seen in demonstrations: rules (parent, child, symbol type) and child types."""

    rules: tuple[tuple[str, str, str], ...]

    @classmethod
    def from_trajectories(cls, trajectories: Sequence[Trajectory]) -> PlanModel:
        """Collect the rule types of every step; raises on an empty set of steps."""
        rules: list[tuple[str, str, str]] = []
        for tr in trajectories:
            for st in tr.steps:
                key = (type_of(st.parent), type_of(st.child), type_of(st.symbol))
                if key not in rules:
                    rules.append(key)
        if not rules:
            raise RelationalError("assembly plans: no step in any demonstration")
        return cls(tuple(rules))

    @property
    def child_types(self) -> set[str]:
        """Types of the objects that get attached."""
        return {c for _, c, _ in self.rules}

    @property
    def symbols(self) -> tuple[str, ...]:
        """Symbol types (the symbol objects of every domain)."""
        return tuple(dict.fromkeys(s for _, _, s in self.rules))

    def domain(self, parts: Iterable[str]) -> Domain:
        """The domain over ``parts`` (object names) and the symbol types."""
        parts = tuple(dict.fromkeys(parts))
        types = sorted({type_of(p) for p in parts} | {t for r in self.rules for t in r})
        preds = {t: 1 for t in types} | {"loose": 1, "is_constraint": 3}
        rules = []
        for tp, tc, ts in self.rules:
            static = (Atom(tp, ("P",)), Atom(tc, ("C",)), Atom(ts, ("S",)))
            c = (*static, Atom("loose", ("C",)))
            rules.append(Rule(c, (*static, Atom("is_constraint", ("P", "C", "S")))))
        acts = (
            ActionSchema("action", ("P", "C", "S"), tuple(rules)),
            ActionSchema("wait", (), (Rule((), ()),)),
        )
        objects = (*parts, *(s for s in self.symbols if s not in parts))
        return Domain("plans", preds, objects, acts, _signature)

    def start(self, domain: Domain) -> State:
        """``s_0``: every object's type, and ``loose(X)`` for parts of a child type."""
        atoms = set()
        for o in domain.objects:
            t = type_of(o) if o not in self.symbols else o
            atoms.add(Atom(t, (o,)))
            if t in self.child_types and o not in self.symbols:
                atoms.add(Atom("loose", (o,)))
        return frozenset(atoms)

    def ground(self, parts: Iterable[str]) -> tuple[GroundMDP, int]:
        """The grounded MDP over ``parts`` and the index of ``s_0``."""
        dom = self.domain(parts)
        s0 = self.start(dom)
        mdp = ground(dom, [s0])
        return mdp, mdp.index[s0]


def _signature(state: State) -> tuple[tuple[str, int], ...]:
    """Configuration: how many parts of each type are still loose."""
    loose = [re.sub(r"\d+$", "", a.args[0]) for a in state if a.pred == "loose"]
    return tuple(sorted((t, loose.count(t)) for t in set(loose)))


def parts_of(trajectory: Trajectory) -> tuple[str, ...]:
    """Parent and child names of a trajectory, in order of appearance."""
    return tuple(dict.fromkeys(x for st in trajectory.steps for x in (st.parent, st.child)))


def expert_pairs_of(model: PlanModel, mdp: GroundMDP, trajectory: Trajectory) -> NDArray[np.int64]:
    """Pairs of a demonstration's steps, then ``wait`` in its last state, shape (n_steps + 1,).

    Raises
    ------
    RelationalError
        Naming the source and step when a step is not applicable (e.g. a child
        attached twice).
    """
    s = mdp.index[model.start(mdp.domain)]
    out = []
    for i, st in enumerate(trajectory.steps):
        act = Atom("action", (st.parent, st.child, type_of(st.symbol)))
        p = mdp.pair_of(s, act, where=f"{trajectory.source} step {i}")
        out.append(p)
        s = int(mdp.pair_next[p])
    out.append(mdp.pair_of(s, Atom("wait"), where=f"{trajectory.source} end"))
    return np.asarray(out, dtype=np.int64)


def assembled_reward(mdp: GroundMDP) -> NDArray[np.float64]:
    """Reward 1 where no part is loose (everything attached), per pair, shape (P,)."""
    goal = np.logical_not(np.any(mdp.tables["loose"], axis=1))
    return goal.astype(np.float64)[mdp.pair_state]


def trajectory_from_steps(steps: Sequence[Mapping[str, object]], *, source: str) -> Trajectory:
    """A trajectory from dicts with ``parent``, ``child`` and optional ``symbol``.

    Raises
    ------
    RelationalError
        When a step lacks a parent or a child.
    """
    out = []
    for i, st in enumerate(steps):
        parent, child = st.get("parent"), st.get("child")
        if not isinstance(parent, str) or not isinstance(child, str) or not parent or not child:
            raise RelationalError(
                f"{source} plan[{i}]: expected parent and child names, got {dict(st)}"
            )
        sym = st.get("symbol")
        out.append(Step(parent, child, sym if isinstance(sym, str) and sym else "constraint"))
    return Trajectory(tuple(out), source)


class PlanStepLike(Protocol):
    """A plan step as the stages type it: a ``PlanAction`` or a task file's ``TaskStep``."""

    @property
    def parent(self) -> str: ...

    @property
    def child(self) -> str: ...

    @property
    def symbol(self) -> str | None: ...


def trajectory_from_plan(steps: Sequence[PlanStepLike], *, source: str) -> Trajectory:
    """A trajectory from typed plan steps (``AssemblyPlan.steps`` or ``TaskFile.plan``).

    Raises
    ------
    RelationalError
        When a step lacks a parent or a child.
    """
    out = []
    for i, st in enumerate(steps):
        if not st.parent or not st.child:
            raise RelationalError(
                f"{source} plan[{i}]: expected parent and child names, "
                f"got {st.parent!r} and {st.child!r}"
            )
        out.append(Step(st.parent, st.child, st.symbol or "constraint"))
    return Trajectory(tuple(out), source)
