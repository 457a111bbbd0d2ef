"""The clarification round: questions to the person, the least certain first.

Two kinds of doubt: a constraint the learner is not sure of (low ``confidence``),
and a DOF range near a decision boundary, where noise and a real motion look
alike (a rotation range of a few degrees: sensor noise or a loose joint?) or a
nearly full turn (a limited hinge or a full joint?). A locked DOF, a range far
from every boundary and an exact full turn are clear and come last.

A score reads as the chance that what the task says is wrong: ``1 - confidence``
for a constraint, ``1 - confidence · (1 - r)`` when the detector had a runner-up
type of probability ``r`` (it holds, but as the other type); for a DOF,
``0.5 · a`` with the ambiguity
``a = exp(-(ln(w / b))² / (2 σ²))``, ``w`` the range width, ``b`` the nearest
boundary (:data:`~thirdhand.review.dofs.NOISE_TRANSLATION`,
:data:`~thirdhand.review.dofs.NOISE_ROTATION`, a full turn) and ``σ = ln 2``: a
range right on a boundary is a coin flip (0.5), one twice or half the boundary
scores 0.31, four times 0.07. A constraint less than 50 % confident is asked
before any DOF.

An object the person singled out (pointed at, looked at:
:mod:`thirdhand.review.focus`) moves its questions to the front: first its own
constraint's (the one whose child it is), then those of the constraints whose
parent it is, each group in the uncertainty order.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from thirdhand.review.dofs import FULL_ROTATION, NOISE_ROTATION, NOISE_TRANSLATION, classify_dof
from thirdhand.task.geometry import DOF_NAMES
from thirdhand.task.model import TaskFile

#: Width of the boundary bump, in natural log of the width ratio.
SIGMA = math.log(2.0)

_DOF_WORDS = {
    "tx": "slide along x",
    "ty": "slide along y",
    "tz": "slide along z",
    "rx": "turn about x",
    "ry": "turn about y",
    "rz": "turn about z",
}


@dataclass(frozen=True)
class Question:
    """One question of the clarification round.

    Attributes
    ----------
    constraint : str
        The constraint's id.
    dof : str or None
        The DOF asked about, or None for the whole constraint.
    score : float
        Uncertainty in [0, 1]; higher is asked first.
    text : str
        The question, for the person.
    focused : bool
        Asked early because it is about the object in focus.
    """

    constraint: str
    dof: str | None
    score: float
    text: str
    focused: bool = False


def dof_ambiguity(lo: float, hi: float, dof: str) -> float:
    """How close a DOF range is to a decision boundary, in [0, 1] (1 on it).

    Locked ranges and exact full turns score 0.
    """
    width = hi - lo
    kind = classify_dof(lo, hi, dof)
    if kind == "locked" or (kind == "full" and width >= 2.0 * math.pi - 1e-6):
        return 0.0
    rotation = not dof.startswith("t")
    bounds = [NOISE_ROTATION, FULL_ROTATION] if rotation else [NOISE_TRANSLATION]
    dist = min(abs(math.log(width / b)) for b in bounds)
    return math.exp(-(dist**2) / (2.0 * SIGMA**2))


def _dof_text(child: str, parent: str, dof: str, lo: float, hi: float) -> str:
    kind = classify_dof(lo, hi, dof)
    unit, scale = ("cm", 100.0) if dof.startswith("t") else ("°", 180.0 / math.pi)
    span = f"{lo * scale:.3g} to {hi * scale:.3g} {unit}"
    what = _DOF_WORDS[dof]
    if kind == "noise":
        return f"Can {child} {what} on {parent} ({span}), or is that noise and it is locked?"
    if kind == "full":
        return f"Can {child} {what} on {parent} all the way round?"
    return f"Can {child} {what} on {parent} by {span}?"


def clarification_queue(task: TaskFile, *, focus: str | None = None) -> list[Question]:
    """The questions to ask about a task, the least certain first.

    One question per constraint (its confidence) and one per DOF of it (its
    range's ambiguity, see :func:`dof_ambiguity`); what the person confirmed
    already (``stages.review.confirmed``) is left out. Ties keep the task's
    order (constraints, then DOFs in :data:`~thirdhand.taskfile.DOF_NAMES` order).

    Parameters
    ----------
    task : TaskFile
    focus : str, optional
        An object the person singled out (:func:`thirdhand.review.focus.perception_focus`):
        the questions about the constraint whose child it is come first, then
        those about constraints whose parent it is, each marked ``focused``. An
        object in no constraint changes nothing.

    Returns
    -------
    list of Question
        Sorted by focus group, then decreasing score.
    """
    confirmed = task.stages.review.confirmed if task.stages.review is not None else {}
    out: list[Question] = []
    group: dict[str, int] = {}
    for c in task.constraints:
        group[c.id] = 0 if c.child == focus else 1 if c.parent == focus else 2
        focused = group[c.id] < 2
        done = set(confirmed.get(c.id, []))
        if "constraint" not in done:
            # Wrong if the constraint does not hold, or holds as the runner-up's type.
            other = 0.0 if c.runner_up is None else c.runner_up.probability
            alt = "" if c.runner_up is None else f"; or {c.runner_up.type}, {other:.0%}"
            out.append(
                Question(
                    c.id,
                    None,
                    1.0 - c.confidence * (1.0 - other),
                    f"Is {c.child} {c.type} on {c.parent} as shown "
                    f"(confidence {c.confidence:.0%}{alt})?",
                    focused,
                )
            )
        for dof in DOF_NAMES:
            if dof in done:
                continue
            lo, hi = c.free_dofs[dof]
            out.append(
                Question(
                    c.id,
                    dof,
                    0.5 * dof_ambiguity(lo, hi, dof),
                    _dof_text(c.child, c.parent, dof, lo, hi),
                    focused,
                )
            )
    order = {id(q): k for k, q in enumerate(out)}
    out.sort(key=lambda q: (group[q.constraint], -q.score, order[id(q)]))
    return out
