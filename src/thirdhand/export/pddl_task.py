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

PDDL names are letters, digits, ``-`` and ``_``: object names are lower-cased
and other characters replaced by ``_`` (``/toolbox/side_front`` becomes
``toolbox_side_front``); the problem's header comments give every name's
original.
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


def pddl_names(names: Sequence[str], *, taken: set[str] | None = None) -> list[str]:
    """Valid, unique PDDL names (a letter, then letters, digits, ``-``, ``_``), lower case."""
    used = taken if taken is not None else set()
    out = []
    for name in names:
        base = re.sub(r"[^a-z0-9_-]", "_", name.lower()).strip("_-") or "x"
        if not base[0].isalpha():
            base = f"n{base}"
        cand, k = base, 2
        while cand in used:
            cand, k = f"{base}_{k}", k + 1
        used.add(cand)
        out.append(cand)
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
    lines += [f";   part {part_of[n]} = {n}" for n in parts]
    lines += [
        f";   slot {c} = constraint {slots[i]} (plan step {i})" for i, c in enumerate(slot_names)
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
