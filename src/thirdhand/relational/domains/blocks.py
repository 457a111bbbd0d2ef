"""Blocks world with colours, and the variant with an unmovable block.

Objects are the blocks ``b1..bn`` and ``floor``; predicates ``on(X,Y)``,
``clear(X)``, ``cube(X)``, ``floor(X)``, ``red(X)``, ``blue(X)``, ``movable(X)``.
``move(X,Y)`` has three rules (block to block, block to floor, floor to block);
``wait()`` is always applicable and changes nothing.
"""

from __future__ import annotations

from functools import lru_cache
from itertools import pairwise

import numpy as np
from numpy.typing import NDArray

from thirdhand.relational.logic import Atom, RelationalError, parse_atom
from thirdhand.relational.mdp import ActionSchema, Domain, GroundMDP, Rule, State, ground

PREDICATES = {"on": 2, "clear": 1, "cube": 1, "floor": 1, "red": 1, "blue": 1, "movable": 1}
REWARDS = ("stack", "unstack")


def _fix(text: str) -> tuple[Atom, ...]:
    return tuple(parse_atom(t) for t in text.split(";"))


_MOVE = ActionSchema(
    "move",
    ("X", "Y"),
    (
        Rule(
            _fix("on(X,Z);clear(X);clear(Y);cube(Y);cube(Z);movable(X)"),
            _fix("on(X,Y);clear(X);cube(Y);cube(Z);clear(Z);movable(X)"),
        ),
        Rule(
            _fix("on(X,Z);clear(X);floor(Y);cube(Z);movable(X)"),
            _fix("on(X,Y);clear(X);floor(Y);cube(Z);clear(Z);movable(X)"),
        ),
        Rule(
            _fix("on(X,Z);clear(X);clear(Y);cube(Y);floor(Z);movable(X)"),
            _fix("on(X,Y);clear(X);cube(Y);floor(Z);movable(X)"),
        ),
    ),
)
_WAIT = ActionSchema("wait", (), (Rule((), ()),))


def block_names(n_blocks: int) -> tuple[str, ...]:
    """``("b1", ..., "bn")``."""
    return tuple(f"b{i + 1}" for i in range(n_blocks))


def tower_heights(state: State) -> tuple[int, ...]:
    """The relational configuration: sorted heights of the towers.

    Raises
    ------
    RelationalError
        If the ``on`` atoms do not form towers standing on the floor (a cycle,
        or a block on nothing known).
    """
    below = {a.args[0]: a.args[1] for a in state if a.pred == "on"}
    supports = set(below.values())
    heights = []
    for b in below:
        if b in supports:
            continue
        h, x = 1, b
        while below.get(x) != "floor":
            x, h = below.get(x, ""), h + 1
            if h > len(below):
                raise RelationalError(
                    f"blocks world: block {b} does not stand on the floor through a tower"
                )
        heights.append(h)
    if sum(heights) != len(below):
        raise RelationalError("blocks world: the on atoms form a cycle")
    return tuple(sorted(heights))


def blocks_domain(n_blocks: int, *, unmovable: tuple[str, ...] = ()) -> Domain:
    """The blocks world with ``n_blocks`` blocks (odd ones red, even ones blue).

    ``unmovable`` blocks lack ``movable(X)``, so ``move`` never applies to them.
    """
    if n_blocks < 1:
        raise RelationalError(f"blocks world: expected at least 1 block, got {n_blocks}")
    return Domain(
        f"blocks{n_blocks}",
        PREDICATES,
        (*block_names(n_blocks), "floor"),
        (_MOVE, _WAIT),
        tower_heights,
        blocks_successors,
    )


_WAIT_ATOM = Atom("wait", ())


def blocks_successors(state: State) -> list[tuple[Atom, State]] | None:
    """The successors the ``move`` rules and ``wait`` give, without generic matching.

    Equal to :meth:`Domain.rule_successors` (pinned by a test over every state of
    5 blocks, with and without an unmovable block); returns None (use the rules)
    when a block stands on more than one object.
    """
    below: dict[str, str] = {}
    clear, movable, cube, floor = set(), set(), set(), set()
    n_on = 0
    for a in state:
        p = a.pred
        if p == "on":
            below[a.args[0]] = a.args[1]
            n_on += 1
        elif p == "clear":
            clear.add(a.args[0])
        elif p == "movable":
            movable.add(a.args[0])
        elif p == "cube":
            cube.add(a.args[0])
        elif p == "floor":
            floor.add(a.args[0])
    if n_on != len(below):
        return None
    out: list[tuple[Atom, State]] = [(_WAIT_ATOM, state)]
    for x, z in below.items():
        if x not in clear or x not in movable or x == z:
            continue
        on_xz = Atom("on", (x, z))
        if z in cube:  # rule 1 (block to block), rule 2 (block to floor)
            for y in clear:
                if y in cube and y != x and y != z:
                    nxt = (state - {on_xz, Atom("clear", (y,))}) | {
                        Atom("on", (x, y)),
                        Atom("clear", (z,)),
                    }
                    out.append((Atom("move", (x, y)), frozenset(nxt)))
            for y in floor:
                if y != x and y != z:
                    nxt = (state - {on_xz}) | {Atom("on", (x, y)), Atom("clear", (z,))}
                    out.append((Atom("move", (x, y)), frozenset(nxt)))
        elif z in floor:  # rule 3 (floor to block)
            for y in clear:
                if y in cube and y != x and y != z:
                    nxt = (state - {on_xz, Atom("clear", (y,))}) | {Atom("on", (x, y))}
                    out.append((Atom("move", (x, y)), frozenset(nxt)))
    return sorted(out)


def floor_state(n_blocks: int, *, unmovable: tuple[str, ...] = ()) -> State:
    """Every block on the floor (with the static colour, cube and movable atoms)."""
    atoms = {Atom("floor", ("floor",))}
    for i, b in enumerate(block_names(n_blocks)):
        atoms |= {Atom("on", (b, "floor")), Atom("clear", (b,)), Atom("cube", (b,))}
        atoms.add(Atom("red" if i % 2 == 0 else "blue", (b,)))
        if b not in unmovable:
            atoms.add(Atom("movable", (b,)))
    return frozenset(atoms)


@lru_cache(maxsize=16)
def blocks_mdp(n_blocks: int, *, unmovable: tuple[str, ...] = ()) -> GroundMDP:
    """The grounded blocks world (cached). With ``unmovable``, the states are those of
    the movable world (every configuration), with the unmovable blocks frozen."""
    if not unmovable:
        return ground(blocks_domain(n_blocks), [floor_state(n_blocks)])
    full = blocks_mdp(n_blocks)
    starts = [s - {Atom("movable", (b,)) for b in unmovable} for s in full.states]
    return ground(blocks_domain(n_blocks, unmovable=unmovable), starts)


def partitions(n: int, largest: int | None = None) -> list[tuple[int, ...]]:
    """Integer partitions of ``n`` (tower heights, non-increasing)."""
    if n == 0:
        return [()]
    top = n if largest is None else min(n, largest)
    return [(h, *rest) for h in range(top, 0, -1) for rest in partitions(n - h, h)]


def blocks_configs(n_blocks: int) -> list[tuple[int, ...]]:
    """Every relational configuration of ``n_blocks`` blocks, as :func:`tower_heights` gives it."""
    return [tuple(sorted(p)) for p in partitions(n_blocks)]


def random_state(n_blocks: int, rng: np.random.Generator) -> State:
    """A state from P_state without enumeration: tower heights (a partition) uniformly,
    then the blocks in a uniformly random order."""
    parts = partitions(n_blocks)
    return blocks_grounding(parts[int(rng.integers(len(parts)))], rng)


def blocks_grounding(heights: tuple[int, ...], rng: np.random.Generator) -> State:
    """A uniformly random grounding of the configuration ``heights`` (tower heights).

    The ``sum(heights)`` blocks are put in a uniformly random order and stacked
    tower by tower (colours are fixed by the block names).
    """
    n_blocks = sum(heights)
    if any(h < 1 for h in heights):
        raise RelationalError(f"blocks world: tower heights must be positive, got {heights}")
    order = [block_names(n_blocks)[i] for i in rng.permutation(n_blocks)]
    atoms = set(floor_state(n_blocks)) - {
        a for a in floor_state(n_blocks) if a.pred in ("on", "clear")
    }
    k = 0
    for h in heights:
        tower = order[k : k + h]
        k += h
        atoms.add(Atom("on", (tower[0], "floor")))
        atoms.update(Atom("on", (a, b)) for b, a in pairwise(tower))
        atoms.add(Atom("clear", (tower[-1],)))
    return frozenset(atoms)


def optimal_steps(state: State, kind: str) -> int:
    """Fewest moves to the goal: stack n − (tallest tower), unstack the blocks not on the floor."""
    heights = tower_heights(state)
    n = sum(heights)
    return n - max(heights) if kind == "stack" else n - len(heights)


def blocks_reward(mdp: GroundMDP, kind: str) -> NDArray[np.float64]:
    """True reward per pair, shape (P,): ``stack`` (one tower) or ``unstack`` (all on the floor)."""
    f = mdp.domain.objects.index("floor")
    n_blocks = len(mdp.domain.objects) - 1
    on_floor = mdp.tables["on"][:, :, f].sum(axis=1)
    if kind == "stack":
        goal = on_floor == 1
    elif kind == "unstack":
        goal = on_floor == n_blocks
    else:
        raise RelationalError(
            f"blocks world: unknown reward {kind!r}, expected one of {', '.join(REWARDS)}"
        )
    return goal.astype(np.float64)[mdp.pair_state]
