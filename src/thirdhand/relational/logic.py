"""First-order atoms, substitutions and θ-subsumption matching.

An atom is a predicate name and a tuple of arguments; an argument that starts
with an upper-case letter (or ``_``) is a variable, any other is an object
(constant). A state is a ``frozenset`` of ground atoms.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping
from typing import NamedTuple

from thirdhand.errors import ThirdhandError

Substitution = dict[str, str]


class RelationalError(ThirdhandError, ValueError):
    """A relational domain, state or trajectory is malformed."""


class Atom(NamedTuple):
    """``pred(args...)``.

    Attributes
    ----------
    pred : str
        Predicate name.
    args : tuple of str
        Variables (upper-case first letter) or objects.
    """

    pred: str
    args: tuple[str, ...] = ()

    def __str__(self) -> str:
        return f"{self.pred}({','.join(self.args)})"

    def substitute(self, theta: Mapping[str, str]) -> Atom:
        """The atom with every variable bound in ``theta`` replaced."""
        return Atom(self.pred, tuple(theta.get(a, a) for a in self.args))

    def is_ground(self) -> bool:
        """True when no argument is a variable."""
        return not any(is_variable(a) for a in self.args)


def is_variable(term: str) -> bool:
    """True for a variable: a name starting with an upper-case letter or ``_``."""
    return bool(term) and (term[0].isupper() or term[0] == "_")


def parse_atom(text: str) -> Atom:
    """Parse ``"on(X,Y)"``, ``"wait()"`` or ``"wait"`` into an :class:`Atom`.

    Raises
    ------
    RelationalError
        If the text is not ``name(arg, ...)``.
    """
    s = text.strip()
    if "(" not in s:
        if not s.isidentifier():
            raise RelationalError(f"atom {text!r}: expected name(arg, ...)")
        return Atom(s)
    name, _, rest = s.partition("(")
    if not rest.endswith(")") or not name.strip().isidentifier():
        raise RelationalError(f"atom {text!r}: expected name(arg, ...)")
    inner = rest[:-1].strip()
    args = tuple(a.strip() for a in inner.split(",")) if inner else ()
    if any(not a or not a.replace("-", "_").isidentifier() for a in args):
        raise RelationalError(f"atom {text!r}: empty or invalid argument")
    return Atom(name.strip(), args)


class StateIndex(dict[str, list[tuple[str, ...]]]):
    """Ground atoms grouped by predicate (a dict of argument tuples), with lookup tables.

    ``facts[pred]`` is the set of argument tuples and ``by_first[pred][x]`` the
    tuples whose first argument is ``x``; :func:`match` uses them to test a
    bound atom by membership and to scan only the facts of a bound first
    argument, instead of every fact of the predicate.
    """

    def __init__(self, atoms: Iterable[Atom]) -> None:
        super().__init__()
        self.facts: dict[str, set[tuple[str, ...]]] = {}
        self.by_first: dict[str, dict[str, list[tuple[str, ...]]]] = {}
        for a in atoms:
            self.setdefault(a.pred, []).append(a.args)
            self.facts.setdefault(a.pred, set()).add(a.args)
            if a.args:
                self.by_first.setdefault(a.pred, {}).setdefault(a.args[0], []).append(a.args)


def index_state(state: Iterable[Atom]) -> StateIndex:
    """Ground atoms grouped by predicate, for fast matching."""
    return StateIndex(state)


def unify(
    pattern: Atom, fact: tuple[str, ...], theta: Substitution, *, distinct: bool
) -> Substitution | None:
    """Extend ``theta`` so that ``pattern`` maps onto the ground ``fact`` args, or None.

    With ``distinct`` (object identity), two variables never bind the same object.
    """
    if len(pattern.args) != len(fact):
        return None
    new = dict(theta)
    for p, f in zip(pattern.args, fact, strict=True):
        if is_variable(p):
            bound = new.get(p)
            if bound is None:
                if distinct and f in new.values():
                    return None
                new[p] = f
            elif bound != f:
                return None
        elif p != f:
            return None
    return new


def match(
    conjunction: Iterable[Atom],
    state: Iterable[Atom] | Mapping[str, list[tuple[str, ...]]],
    theta: Mapping[str, str] | None = None,
    *,
    distinct: bool = True,
) -> Iterator[Substitution]:
    """Every substitution σ ⊇ θ with ``conjunction``σ ⊆ ``state`` (θ-subsumption).

    Parameters
    ----------
    conjunction : iterable of Atom
        Atoms with variables.
    state : set of ground Atom, or the output of :func:`index_state`
    theta : dict, optional
        Bindings to start from.
    distinct : bool
        Object identity: distinct variables bind distinct objects.

    Yields
    ------
    dict of str to str
        Each complete substitution (backtracking search, atoms in the given order).
    """
    index = state if isinstance(state, Mapping) else index_state(state)
    atoms = list(conjunction)
    start = dict(theta or {})
    if distinct and len(set(start.values())) != len(start):
        return

    fast = isinstance(index, StateIndex)

    def rec(i: int, th: Substitution) -> Iterator[Substitution]:
        if i == len(atoms):
            yield th
            return
        atom = atoms[i]
        facts: Iterable[tuple[str, ...]] = index.get(atom.pred, ())
        if fast:
            assert isinstance(index, StateIndex)
            args = tuple(th.get(a, a) if is_variable(a) else a for a in atom.args)
            if not any(is_variable(a) for a in args):
                if args in index.facts.get(atom.pred, ()):
                    yield from rec(i + 1, th)
                return
            if args and not is_variable(args[0]):
                facts = index.by_first.get(atom.pred, {}).get(args[0], ())
        for fact in facts:
            nxt = unify(atom, fact, th, distinct=distinct)
            if nxt is not None:
                yield from rec(i + 1, nxt)

    yield from rec(0, start)


def subsumes(conjunction: Iterable[Atom], state: Iterable[Atom], *, distinct: bool = True) -> bool:
    """True when some substitution maps ``conjunction`` into ``state``."""
    return next(match(conjunction, state, distinct=distinct), None) is not None
