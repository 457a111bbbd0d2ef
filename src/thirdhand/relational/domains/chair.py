"""Chair world: parts with connectors, ``connect``/``unconnect`` compatible connectors.

Parts are ``seating``, ``back`` and legs ``leg1..legn``. Each leg carries a male
connector ``lm<i>``, the back a male ``bm``; the seating carries the female
connectors ``sf1..sfn`` (for legs) and ``sb`` (for the back). A male and a female
connector are ``compatible`` when of the same kind (leg or back).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from thirdhand.relational.logic import Atom, RelationalError, parse_atom
from thirdhand.relational.mdp import ActionSchema, Domain, GroundMDP, Rule, State, ground

PREDICATES = {
    "leg": 1,
    "seating": 1,
    "back": 1,
    "connector": 1,
    "male": 1,
    "female": 1,
    "part_of": 2,
    "compatible": 2,
    "free": 1,
    "connected": 2,
}


def _atoms(text: str) -> tuple[Atom, ...]:
    return tuple(parse_atom(t) for t in text.split(";"))


_CONNECT = ActionSchema(
    "connect",
    ("A", "B"),
    (Rule(_atoms("free(A);free(B);compatible(A,B)"), _atoms("compatible(A,B);connected(A,B)")),),
)
_UNCONNECT = ActionSchema(
    "unconnect", ("A", "B"), (Rule(_atoms("connected(A,B)"), _atoms("free(A);free(B)")),)
)
_WAIT = ActionSchema("wait", (), (Rule((), ()),))


def chair_signature(state: State) -> tuple[int, int]:
    """The relational configuration: (connected legs, back connected)."""
    conn = [a.args[0] for a in state if a.pred == "connected"]
    return sum(c.startswith("lm") for c in conn), int("bm" in conn)


def chair_domain(n_legs: int = 4, *, with_back: bool = True) -> Domain:
    """The chair world with ``n_legs`` legs (and a back unless ``with_back`` is False)."""
    if n_legs < 0:
        raise RelationalError(f"chair world: expected a non-negative number of legs, got {n_legs}")
    legs = tuple(f"leg{i + 1}" for i in range(n_legs))
    objects = (
        "seating",
        *legs,
        *(f"lm{i + 1}" for i in range(n_legs)),
        *(f"sf{i + 1}" for i in range(n_legs)),
    )
    if with_back:
        objects = (*objects, "back", "bm", "sb")
    return Domain(
        f"chair{n_legs}{'' if with_back else '-bench'}",
        PREDICATES,
        objects,
        (_CONNECT, _UNCONNECT, _WAIT),
        chair_signature,
    )


def chair_start(n_legs: int = 4, *, with_back: bool = True) -> State:
    """The disassembled chair: every connector free."""
    atoms = {Atom("seating", ("seating",))}

    def conn(c: str, part: str, sex: str) -> None:
        atoms.update(
            {
                Atom("connector", (c,)),
                Atom(sex, (c,)),
                Atom("part_of", (c, part)),
                Atom("free", (c,)),
            }
        )

    for i in range(n_legs):
        atoms.add(Atom("leg", (f"leg{i + 1}",)))
        conn(f"lm{i + 1}", f"leg{i + 1}", "male")
        conn(f"sf{i + 1}", "seating", "female")
        atoms.update(Atom("compatible", (f"lm{i + 1}", f"sf{j + 1}")) for j in range(n_legs))
    if with_back:
        atoms.add(Atom("back", ("back",)))
        conn("bm", "back", "male")
        conn("sb", "seating", "female")
        atoms.add(Atom("compatible", ("bm", "sb")))
    return frozenset(atoms)


@lru_cache(maxsize=8)
def chair_mdp(n_legs: int = 4, *, with_back: bool = True) -> GroundMDP:
    """The grounded chair world (cached)."""
    return ground(
        chair_domain(n_legs, with_back=with_back), [chair_start(n_legs, with_back=with_back)]
    )


def chair_reward(mdp: GroundMDP) -> NDArray[np.float64]:
    """Reward *build* per pair, shape (P,): 1 when every connector is connected."""
    goal = np.logical_not(np.any(mdp.tables["free"], axis=1))
    return goal.astype(np.float64)[mdp.pair_state]


def chair_configs(n_legs: int, *, with_back: bool = True) -> list[tuple[int, int]]:
    """Every relational configuration (connected legs, back connected) of the chair world."""
    return [(k, b) for k in range(n_legs + 1) for b in ((0, 1) if with_back else (0,))]


def chair_grounding(
    n_legs: int, config: tuple[int, int], rng: np.random.Generator, *, with_back: bool = True
) -> State:
    """A uniformly random grounding of ``config`` = (connected legs, back connected).

    ``k`` legs drawn uniformly, each connected to a distinct seating connector
    drawn uniformly (a uniformly random partial matching of that size).
    """
    k, back = config
    if not 0 <= k <= n_legs or back not in (0, 1) or (back and not with_back):
        raise RelationalError(
            f"chair world: configuration {config} impossible with {n_legs} legs"
            f"{'' if with_back else ' and no back'}"
        )
    atoms = set(chair_start(n_legs, with_back=with_back))
    pairs = [("bm", "sb")] if back else []
    legs = rng.permutation(n_legs)[:k]
    sockets = rng.permutation(n_legs)[:k]
    pairs += [(f"lm{i + 1}", f"sf{j + 1}") for i, j in zip(legs, sockets, strict=True)]
    for m, f in pairs:
        atoms -= {Atom("free", (m,)), Atom("free", (f,))}
        atoms.add(Atom("connected", (m, f)))
    return frozenset(atoms)
