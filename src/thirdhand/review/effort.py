"""The person's effort: GUI operations per object and changed parameters.

The 3rdHand IROS 2015 user study logged, per object, the operations people made in
the correction GUI (``click``, ``movex``/``y``/``z``, ``rotx``/``y``/``z``,
``parent``, ``reordering``, ``kfviews``); :class:`EffortLog` counts the same ones
(plus ``range``, ``confirm`` and ``primitive``, a moved key point of a learned
motion) and :func:`changed_parameters` the parameters that differ between two
tasks, in the report's unit (see ``research/notes/review.md``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from thirdhand.errors import ThirdhandError
from thirdhand.review.edits import (
    Confirm,
    Edit,
    MoveStep,
    SetDofRange,
    SetParent,
    SetPose,
    SetPoseValue,
    SetPrimitivePoint,
    pose_values,
)
from thirdhand.task.geometry import DOF_NAMES
from thirdhand.task.model import TaskFile
from thirdhand.task.stages import EffortRecord

#: GUI operations counted per object (the IROS'15 study's, then ``range``, ``confirm``,
#: ``primitive``).
OPERATIONS: tuple[str, ...] = (
    "click",
    "movex",
    "movey",
    "movez",
    "rotx",
    "roty",
    "rotz",
    "parent",
    "reordering",
    "kfviews",
    "range",
    "confirm",
    "primitive",
)
#: Object name under which plan-wide operations (reordering, keyframe views) are counted.
ACTIONS = "actions"

#: Effort operation of a typed pose value.
VALUE_OPERATION = {
    "x": "movex",
    "y": "movey",
    "z": "movez",
    "roll": "rotx",
    "pitch": "roty",
    "yaw": "rotz",
}


def operation_of(edit: Edit) -> str:
    """The GUI operation an edit stands for (``SetPose`` counts as ``movex``)."""
    if isinstance(edit, SetPoseValue):
        return VALUE_OPERATION.get(edit.name, "movex")
    if isinstance(edit, SetPose):
        return "movex"
    if isinstance(edit, SetDofRange):
        return "range"
    if isinstance(edit, SetParent):
        return "parent"
    if isinstance(edit, MoveStep):
        return "reordering"
    if isinstance(edit, Confirm):
        return "confirm"
    if isinstance(edit, SetPrimitivePoint):
        return "primitive"
    raise ThirdhandError(f"unknown edit {edit!r}")


class EffortLog:
    """Counts of GUI operations per object.

    Parameters
    ----------
    counts : mapping, optional
        Counts to start from (``{object: {operation: n}}``, e.g. read back from a
        task file's ``stages.review.effort.operations``).
    """

    def __init__(self, counts: Mapping[str, Mapping[str, int]] | None = None) -> None:
        self._counts: dict[str, dict[str, int]] = {}
        for obj, ops in (counts or {}).items():
            for op, n in ops.items():
                if op in OPERATIONS and isinstance(n, int) and n > 0:
                    self._counts.setdefault(str(obj), {})[op] = n

    def record(self, operation: str, obj: str) -> None:
        """Count one ``operation`` on object ``obj`` (``"actions"`` for plan-wide ones).

        Raises
        ------
        ThirdhandError
            For an operation not in :data:`OPERATIONS`.
        """
        if operation not in OPERATIONS:
            raise ThirdhandError(
                f"unknown effort operation {operation!r}; expected one of {', '.join(OPERATIONS)}"
            )
        ops = self._counts.setdefault(obj, {})
        ops[operation] = ops.get(operation, 0) + 1

    def counts(self) -> dict[str, dict[str, int]]:
        """``{object: {operation: count}}``, a copy."""
        return {obj: dict(ops) for obj, ops in self._counts.items()}

    def total(self) -> int:
        """All operations counted."""
        return sum(sum(ops.values()) for ops in self._counts.values())

    def to_stage(self, changed: list[str] | None = None) -> EffortRecord:
        """The record stored as ``task.stages.review.effort``.

        Parameters
        ----------
        changed : list of str, optional
            Changed parameters (:func:`changed_parameters`) to store with the counts.
        """
        out = EffortRecord(operations=self.counts(), total_operations=self.total())
        if changed is not None:
            out.changed_parameters = list(changed)
            out.n_changed_parameters = len(changed)
        return out


def _angle_diff(a: float, b: float) -> float:
    return abs(math.remainder(a - b, 2.0 * math.pi))


def changed_parameters(
    before: TaskFile, after: TaskFile, *, tol_pos: float = 1e-9, tol_rot: float = 1e-9
) -> list[str]:
    """The parameters that differ between two versions of a task.

    Constraints are matched by id. Per constraint: ``<id>.parent``, ``<id>.x|y|z``
    (beyond ``tol_pos`` metres), ``<id>.roll|pitch|yaw`` (beyond ``tol_rot``
    radians, extrinsic xyz), ``<id>.range.<dof>`` (any change of a DOF range);
    then ``plan.order`` if the sequence of (child, constraint) steps changed.

    Returns
    -------
    list of str
    """
    out: list[str] = []
    old = {c.id: c for c in before.constraints}
    for c in after.constraints:
        o = old.get(c.id)
        if o is None:
            out.append(f"{c.id}.added")
            continue
        if o.parent != c.parent:
            out.append(f"{c.id}.parent")
        pv_old, pv_new = pose_values(o), pose_values(c)
        for name in ("x", "y", "z"):
            if abs(pv_old[name] - pv_new[name]) > tol_pos:
                out.append(f"{c.id}.{name}")
        for name in ("roll", "pitch", "yaw"):
            if _angle_diff(pv_old[name], pv_new[name]) > tol_rot:
                out.append(f"{c.id}.{name}")
        for dof in DOF_NAMES:
            if o.free_dofs[dof] != c.free_dofs[dof]:
                out.append(f"{c.id}.range.{dof}")
    if [(s.child, s.constraint) for s in before.plan] != [
        (s.child, s.constraint) for s in after.plan
    ]:
        out.append("plan.order")
    return out


#: The study's operations that change a parameter in the report's unit (parent + pose).
PARAMETER_OPERATIONS: tuple[str, ...] = (
    "movex",
    "movey",
    "movez",
    "rotx",
    "roty",
    "rotz",
    "parent",
)


def study_effort(study: Any) -> dict[tuple[str, str], dict[str, float]]:
    """Mean effort of the first attempt per subject, per scene and condition of the IROS'15 study.

    Parameters
    ----------
    study : thirdhand.io.iros15.UserStudy

    Returns
    -------
    dict of (scene, condition) to dict
        ``attempts``; ``parameters``: mean count of (object, operation) pairs
        touched among :data:`PARAMETER_OPERATIONS` (the report's unit: at most 7
        per constrained object); ``operations``: mean number of those operations;
        ``per_object``: mean operations per object listed in the effort log.
    """
    rows: dict[tuple[str, str], list[tuple[int, int, float]]] = {}
    for _subject, scene, session, attempt in study.attempts():
        if attempt.index != 0:
            continue
        objs = {o: ops for o, ops in attempt.effort.items() if o != ACTIONS}
        if not objs:
            continue
        touched = sum(1 for ops in objs.values() for k in PARAMETER_OPERATIONS if ops.get(k, 0))
        n_ops = sum(ops.get(k, 0) for ops in objs.values() for k in PARAMETER_OPERATIONS)
        rows.setdefault((scene, session.name), []).append((touched, n_ops, n_ops / len(objs)))
    return {
        key: {
            "attempts": float(len(v)),
            "parameters": sum(r[0] for r in v) / len(v),
            "operations": sum(r[1] for r in v) / len(v),
            "per_object": sum(r[2] for r in v) / len(v),
        }
        for key, v in rows.items()
    }
