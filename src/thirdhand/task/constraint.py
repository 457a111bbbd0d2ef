"""A learned or corrected kinematic constraint, and its 19-number row form.

The row form is the one of the 3rdHand correction GUI and its IROS 2015 user
study: position x y z (m), quaternion x y z w, then six ``(min, max)`` pairs for
tx ty tz (m) and rx ry rz (rad) — 19 numbers, or only the first 7 when every
DOF is locked.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Annotated, Any, Literal, get_args

import numpy as np
from pydantic import (
    Field,
    SerializerFunctionWrapHandler,
    StringConstraints,
    ValidationError,
    model_serializer,
)

from thirdhand.arrays import FloatArray
from thirdhand.errors import TaskFileError
from thirdhand.task.geometry import (
    DOF_NAMES,
    IDENTITY_QUAT,
    ORIGIN,
    FreeDofs,
    Pose,
    Quat,
    TaskModel,
    UnitInterval,
    Vec3,
)

ConstraintType = Literal["fixed", "prismatic", "revolute", "free", "cylindrical", "screw"]
CONSTRAINT_TYPES: tuple[str, ...] = get_args(ConstraintType)
ConstraintSource = Literal["learned", "corrected"]
Name = Annotated[str, StringConstraints(min_length=1)]

#: Length of a full constraint row: 3 position + 4 quaternion + 6 x (min, max).
ROW_LENGTH = 19
#: Length of a short row: pose only, every DOF locked.
SHORT_ROW_LENGTH = 7


def infer_constraint_type(free_dofs: FreeDofs) -> ConstraintType:
    """The constraint type implied by which DOFs are free.

    None free: ``fixed``; all six: ``free``; one rotation: ``revolute``; one
    translation: ``prismatic``; a translation and a rotation about the same axis:
    ``cylindrical`` (a ``screw`` has the same ranges and is never inferred); any
    other combination: ``free`` (a general constraint whose ranges say the rest).
    """
    free = free_dofs.free()
    trans = [n[1] for n in free if n[0] == "t"]
    rots = [n[1] for n in free if n[0] == "r"]
    if not free:
        return "fixed"
    if len(trans) == 1 and not rots:
        return "prismatic"
    if len(rots) == 1 and not trans:
        return "revolute"
    if len(trans) == 1 and trans == rots:
        return "cylindrical"
    return "free"


def drop_empty_runner_up(data: dict[str, object]) -> dict[str, object]:
    """A record's serialised fields without ``runner_up`` when it is None (files written
    before it existed read back as they were)."""
    if data.get("runner_up", 0) is None:
        del data["runner_up"]
    return data


class RunnerUp(TaskModel):
    """The joint type the detector found next most likely, with its geometry.

    Attributes
    ----------
    type : str
        One of the constraint types.
    probability : float
        Its probability among the types compared, in [0, 1] (the constraint's own
        type has the rest, or most of it).
    axis : tuple of 3 floats or None
        Unit joint axis in the parent frame (None for ``fixed``).
    origin : tuple of 3 floats or None
        A point on a revolute joint's axis, parent frame, metres.
    radius : float or None
        Distance of the child's origin from a revolute axis, metres.
    travel : float
        Motion along the joint over the demonstration: metres for ``prismatic``,
        radians for ``revolute``, 0 for ``fixed``.
    """

    type: ConstraintType
    probability: UnitInterval
    axis: Vec3 | None = None
    origin: Vec3 | None = None
    radius: float | None = Field(default=None, ge=0.0)
    travel: float = Field(default=0.0, ge=0.0)


class Constraint(TaskModel):
    """A kinematic constraint between two objects.

    Attributes
    ----------
    id : str
        Unique within a task file; plan steps refer to it.
    parent, child : str
        Object names; the pose is the child's in the parent's frame.
    type : {"fixed", "prismatic", "revolute", "free", "cylindrical", "screw"}
    pos : tuple of 3 floats
        Child origin in the parent frame, metres, when the constraint is made.
    quat : tuple of 4 floats
        Child orientation in the parent frame, unit quaternion x y z w.
    frame : Pose
        The constraint frame, as a pose in the child frame (default identity).
    free_dofs : FreeDofs
        ``[min, max]`` of tx ty tz (m) and rx ry rz (rad) in the constraint frame.
    symbol : str or None
        The constraint's symbol (a slot such as ``"c2"``).
    confidence : float
        In [0, 1].
    source : {"learned", "corrected"}
        Whether a person corrected it.
    time : float or None
        Seconds on the demonstration's time axis when it appears.
    demo : str or None
        The demonstration it was learned from.
    runner_up : RunnerUp or None
        The type that explains the motion next best, for a joint the detector
        chose between types (None otherwise, and after a person's correction).
    """

    id: Name
    parent: Name
    child: Name
    type: ConstraintType
    pos: Vec3 = ORIGIN
    quat: Quat = IDENTITY_QUAT
    frame: Pose = Field(default_factory=Pose)
    free_dofs: FreeDofs = Field(default_factory=FreeDofs)
    symbol: str | None = None
    confidence: UnitInterval = 1.0
    source: ConstraintSource = "learned"
    time: float | None = None
    demo: str | None = None
    runner_up: RunnerUp | None = None

    @model_serializer(mode="wrap")
    def _no_empty_runner_up(self, handler: SerializerFunctionWrapHandler) -> dict[str, object]:
        return drop_empty_runner_up(handler(self))

    @property
    def pose(self) -> Pose:
        """The child's pose in the parent frame."""
        return Pose(pos=self.pos, quat=self.quat)

    def free_dof_array(self) -> FloatArray:
        """DOF ranges, shape (6, 2): rows tx ty tz (m) rx ry rz (rad), constraint frame."""
        return self.free_dofs.array()

    @classmethod
    def from_row(
        cls,
        row: Sequence[float],
        *,
        parent: str,
        child: str,
        symbol: str,
        id: str | None = None,
        type: ConstraintType | None = None,
        **fields: Any,
    ) -> Constraint:
        """Build from a 19-number (or 7-number, all locked) constraint row.

        Parameters
        ----------
        row : sequence of 19 or 7 floats
            Position x y z (m, child in parent), quaternion x y z w, then
            ``(min, max)`` of tx ty tz (m) and rx ry rz (rad).
        parent, child : str
            Object names.
        symbol : str
            The constraint's symbol; also its id unless ``id`` is given.
        id : str, optional
        type : str, optional
            Inferred from the free DOFs (:func:`infer_constraint_type`) when omitted.
        **fields
            Any other :class:`Constraint` field (``confidence``, ``source``, ``time``...).

        Raises
        ------
        TaskFileError
            For a row of another length, a non-number, a zero or non-unit
            quaternion, or a range with min > max.
        """
        values = list(row)
        where = f"constraint {symbol!r} ({parent} -> {child})"
        if len(values) not in (ROW_LENGTH, SHORT_ROW_LENGTH):
            raise TaskFileError(
                f"{where}: expected a row of {ROW_LENGTH} (or {SHORT_ROW_LENGTH}) numbers, "
                f"got {len(values)}"
            )
        for i, v in enumerate(values):
            if isinstance(v, bool) or not isinstance(v, int | float):
                raise TaskFileError(f"{where}: row[{i}] is {v!r}, expected a number")
        nums = [float(v) for v in values]
        pairs = zip(nums[7::2], nums[8::2], strict=True)
        try:
            c = cls.model_validate(
                {
                    "id": symbol if id is None else id,
                    "parent": parent,
                    "child": child,
                    "type": "free" if type is None else type,
                    "pos": (nums[0], nums[1], nums[2]),
                    "quat": (nums[3], nums[4], nums[5], nums[6]),
                    "free_dofs": dict(zip(DOF_NAMES, pairs, strict=False)),
                    "symbol": symbol,
                    **fields,
                }
            )
        except ValidationError as exc:
            from thirdhand.task.errors import first_error

            raise TaskFileError(f"{where}: {first_error(exc)}") from None
        if type is None:
            c.type = infer_constraint_type(c.free_dofs)
        return c

    def to_row(self) -> list[float]:
        """The 19-number row: pos (3), quat x y z w (4), (min, max) of tx ty tz rx ry rz.

        Raises
        ------
        TaskFileError
            If the constraint frame is not the identity (the row cannot hold it).
        """
        if not self.frame.is_identity:
            raise TaskFileError(
                f"constraint {self.id!r}: a row cannot hold a constraint frame other than "
                "the identity; express the DOF ranges in the child frame first"
            )
        row = [*self.pos, *self.quat]
        for lo, hi in self.free_dofs.ranges():
            row += [lo, hi]
        return row

    def row_array(self) -> FloatArray:
        """:meth:`to_row` as an array, shape (19,)."""
        return np.asarray(self.to_row(), dtype=np.float64)
