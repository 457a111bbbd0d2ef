"""The assembly plan: ordered actions ``action(parent, child, symbol)`` and relational states.

Decision points are the keyframes; the relational state starts empty and each
action adds one atom: ``s_0 = ∅``, ``s_{i+1} = s_i ∪ {is_constraint(parent, child, c)}``.

From several demonstrations the plan has one step per symbol (slot). Step ``b``
must follow step ``a`` when ``a`` came before ``b`` in *every* demonstration that
has both; otherwise the two are interchangeable. Steps are listed by their mean
rank over the demonstrations (a linear extension of that partial order), and each
step's ``after`` lists its direct predecessors (the transitive reduction). With
one demonstration the order is total. The child of a step is the part that went
into its slot in most demonstrations, each part used once. A slot becomes a step
only when more than half (``min_support``) of the demonstrations have it, counting
only the demonstrations that show at least one constraint: a recording that shows
none (an excerpt, a recording cut before the first attachment) says nothing about
which slots the task has, and must not erase the steps the others agree on.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from thirdhand import se3
from thirdhand.constraints.detect import ConstraintInstance, DetectionResult
from thirdhand.demonstration import ConstraintEvent
from thirdhand.errors import OptionError
from thirdhand.plan.symbols import Symbol


@dataclass
class PlanAction:
    """One step ``action(parent, child, symbol)``.

    Attributes
    ----------
    parent, child, symbol : str
    after : list of int
        Indices of the earlier steps this one must directly follow.
    times : list of float
        When it happened in each demonstration that has it, seconds.
    """

    parent: str
    child: str
    symbol: str
    after: list[int] = field(default_factory=list)
    times: list[float] = field(default_factory=list)

    def __str__(self) -> str:
        return f"action({self.parent}, {self.child}, {self.symbol})"

    def atom(self) -> str:
        """The relational atom this step makes true."""
        return f"is_constraint({self.parent}, {self.child}, {self.symbol})"


@dataclass
class AssemblyPlan:
    """Ordered steps and the relational trajectory they produce.

    Attributes
    ----------
    steps : list of PlanAction
    root : str or None
        The base every other part is (directly or not) attached to.
    n_demos : int
    silent : list of int
        Demonstrations (indices) that show no constraint; they do not vote.
    left_out : dict of str to int
        Slots seen in too few of the voting demonstrations to become steps, with the
        number of demonstrations that have each.
    """

    steps: list[PlanAction]
    root: str | None
    n_demos: int
    silent: list[int] = field(default_factory=list)
    left_out: dict[str, int] = field(default_factory=dict)

    @property
    def voters(self) -> int:
        """Demonstrations that vote on the slots (those that show a constraint)."""
        return self.n_demos - len(self.silent)

    def relational_trajectory(self) -> list[frozenset[str]]:
        """States ``s_0 = ∅ … s_n``, each a set of atoms ``is_constraint(O1, O2, C)``."""
        states: list[frozenset[str]] = [frozenset()]
        for s in self.steps:
            states.append(states[-1] | {s.atom()})
        return states

    def interchangeable(self) -> list[tuple[int, int]]:
        """Pairs of step indices with no order between them (either may come first)."""
        n = len(self.steps)
        before = _closure([s.after for s in self.steps])
        return [(i, j) for i in range(n) for j in range(i + 1, n) if i not in before[j]]

    def lines(self) -> list[str]:
        """Human-readable steps."""
        out = []
        for i, s in enumerate(self.steps):
            dep = f"  after {', '.join(str(j + 1) for j in s.after)}" if s.after else ""
            out.append(f"{i + 1}. {s}{dep}")
        return out


def _closure(after: list[list[int]]) -> list[set[int]]:
    out: list[set[int]] = []
    for preds in after:
        s: set[int] = set()
        for j in preds:
            s |= {j} | out[j]
        out.append(s)
    return out


def plan_from_demos(
    demos: Sequence[Sequence[ConstraintInstance]],
    symbols: Sequence[Symbol],
    *,
    root: str | None = None,
    min_support: float = 0.5,
) -> AssemblyPlan:
    """The assembly plan of one or several demonstrations.

    Parameters
    ----------
    demos : sequence of sequences of ConstraintInstance
        Each demonstration's instances (with ``symbol`` set by
        :func:`~thirdhand.plan.symbols.assign_symbols`); removed ones are ignored.
    symbols : sequence of Symbol
    root : str, optional
        The base (default: the most common parent).
    min_support : float
        A slot becomes a step when more than this fraction of the demonstrations
        that show any constraint have it, in [0, 1): 0.5 (default) is a strict
        majority, so one demonstration's spurious constraint is not a step; 0 keeps
        every slot seen at least once.

    Raises
    ------
    OptionError
        When ``min_support`` is outside [0, 1) (a ``ValueError`` too).
    """
    if not 0.0 <= min_support < 1.0:  # also NaN
        raise OptionError(f"min_support: expected a number >= 0 and < 1, got {min_support:g}")
    by_name = {s.name: s for s in symbols}
    seqs = []
    for insts in demos:
        kept = [i for i in sorted(insts, key=lambda c: c.start) if i.end is None and i.symbol]
        seq: list[ConstraintInstance] = []
        for i in kept:
            if all(j.symbol != i.symbol for j in seq):
                seq.append(i)
        seqs.append(seq)
    support: dict[str, int] = {}
    for seq in seqs:
        for i in seq:
            if i.symbol in by_name:
                support[i.symbol] = support.get(i.symbol, 0) + 1
    # A step must appear in more than half of the demonstrations that show anything:
    # one demonstration's spurious constraint does not become a step, and a recording
    # with no constraint at all (an excerpt) does not vote against the others.
    silent = [k for k, seq in enumerate(seqs) if not seq]
    voters = len(seqs) - len(silent)
    names = sorted(n for n, v in support.items() if v > min_support * voters)
    left_out = {n: v for n, v in sorted(support.items()) if n not in names}
    seqs = [[i for i in seq if i.symbol in names] for seq in seqs]
    rank: dict[str, list[float]] = {n: [] for n in names}
    times: dict[str, list[float]] = {n: [] for n in names}
    for seq in seqs:
        for r, i in enumerate(seq):
            if i.symbol in rank:
                rank[i.symbol].append(r / max(1, len(seq) - 1))
                times[i.symbol].append(i.start)
    order = sorted(names, key=lambda n: (float(np.mean(rank[n])), n))
    pos_in = [{i.symbol: r for r, i in enumerate(seq)} for seq in seqs]

    def always_before(a: str, b: str) -> bool:
        both = [p for p in pos_in if a in p and b in p]
        return bool(both) and all(p[a] < p[b] for p in both)

    preds = [[j for j in range(k) if always_before(order[j], order[k])] for k in range(len(order))]
    reduced = []
    closure = _closure(preds)
    for ps in preds:
        reduced.append([j for j in ps if not any(j in closure[m] for m in ps if m != j)])
    children = _assign_children(order, seqs)
    steps = [
        PlanAction(
            parent=by_name[n].parent, child=children[n], symbol=n, after=reduced[k], times=times[n]
        )
        for k, n in enumerate(order)
    ]
    parents = [s.parent for s in steps]
    base = (
        root
        if root is not None
        else (max(sorted(set(parents)), key=parents.count) if parents else None)
    )
    return AssemblyPlan(steps=steps, root=base, n_demos=len(seqs), silent=silent, left_out=left_out)


def _assign_children(order: list[str], seqs: list[list[ConstraintInstance]]) -> dict[str, str]:
    """Each slot's most frequent child, every child used once (greedy by votes)."""
    votes: dict[tuple[str, str], int] = {}
    for seq in seqs:
        for i in seq:
            if i.symbol is not None:
                votes[(i.symbol, i.child)] = votes.get((i.symbol, i.child), 0) + 1
    out: dict[str, str] = {}
    used: set[str] = set()
    for (sym, child), _ in sorted(
        votes.items(),
        key=lambda kv: (-kv[1], order.index(kv[0][0]) if kv[0][0] in order else 0, kv[0][1]),
    ):
        if sym in order and sym not in out and child not in used:
            out[sym] = child
            used.add(child)
    # Slots whose voted children are all taken get the parts still unused (identical
    # parts, such as legs, go anywhere), so that every part is placed once.
    spare = sorted({c for (_, c) in votes} - used)
    for sym in order:
        if sym not in out:
            cands = sorted((v, c) for (s, c), v in votes.items() if s == sym)
            out[sym] = spare.pop(0) if spare else cands[-1][1]
    return out


def truth_slot(
    symbol: Symbol,
    truth: Sequence[ConstraintEvent],
    *,
    pos_tol: float = 0.02,
    rot_tol: float = math.radians(20.0),
) -> str | None:
    """The true slot (symbol of a ground-truth constraint) a learned symbol stands for.

    A true slot matches when it has the same parent, its position is within
    ``pos_tol`` metres and its orientation within ``rot_tol`` radians (about the
    free axis when the true constraint spins freely, in the child frame).
    """
    best, best_d = None, math.inf
    for ev in truth:
        if ev.removed or ev.parent != symbol.parent or ev.symbol is None:
            continue
        dp = float(np.linalg.norm(symbol.pos - np.asarray(ev.pos)))
        q = np.asarray(ev.quat, dtype=np.float64)
        spin = [k for k, n in enumerate(("rx", "ry", "rz")) if n in ev.free_dofs.free()]
        if len(spin) == 1:
            e = np.zeros(3)
            e[spin[0]] = 1.0
            a, b = se3.quat_rotate(q, e), se3.quat_rotate(symbol.quat, e)
            dr = float(np.arccos(np.clip(a @ b, -1.0, 1.0)))
        else:
            dr = float(se3.quat_angle(q, symbol.quat))
        if dp <= pos_tol and dr <= rot_tol and dp < best_d:
            best, best_d = ev.symbol, dp
    return best


def plan_success(
    plan: AssemblyPlan, symbols: Sequence[Symbol], truth: Sequence[ConstraintEvent]
) -> bool:
    """Execute the plan symbolically against the true slots (the report's criterion).

    Success: every step attaches its child to the true parent in a true slot, no
    slot is used twice, and every part the truth attaches is placed exactly once.
    """
    by_name = {s.name: s for s in symbols}
    true_parent = {ev.child: ev.parent for ev in truth if not ev.removed}
    used: set[str] = set()
    placed: list[str] = []
    for step in plan.steps:
        slot = truth_slot(by_name[step.symbol], truth)
        if slot is None or slot in used or true_parent.get(step.child) != step.parent:
            return False
        used.add(slot)
        placed.append(step.child)
    return sorted(placed) == sorted(true_parent)


def assemble(
    detections: Sequence[DetectionResult], *, min_support: float = 0.5
) -> tuple[list[Symbol], AssemblyPlan]:
    """Symbols over every recording's constraints, and the plan they vote for.

    The stage behind :func:`thirdhand.plan_assembly` and
    :func:`thirdhand.learn_task`.

    Parameters
    ----------
    detections : sequence of DetectionResult
        One per recording of the same task.
    min_support : float
        See :func:`plan_from_demos`.
    """
    from thirdhand.plan.symbols import assign_symbols

    symbols = assign_symbols([i for d in detections for i in d.instances])
    plan = plan_from_demos([d.instances for d in detections], symbols, min_support=min_support)
    return symbols, plan
