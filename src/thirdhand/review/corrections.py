"""From what a person typed, chose or dragged to the edits of :mod:`~thirdhand.review.edits`.

Pure functions: each takes the constraint (or learned motion) being corrected and
the raw widget input and returns the typed edits with the effort operation each is
counted as, or raises :class:`~thirdhand.errors.ThirdhandError` with the line the
person reads. Every value is parsed before any edit is made, so one bad value
changes nothing.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from thirdhand.arrays import FloatArray
from thirdhand.errors import ThirdhandError
from thirdhand.review.edits import (
    SetDofRange,
    SetParent,
    SetPose,
    SetPoseValue,
    SetPrimitivePoint,
    parse_number,
    pose_values,
)
from thirdhand.review.effort import VALUE_OPERATION
from thirdhand.review.gizmo import GizmoMove, dominant_operation, moved_child
from thirdhand.review.primitive_edit import PrimitivePath
from thirdhand.se3 import pose_compose, pose_invert
from thirdhand.task.constraint import Constraint

#: What a dropdown shows for no object.
NONE = "(none)"
#: Translations are typed and shown in cm, rotations in degrees.
TRANSLATIONS = ("x", "y", "z", "tx", "ty", "tz")


def unit_of(name: str) -> str:
    """The unit a bare number typed for pose value or DOF ``name`` is read in."""
    return "cm" if name in TRANSLATIONS else "deg"


def changed_texts(texts: Mapping[str, str], shown: Mapping[str, str]) -> dict[str, str]:
    """The texts that differ from what the panel showed (only those are applied)."""
    return {n: t for n, t in texts.items() if t != shown.get(n)}


def value_edits(c: Constraint, texts: Mapping[str, str]) -> list[tuple[SetPoseValue, str]]:
    """Typed pose values of ``c`` (``{"x": "12 cm", "yaw": "90 deg"}``) as edits.

    A bare number is read in the unit shown (cm, deg).

    Returns
    -------
    list of (SetPoseValue, str)
        One edit per value with its effort operation, in the order given.
    """
    values = {name: parse_number(text, unit=unit_of(name)) for name, text in texts.items()}
    return [(SetPoseValue(c.id, n, v), VALUE_OPERATION[n]) for n, v in values.items()]


def nudge_delta(name: str, step: str) -> float:
    """A nudge button's step (``"-5"``: cm for x y z, degrees otherwise) in m or rad."""
    value = float(step)
    return value / 100.0 if name in ("x", "y", "z") else math.radians(value)


def nudge_edit(c: Constraint, name: str, delta: float) -> tuple[SetPoseValue, str]:
    """Add ``delta`` (m or rad) to pose value ``name`` of ``c``; the edit and its operation."""
    current = pose_values(c)[name]
    return SetPoseValue(c.id, name, current + delta), VALUE_OPERATION[name]


def range_edit(c: Constraint, dof: str, lo: str, hi: str) -> SetDofRange:
    """The free range of ``dof`` typed as two texts (a bare number in the unit shown)."""
    unit = unit_of(dof)
    return SetDofRange(c.id, dof, parse_number(lo, unit=unit), parse_number(hi, unit=unit))


def parent_edit(child: str | None, parent: str) -> SetParent:
    """Make ``parent`` (a dropdown's value, :data:`NONE` for none) the parent of ``child``."""
    if child is None or parent == NONE:
        raise ThirdhandError("select an object and its new parent first")
    return SetParent(child, parent)


def reparent_edit(child: str | None, parent: str) -> SetParent:
    """A shift-click on ``parent`` in the 3D view with ``child`` selected."""
    if child is None:
        raise ThirdhandError("select the child first, then shift-click its new parent")
    return SetParent(child, parent)


def key_point_edit(path: PrimitivePath, index: int, texts: Mapping[str, str]) -> SetPrimitivePoint:
    """Move key point ``index`` of ``path`` to the typed ``{"x": "12 cm", ...}`` (parent frame).

    A bare number is in cm; a coordinate not given (or blank) stays.
    """
    point = [float(v) for v in path.key_points[index]]
    for k, name in enumerate("xyz"):
        text = texts.get(name, "").strip()
        if text:
            point[k] = parse_number(text, unit="cm")
    return SetPrimitivePoint(path.key, index, (point[0], point[1], point[2]))


def dragged_key_point(key: str, index: int, point: FloatArray) -> SetPrimitivePoint:
    """Key point ``index`` of motion ``key`` released at ``point`` (shape (3,), m, parent frame)."""
    return SetPrimitivePoint(key, index, (float(point[0]), float(point[1]), float(point[2])))


def gizmo_pose(child: Any, c: Constraint, move: GizmoMove) -> tuple[FloatArray, FloatArray]:
    """Where the gizmo drag ``move`` puts ``c``'s child: position (m) and quaternion
    x y z w, world frame, from the child's world pose ``child`` (``.pos``, ``.quat``)."""
    return moved_child(child, c.frame, move.pos, move.quat)


def gizmo_edit(
    c: Constraint, parent: Any, pos: FloatArray, quat: FloatArray, move: GizmoMove
) -> tuple[SetPose, str]:
    """The pose correction of a released gizmo drag: the child's new world pose
    (``pos`` m, ``quat`` x y z w) in its parent's frame (``parent``: world pose with
    ``.pos``, ``.quat``), and the operation the drag is counted as."""
    lp, lq = pose_compose(*pose_invert(parent.pos, parent.quat), pos, quat)
    edit = SetPose(
        c.id,
        (float(lp[0]), float(lp[1]), float(lp[2])),
        (float(lq[0]), float(lq[1]), float(lq[2]), float(lq[3])),
    )
    return edit, dominant_operation(move.pos, move.quat)


def step_index(label: str) -> int:
    """The 0-based plan step of a Step list label (``"2. leg3 on seating (c3)"``)."""
    try:
        return int(label.split(".", 1)[0]) - 1
    except ValueError:
        raise ThirdhandError("the plan has no step to choose") from None


__all__ = [
    "NONE",
    "changed_texts",
    "dragged_key_point",
    "gizmo_edit",
    "gizmo_pose",
    "key_point_edit",
    "nudge_delta",
    "nudge_edit",
    "parent_edit",
    "range_edit",
    "reparent_edit",
    "step_index",
    "unit_of",
    "value_edits",
]
