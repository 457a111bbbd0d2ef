"""Corrections of a task as plain, pure functions: ``apply_edit(task, edit) -> task``.

An edit is a small frozen record (set a pose value, a DOF range, a parent, move a
plan step, confirm). :func:`apply_edit` checks it against the task, refuses bad
input with an :class:`EditError` (the task is left as it was: every edit returns
a new task), marks the constraints it changed as ``source = "corrected"`` and
records one provenance :class:`~thirdhand.taskfile.Correction` per changed
parameter, its ``field`` the JSON location (``constraints[2].free_dofs.rz``).

Pose values are the child's pose in the parent frame: ``x y z`` in metres and
``roll pitch yaw`` in radians, extrinsic rotations about the parent's x, y, z
axes in that order (``scipy`` ``"xyz"``).

Plan reordering and the partial order (``TaskStep.after``): a plan whose steps
each follow just the previous one (``after`` all None, or the chain
``[], [0], [1]...`` the learner writes) is a total order made by the
demonstration, and a move simply makes the new order the total order. In a true
partial order, indices are remapped to the new positions and a dependency the
move contradicts (a step moved before one it must follow, or after one that must
follow it) is dropped and recorded in the provenance with the reason; implied
dependencies that the move keeps valid are kept (transitively reduced). A move
with ``keep_order`` (what the GUI's plan timeline and Up/Down make) is instead
refused when it contradicts a true partial order: :func:`order_conflict` says why.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from pydantic import ValidationError

from thirdhand import se3
from thirdhand.errors import ThirdhandError
from thirdhand.review.dofs import relative, world_poses
from thirdhand.task.constraint import Constraint, infer_constraint_type
from thirdhand.task.errors import first_error
from thirdhand.task.geometry import DOF_NAMES
from thirdhand.task.model import Correction, TaskFile, utc_now

#: Names of the pose values of :class:`SetPoseValue`: metres, then radians.
POSE_VALUE_NAMES: tuple[str, ...] = ("x", "y", "z", "roll", "pitch", "yaw")
#: The widest rotation range accepted, radians (a full turn and a little slack).
MAX_ROTATION_RANGE = 2.0 * math.pi + 1e-2


class EditError(ThirdhandError, ValueError):
    """An edit that cannot be applied: bad number, unknown id, parent cycle, bad index."""


@dataclass(frozen=True)
class SetPose:
    """Set the child's pose in the parent frame (a None part is left unchanged).

    ``pos`` in metres; ``quat`` x y z w (normalised; zero refused).
    """

    constraint: str
    pos: tuple[float, float, float] | None = None
    quat: tuple[float, float, float, float] | None = None


@dataclass(frozen=True)
class SetPoseValue:
    """Set one pose value: ``x y z`` (m) or ``roll pitch yaw`` (rad, extrinsic xyz)."""

    constraint: str
    name: str
    value: float


@dataclass(frozen=True)
class SetDofRange:
    """Set a DOF range ``[lo, hi]`` (m or rad, constraint frame); ``(0, 0)`` locks it."""

    constraint: str
    dof: str
    lo: float
    hi: float


@dataclass(frozen=True)
class SetParent:
    """Give the constraint(s) whose child is ``child`` the parent ``parent``.

    The child's world pose at the constraint's plan step is kept (the constraint
    pose is re-expressed in the new parent's frame); a parent cycle is refused.
    """

    child: str
    parent: str


@dataclass(frozen=True)
class MoveStep:
    """Move the plan step at ``index`` to ``new_index`` (the others shift).

    ``keep_order``: refuse a move that puts a step before one it must follow (or
    after one that must follow it) in a true partial order (:func:`order_conflict`);
    otherwise such a dependency is dropped and the drop recorded.
    """

    index: int
    new_index: int
    keep_order: bool = False


@dataclass(frozen=True)
class Confirm:
    """The person says the constraint (or one of its DOFs) is right.

    The constraint's confidence becomes 1 and its runner-up type is dropped
    (whole-constraint confirmation); the confirmation is listed in
    ``stages.review.confirmed`` so the clarification round does not ask again.
    Nothing else changes.
    """

    constraint: str
    dof: str | None = None


@dataclass(frozen=True)
class SetPrimitivePoint:
    """Move key point ``index`` of the learned motion ``key`` to ``pos`` (m, parent frame).

    The primitive is refitted (:func:`~thirdhand.review.primitive_edit.move_key_point`)
    and saved in the task's ``stages.primitives`` block; its start, goal and
    orientation stay.
    """

    key: str
    index: int
    pos: tuple[float, float, float]


Edit = SetPose | SetPoseValue | SetDofRange | SetParent | MoveStep | Confirm | SetPrimitivePoint

_NUMBER = re.compile(r"^\s*([+-]?(?:\d+(?:[.,]\d*)?|[.,]\d+)(?:[eE][+-]?\d+)?)\s*([A-Za-z°µ]*)\s*$")
_LENGTH = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "µm": 1e-6, "um": 1e-6}
_ANGLE = {
    "rad": 1.0,
    "deg": math.pi / 180.0,
    "°": math.pi / 180.0,
    "degree": math.pi / 180.0,
    "degrees": math.pi / 180.0,
}


def parse_number(text: str, *, unit: str) -> float:
    """A number typed by a person, in SI units (metres or radians).

    Parameters
    ----------
    text : str
        ``"0.12"``, ``"12 cm"``, ``"120mm"``, ``"1e-3 m"``, ``"45 deg"``, ``"45°"``,
        ``"0,5"`` (decimal comma)...
    unit : {"m", "cm", "mm", "rad", "deg"}
        The unit of a bare number; a unit typed in the text must measure the same
        thing (a length or an angle).

    Returns
    -------
    float
        Metres for a length, radians for an angle.

    Raises
    ------
    EditError
        Not a number, NaN or infinite, an unknown unit, or a length typed where an
        angle is expected (or the other way round).
    """
    if unit in _LENGTH:
        table = _LENGTH
    elif unit in _ANGLE:
        table = _ANGLE
    else:
        raise EditError(f"unknown unit {unit!r}; expected one of m, cm, mm, rad, deg")
    match = _NUMBER.match(text)
    if match is None:
        raise EditError(f"{text!r} is not a number (e.g. 0.12, 12 cm, 45 deg)")
    number, typed = match.group(1).replace(",", "."), match.group(2)
    typed = typed or unit
    if typed not in table:
        kind = "length (m, cm, mm)" if table is _LENGTH else "angle (rad, deg)"
        raise EditError(f"{text!r}: unit {typed!r} is not a {kind}")
    value = float(number) * table[typed]
    if not math.isfinite(value):
        raise EditError(f"{text!r} is not a finite number")
    return value


def _finite(value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating | np.integer):
        raise EditError(f"{what}: expected a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise EditError(f"{what}: expected a finite number, got {v}")
    return v


def _constraint_index(task: TaskFile, cid: str) -> int:
    for i, c in enumerate(task.constraints):
        if c.id == cid:
            return i
    raise EditError(
        f"unknown constraint {cid!r}; ids are {', '.join(c.id for c in task.constraints)}"
    )


class _Recorder:
    """Collects the corrections of one edit (same author and time)."""

    def __init__(self, task: TaskFile, who: str) -> None:
        self.task = task
        self.who = who
        self.when = utc_now()
        self.changed: set[int] = set()

    def __call__(self, field: str, old: Any, new: Any, **extra: Any) -> None:
        self.task.provenance.corrections.append(
            Correction(who=self.who, when=self.when, field=field, old=old, new=new, **extra)
        )
        self.task.provenance.modified = self.when


def _rpy(quat: Sequence[float]) -> list[float]:
    return [float(v) for v in se3.euler_from_quat(np.asarray(quat, dtype=float), "xyz")]


def _quat_from_rpy(rpy: Sequence[float]) -> tuple[float, float, float, float]:
    q = se3.quat_from_euler(np.asarray(rpy, dtype=float), "xyz")
    return (float(q[0]), float(q[1]), float(q[2]), float(q[3]))


def pose_values(constraint: Constraint) -> dict[str, float]:
    """The six pose values of a constraint: x y z (m), roll pitch yaw (rad, extrinsic xyz)."""
    return dict(zip(POSE_VALUE_NAMES, [*constraint.pos, *_rpy(constraint.quat)], strict=True))


#: Largest offset (m) of a child from its parent an edit may set: beyond it a typed
#: value is a slip (``1e9 m``), and the part would vanish from the view.
PLAUSIBLE_OFFSET_M = 5.0


def _set_pos(task: TaskFile, i: int, pos: Sequence[float], rec: _Recorder) -> None:
    c = task.constraints[i]
    new = tuple(_finite(v, f"constraint {c.id!r} position[{k}]") for k, v in enumerate(pos))
    if len(new) != 3:
        raise EditError(f"constraint {c.id!r}: expected 3 position values, got {len(new)}")
    for k, v in enumerate(new):
        if abs(v) > PLAUSIBLE_OFFSET_M and abs(v) > abs(c.pos[k]):
            raise EditError(
                f"constraint {c.id!r}: {'xyz'[k]} = {v:.4g} m is not plausible "
                f"(a part within {PLAUSIBLE_OFFSET_M:g} m of its parent expected)"
            )
    for k in range(3):
        if new[k] != c.pos[k]:
            rec(f"constraints[{i}].pos[{k}]", c.pos[k], new[k])
            rec.changed.add(i)
    c.pos = (new[0], new[1], new[2])


def _set_quat(task: TaskFile, i: int, quat: Sequence[float], rec: _Recorder, **extra: Any) -> None:
    c = task.constraints[i]
    q = [_finite(v, f"constraint {c.id!r} quaternion[{k}]") for k, v in enumerate(quat)]
    if len(q) != 4:
        raise EditError(
            f"constraint {c.id!r}: expected a quaternion of 4 values x y z w, got {len(q)}"
        )
    norm = math.sqrt(sum(v * v for v in q))
    if norm < 1e-9:
        raise EditError(f"constraint {c.id!r}: quaternion of zero norm")
    new = (q[0] / norm, q[1] / norm, q[2] / norm, q[3] / norm)
    if new != c.quat:
        rec(f"constraints[{i}].quat", list(c.quat), list(new), **extra)
        rec.changed.add(i)
    c.quat = new


def _set_pose(task: TaskFile, e: SetPose, rec: _Recorder) -> None:
    i = _constraint_index(task, e.constraint)
    if e.pos is not None:
        _set_pos(task, i, e.pos, rec)
    if e.quat is not None:
        _set_quat(task, i, e.quat, rec)


def _set_pose_value(task: TaskFile, e: SetPoseValue, rec: _Recorder) -> None:
    i = _constraint_index(task, e.constraint)
    c = task.constraints[i]
    if e.name not in POSE_VALUE_NAMES:
        raise EditError(
            f"constraint {c.id!r}: unknown pose value {e.name!r}; "
            f"expected one of {', '.join(POSE_VALUE_NAMES)}"
        )
    value = _finite(e.value, f"constraint {c.id!r} {e.name}")
    k = POSE_VALUE_NAMES.index(e.name)
    if k < 3:
        pos = list(c.pos)
        pos[k] = value
        _set_pos(task, i, pos, rec)
        return
    rpy = _rpy(c.quat)
    if rpy[k - 3] == value:
        return
    rpy[k - 3] = value
    _set_quat(task, i, _quat_from_rpy(rpy), rec, parameter=e.name)


def _set_dof_range(task: TaskFile, e: SetDofRange, rec: _Recorder) -> None:
    i = _constraint_index(task, e.constraint)
    c = task.constraints[i]
    if e.dof not in DOF_NAMES:
        raise EditError(
            f"constraint {c.id!r}: unknown DOF {e.dof!r}; expected one of {', '.join(DOF_NAMES)}"
        )
    lo = _finite(e.lo, f"constraint {c.id!r} {e.dof} min")
    hi = _finite(e.hi, f"constraint {c.id!r} {e.dof} max")
    if lo > hi:
        raise EditError(
            f"constraint {c.id!r} {e.dof}: min {_shown(e.dof, lo)} > max {_shown(e.dof, hi)}"
        )
    if e.dof.startswith("r") and hi - lo > MAX_ROTATION_RANGE:
        raise EditError(
            f"constraint {c.id!r} {e.dof}: range {_shown(e.dof, lo)} to {_shown(e.dof, hi)} "
            "is wider than a full turn (360°)"
        )
    if e.dof.startswith("t") and max(abs(lo), abs(hi)) > PLAUSIBLE_OFFSET_M:
        raise EditError(
            f"constraint {c.id!r} {e.dof}: range {_shown(e.dof, lo)} to {_shown(e.dof, hi)} "
            f"is not plausible (a part within {PLAUSIBLE_OFFSET_M:g} m of its parent expected)"
        )
    old = c.free_dofs[e.dof]
    if (lo, hi) == tuple(old):
        return
    rec(f"constraints[{i}].free_dofs.{e.dof}", list(old), [lo, hi])
    rec.changed.add(i)
    dofs = dataclasses.replace(c.free_dofs, **{e.dof: (lo, hi)})
    c.free_dofs = dofs
    inferred = infer_constraint_type(dofs)
    if not (c.type == "screw" and inferred == "cylindrical") and inferred != c.type:
        rec(f"constraints[{i}].type", c.type, inferred)
        c.type = inferred


def _cycle(task: TaskFile, child: str, parent: str, skip: set[int]) -> list[str] | None:
    """The chain parent -> ... -> child through the other constraints' parents, if any."""
    parents: dict[str, list[str]] = {}
    for k, c in enumerate(task.constraints):
        if k not in skip:
            parents.setdefault(c.child, []).append(c.parent)
    stack: list[list[str]] = [[parent]]
    seen: set[str] = set()
    while stack:
        path = stack.pop()
        node = path[-1]
        if node == child:
            return path
        if node in seen:
            continue
        seen.add(node)
        stack.extend([*path, p] for p in parents.get(node, []))
    return None


def _set_parent(task: TaskFile, e: SetParent, rec: _Recorder) -> None:
    names = {o.name for o in task.objects}
    for what, name in (("child", e.child), ("parent", e.parent)):
        if name not in names:
            raise EditError(f"set parent: unknown {what} object {name!r}")
    if e.child == e.parent:
        raise EditError(f"set parent: {e.child!r} cannot be its own parent")
    targets = [k for k, c in enumerate(task.constraints) if c.child == e.child]
    if not targets:
        raise EditError(f"set parent: no constraint has the child {e.child!r}")
    chain = _cycle(task, e.child, e.parent, set(targets))
    if chain is not None:
        loop = " -> ".join([e.child, *chain])
        raise EditError(f"set parent: {e.parent!r} as parent of {e.child!r} makes a cycle ({loop})")
    step_of: dict[str, int] = {}
    for k, s in enumerate(task.plan):
        if s.constraint is not None:
            step_of.setdefault(s.constraint, k)
    for i in targets:
        c = task.constraints[i]
        if c.parent == e.parent:
            continue
        world = world_poses(task, step_of.get(c.id))
        pose = relative(world[e.parent], world[e.child])
        rec(f"constraints[{i}].parent", c.parent, e.parent)
        rec.changed.add(i)
        c.parent = e.parent
        _set_pos(task, i, pose.pos, rec)
        _set_quat(task, i, pose.quat, rec)
        for k, s in enumerate(task.plan):
            if s.constraint == c.id and s.parent != e.parent:
                rec(f"plan[{k}].parent", s.parent, e.parent)
                s.parent = e.parent


def _is_chain(preds: list[list[int]]) -> bool:
    return all(p == ([i - 1] if i else []) for i, p in enumerate(preds))


def _closure(preds: list[list[int]]) -> list[set[int]]:
    """For each step, every step it must follow (transitively)."""
    out: list[set[int]] = []
    for p in preds:
        s: set[int] = set()
        for j in p:
            s.add(j)
            s |= out[j]
        out.append(s)
    return out


def _step_name(task: TaskFile, i: int) -> str:
    s = task.plan[i]
    return f"step {i + 1} ({s.child} on {s.parent})"


def is_partial_order(task: TaskFile) -> bool:
    """True when the plan's ``after`` lists are a true partial order, not the
    demonstration's total order (all None, or each step after just the previous one)."""
    if all(s.after is None for s in task.plan):
        return False
    return not _is_chain(task.predecessors())


def order_conflict(task: TaskFile, index: int, new_index: int) -> str | None:
    """Why moving plan step ``index`` to position ``new_index`` breaks the partial order.

    Parameters
    ----------
    task : TaskFile
    index, new_index : int
        Plan indices (0-based), both in range.

    Returns
    -------
    str or None
        ``"step 5 (back on seating) must follow step 4 (leg1 on seating): it cannot
        move to position 3"``; None when the move keeps every dependency (always
        for the demonstration's total order, which any move may change).
    """
    if index == new_index or not is_partial_order(task):
        return None
    closure = _closure(task.predecessors())
    lo, hi = sorted((index, new_index))
    between = range(lo, hi + 1)
    if new_index < index:  # moved earlier: past a step it must follow?
        for j in reversed(between):
            if j != index and j in closure[index]:
                return (
                    f"{_step_name(task, index)} must follow {_step_name(task, j)}: "
                    f"it cannot move to position {new_index + 1}"
                )
    else:  # moved later: past a step that must follow it?
        for j in between:
            if j != index and index in closure[j]:
                return (
                    f"{_step_name(task, j)} must follow {_step_name(task, index)}: "
                    f"{_step_name(task, index)} cannot move to position {new_index + 1}"
                )
    return None


def _move_step(task: TaskFile, e: MoveStep, rec: _Recorder) -> None:
    n = len(task.plan)
    for what, v in (("index", e.index), ("new index", e.new_index)):
        if isinstance(v, bool) or not isinstance(v, int | np.integer) or not 0 <= v < n:
            raise EditError(f"move step: {what} {v!r} out of range (plan has {n} steps)")
    if e.index == e.new_index:
        return
    if e.keep_order:
        why = order_conflict(task, e.index, e.new_index)
        if why is not None:
            raise EditError(f"move refused: {why}")
    order = list(range(n))
    order.insert(e.new_index, order.pop(e.index))
    new_of = {old: new for new, old in enumerate(order)}
    preds = task.predecessors()
    label = [f"{s.parent}->{s.child}" for s in task.plan]
    steps = [task.plan[old] for old in order]
    rec("plan", label, [label[old] for old in order], parameter="order")
    if all(s.after is None for s in task.plan):
        task.plan = steps
        return
    if _is_chain(preds):
        for k, s in enumerate(steps):
            s.after = [k - 1] if k else []
        task.plan = steps
        return
    closure = _closure(preds)
    moved = e.index
    for old_b, direct in enumerate(preds):
        for old_a in direct:
            if new_of[old_a] > new_of[old_b]:
                rec(
                    f"plan[{new_of[old_b]}].after",
                    label[old_a],
                    None,
                    reason=(
                        f"step {label[old_b]} must follow {label[old_a]}, but the person moved "
                        f"{label[moved]} to position {e.new_index}; dependency dropped"
                    ),
                )
    for old_b in range(n):
        keep = {a for a in closure[old_b] if new_of[a] < new_of[old_b]}
        # Transitive reduction: drop a if it is implied through another kept b.
        reduced = [a for a in keep if not any(a in closure[b] for b in keep if b != a)]
        task.plan[old_b].after = sorted(new_of[a] for a in reduced)
    task.plan = steps


def _confirm(task: TaskFile, e: Confirm, rec: _Recorder) -> None:
    i = _constraint_index(task, e.constraint)
    c = task.constraints[i]
    if e.dof is not None and e.dof not in DOF_NAMES:
        raise EditError(
            f"confirm: unknown DOF {e.dof!r} of constraint {c.id!r}; "
            f"expected one of {', '.join(DOF_NAMES)}"
        )
    if e.dof is None and c.confidence != 1.0:
        rec(f"constraints[{i}].confidence", c.confidence, 1.0, parameter="confirm")
        c.confidence = 1.0
    if e.dof is None:
        c.runner_up = None  # the person chose the type shown over the runner-up
    entry = task.stages.ensure_review().confirmed.setdefault(c.id, [])
    what = e.dof if e.dof is not None else "constraint"
    if what not in entry:
        entry.append(what)


def _set_primitive_point(task: TaskFile, e: SetPrimitivePoint, rec: _Recorder) -> None:
    from thirdhand.review.primitive_edit import PrimitiveEditError, move_key_point, primitive_path

    what = f"primitive {e.key!r} key point {e.index + 1}"
    pos = [_finite(v, f"{what} {axis}") for v, axis in zip(e.pos, "xyz", strict=True)]
    far = max(abs(v) for v in pos)
    if far > PLAUSIBLE_OFFSET_M:
        raise EditError(
            f"{what}: {far:g} m from the parent is not plausible "
            f"(a part within {PLAUSIBLE_OFFSET_M:g} m of its parent expected)"
        )
    block = task.stages.primitives
    try:
        old = primitive_path(block, e.key).key_points
        new = move_key_point(block, e.key, e.index, pos)
    except PrimitiveEditError as exc:
        raise EditError(str(exc)) from None
    task.stages.primitives = new
    rec(
        f"stages.primitives.constraints.{e.key}.key_points[{e.index}]",
        [float(v) for v in old[e.index]],
        pos,
        parameter="primitive",
    )


def _shown(name: str, value: float) -> str:
    """A value as the panels show it: centimetres for a translation, degrees for a rotation."""
    if name in ("x", "y", "z") or name.startswith("t"):
        return f"{value * 100:.2f} cm"
    return f"{math.degrees(value):.1f}°"


def describe_edit(edit: Edit) -> str:
    """One line naming what an edit changes, in the units the panels show (cm, degrees)."""
    if isinstance(edit, SetPose):
        return f"new pose of {edit.constraint}"
    if isinstance(edit, SetPoseValue):
        return f"{edit.constraint} {edit.name} = {_shown(edit.name, edit.value)}"
    if isinstance(edit, SetDofRange):
        if edit.lo == edit.hi == 0.0:
            return f"{edit.constraint} {edit.dof} locked"
        lo, hi = _shown(edit.dof, edit.lo), _shown(edit.dof, edit.hi)
        return f"{edit.constraint} {edit.dof} range {lo} to {hi}"
    if isinstance(edit, SetParent):
        return f"{edit.child} now on {edit.parent}"
    if isinstance(edit, MoveStep):
        return f"step {edit.index + 1} moved to position {edit.new_index + 1}"
    if isinstance(edit, SetPrimitivePoint):
        where = ", ".join(f"{100.0 * v:.2f}" for v in edit.pos)
        return f"{edit.key} motion: key point {edit.index + 1} at ({where}) cm"
    what = f" {edit.dof}" if edit.dof is not None else ""
    return f"{edit.constraint}{what} confirmed"


def apply_edit(task: TaskFile, edit: Edit, *, who: str = "user") -> TaskFile:
    """Apply one correction; the input task is left untouched.

    Parameters
    ----------
    task : TaskFile
    edit : SetPose, SetPoseValue, SetDofRange, SetParent, MoveStep, Confirm or SetPrimitivePoint
    who : str
        Recorded as the author of the provenance corrections.

    Returns
    -------
    TaskFile
        A new task: changed constraints have ``source = "corrected"`` (and, after a
        DOF change, the type inferred from the free DOFs), and the provenance one
        correction per changed parameter.

    Raises
    ------
    EditError
        Invalid number (NaN, infinite, not a number), unknown constraint, object or
        DOF, ``lo > hi``, a parent cycle, a step index out of range, or a result
        that is not a valid task.
    """
    new = task.model_copy(deep=True)
    rec = _Recorder(new, who)
    if isinstance(edit, SetPose):
        _set_pose(new, edit, rec)
    elif isinstance(edit, SetPoseValue):
        _set_pose_value(new, edit, rec)
    elif isinstance(edit, SetDofRange):
        _set_dof_range(new, edit, rec)
    elif isinstance(edit, SetParent):
        _set_parent(new, edit, rec)
    elif isinstance(edit, MoveStep):
        _move_step(new, edit, rec)
    elif isinstance(edit, Confirm):
        _confirm(new, edit, rec)
    elif isinstance(edit, SetPrimitivePoint):
        _set_primitive_point(new, edit, rec)
    else:
        raise EditError(f"unknown edit {edit!r}")
    for i in rec.changed:
        new.constraints[i].source = "corrected"
        new.constraints[i].runner_up = None  # the person decided between the types
    try:
        return TaskFile.model_validate(new.model_dump(by_alias=True))
    except ValidationError as exc:
        raise EditError(
            f"{type(edit).__name__}: the result is not a valid task: {first_error(exc)}"
        ) from None


#: The issue's name for :func:`apply_edit`.
apply_correction = apply_edit
