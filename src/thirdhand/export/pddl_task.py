"""A task's plan as a PDDL domain and problem, for a task planner.

``thirdhand convert TASK.json OUT.pddl`` writes the problem to ``OUT.pddl`` and
the domain beside it to ``OUT.domain.pddl`` (:func:`domain_path`).

The domain ``thirdhand-assembly`` is plain STRIPS with types, so any PDDL
planner reads it. Objects are the plan's parts (type ``part``) and its
constraints, the slots (type ``slot``). Its one action is the report's
``action(parent, child, c)``:

``(assemble ?parent ?child ?c)``
    precondition: ``(fits ?c ?parent ?child)`` (the plan puts ``child`` into
    slot ``c`` of ``parent``), ``(placed ?parent)`` — the parent order: a part
    is attached only to a part already in the assembly, the base being placed
    at the start — ``(loose ?child)`` and ``(open ?c)``; effect: the
    relational atom ``(is_constraint ?parent ?child ?c)``, ``(placed ?child)``,
    the child no longer loose, the slot no longer open.

The goal is every plan step's ``is_constraint`` atom, so a plan has one
action per step and puts every parent before its children. The order the
learned plan gives among steps with no parent link between them (which leg
first) is not in the problem: STRIPS cannot say "after all of these steps"
in one generic action, and a planner is free to choose; the behaviour tree
(:mod:`thirdhand.export.behavior_tree`) keeps it.

PDDL names are a letter, then letters, digits, ``-`` and ``_``, and PDDL
does not tell case apart: object names are lower-cased and other characters
replaced by ``_`` (``/toolbox/side_front`` becomes ``toolbox_side_front``); a
name that is one of PDDL's words (``not``, ``define``, ``and``, ``object``...)
or the domain's own (``part``, ``placed``...) gets ``_`` appended, and a name
another name already took a numeric suffix, so every object has its own
identifier (:func:`pddl_names`, checked injective). The problem's header
comments give every name's original, escaped to one line of printable ASCII
(:func:`comment_text`): nothing in a name can end a comment.
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from pathlib import Path

from thirdhand.errors import TaskFileError
from thirdhand.task.model import TaskFile

#: The domain's name.
DOMAIN_NAME = "thirdhand-assembly"
#: The action's name.
ACTION = "assemble"

DOMAIN = f"""; The assembly domain of thirdhand: one action per plan step, the report's
; action(parent, child, c), which makes is_constraint(parent, child, c) true.
(define (domain {DOMAIN_NAME})
  (:requirements :strips :typing)
  (:types part slot)
  (:predicates
    (fits ?c - slot ?parent - part ?child - part)
    (placed ?p - part)
    (loose ?p - part)
    (open ?c - slot)
    (is_constraint ?parent - part ?child - part ?c - slot))
  (:action {ACTION}
    :parameters (?parent - part ?child - part ?c - slot)
    :precondition (and (fits ?c ?parent ?child) (placed ?parent) (loose ?child) (open ?c))
    :effect (and (is_constraint ?parent ?child ?c) (placed ?child)
                 (not (loose ?child)) (not (open ?c)))))
"""


def domain_path(problem: str | os.PathLike[str]) -> Path:
    """Where the domain goes for a problem file: ``OUT.pddl`` -> ``OUT.domain.pddl``."""
    p = Path(problem)
    return p.with_name(f"{p.stem}.domain{p.suffix or '.pddl'}")


#: Words a PDDL name may not be: the language's keywords and the domain's own names.
RESERVED: frozenset[str] = frozenset(
    {
        "and", "or", "not", "imply", "exists", "forall", "when", "either", "oneof",
        "define", "domain", "problem", "object", "assign", "increase", "decrease",
        "scale-up", "scale-down", "maximize", "minimize", "total-cost", "total-time",
        "at", "over", "all", "start", "end", "preference", "sometime", "always",
        "within", "number", "undefined", "is-violated",
        DOMAIN_NAME, ACTION, "part", "slot", "fits", "placed", "loose", "open", "is_constraint",
    }
)  # fmt: skip
_IDENTIFIER = re.compile(r"[a-z][a-z0-9_-]*")


def comment_text(name: str) -> str:
    """``name`` as printable ASCII on one line (``\\n``, ``\\x00``, ``\\u00e9`` escapes)."""
    return name.encode("unicode_escape").decode("ascii")


def pddl_names(names: Sequence[str], *, taken: set[str] | None = None) -> list[str]:
    """Valid, unique PDDL names (a letter, then letters, digits, ``-``, ``_``), lower case.

    No name is a PDDL keyword or a name of the domain (:data:`RESERVED`), and no
    two names map to one identifier (nor to one in ``taken``, which is updated).

    Raises
    ------
    TaskFileError
        Two names mapped to one identifier (a broken invariant, never expected).
    """
    used = taken if taken is not None else set()
    before = len(used)
    out = []
    for name in names:
        base = re.sub(r"[^a-z0-9_-]", "_", name.lower()).strip("_-") or "x"
        if not base[0].isalpha():
            base = f"n{base}"
        if base in RESERVED:
            base = f"{base}_"
        cand, k = base, 2
        while cand in used:
            cand, k = f"{base}_{k}", k + 1
        used.add(cand)
        out.append(cand)
    if len(used) - before != len(out) or not all(_IDENTIFIER.fullmatch(n) for n in out):
        raise TaskFileError(f"PDDL names {out} of {list(names)} are not unique identifiers")
    return out


def problem_pddl(task: TaskFile, *, name: str = "task") -> str:
    """The PDDL problem of the task's plan (domain :data:`DOMAIN_NAME`).

    Raises
    ------
    TaskFileError
        The task has no plan.
    """
    if not task.plan:
        raise TaskFileError("the task has no plan (learn it from a demonstration first)")
    parts: list[str] = []
    for s in task.plan:
        for n in (s.parent, s.child):
            if n not in parts:
                parts.append(n)
    slots = [s.constraint or s.symbol or f"step{i}" for i, s in enumerate(task.plan)]
    taken: set[str] = set()
    part_of = dict(zip(parts, pddl_names(parts, taken=taken), strict=True))
    slot_names = pddl_names(slots, taken=taken)
    children = {s.child for s in task.plan}
    (problem_name,) = pddl_names([name])
    lines = [f"; thirdhand task as a PDDL problem; domain in {DOMAIN_NAME} (the .domain.pddl file)"]
    lines += [f";   part {part_of[n]} = {comment_text(n)}" for n in parts]
    lines += [
        f";   slot {c} = constraint {comment_text(slots[i])} (plan step {i})"
        for i, c in enumerate(slot_names)
    ]
    lines += [
        f"(define (problem {problem_name})",
        f"  (:domain {DOMAIN_NAME})",
        "  (:objects",
        f"    {' '.join(part_of[n] for n in parts)} - part",
        f"    {' '.join(slot_names)} - slot)",
        "  (:init",
    ]
    lines += [f"    (placed {part_of[n]})" for n in parts if n not in children]
    lines += [f"    (loose {part_of[s.child]})" for s in task.plan]
    lines += [f"    (open {c})" for c in slot_names]
    lines += [
        f"    (fits {c} {part_of[s.parent]} {part_of[s.child]})"
        for s, c in zip(task.plan, slot_names, strict=True)
    ]
    lines[-1] += ")"
    lines += ["  (:goal (and"]
    lines += [
        f"    (is_constraint {part_of[s.parent]} {part_of[s.child]} {c})"
        for s, c in zip(task.plan, slot_names, strict=True)
    ]
    lines[-1] += ")))"
    return "\n".join(lines) + "\n"
