"""Validated geometric fields of the task file: positions, unit quaternions, poses, DOF ranges.

Every model here (and in the rest of :mod:`thirdhand.task`) keeps fields it does not
know (``extra="allow"``), so a file written by a newer thirdhand survives a round
trip through an older one, except :class:`FreeDofs`, whose six names are fixed.
"""

from __future__ import annotations

import math
from contextvars import ContextVar
from typing import Annotated, Any, Self

from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    ValidationError,
    model_validator,
)

from thirdhand.arrays import FloatArray

# Defined once, in the core types, and re-exported here for the task-file models.
from thirdhand.demonstration import DOF_NAMES as DOF_NAMES
from thirdhand.demonstration import FreeDofs as FreeDofs
from thirdhand.se3 import matrix_from_pose

#: A quaternion whose norm is within this of 1 is stored exactly as given (so
#: float32-exported data round-trip bit for bit).
QUAT_EXACT_TOL = 1e-6
#: A quaternion whose norm is within this of 1 (but not within QUAT_EXACT_TOL) is
#: normalised; beyond it, it is rejected as a probable typo.
QUAT_NORM_TOL = 1e-2


def non_finite_path(value: Any, where: str = "") -> str | None:
    """Where in ``value`` (nested lists and dicts) the first NaN or infinity is, else None.

    ``where`` prefixes the returned path (``"extra.scores[2]"``).
    """
    if isinstance(value, float):
        return None if math.isfinite(value) else where or "value"
    if isinstance(value, dict):
        for k, v in value.items():
            found = non_finite_path(v, f"{where}.{k}" if where else str(k))
            if found is not None:
                return found
    if isinstance(value, list | tuple):
        for i, v in enumerate(value):
            found = non_finite_path(v, f"{where}[{i}]")
            if found is not None:
                return found
    return None


#: True while a task-file model is being validated (models built inside it raise pydantic's
#: own error, which the outer validation places).
_VALIDATING: ContextVar[bool] = ContextVar("_VALIDATING", default=False)


class TaskModel(BaseModel):
    """Base of every task-file model: unknown fields kept, no NaN or infinity.

    Built in code (``Model(field=...)``, as the stages of ``learn`` build their
    blocks), an invalid value raises :class:`~thirdhand.errors.TaskFileError` on one
    line naming the model and the field, so that a stage that computed a NaN
    ends the command with a message, not a traceback. Unknown fields are held
    to the same rule: no NaN or infinity anywhere in them.
    """

    model_config = ConfigDict(
        extra="allow", allow_inf_nan=False, populate_by_name=True, ser_json_inf_nan="constants"
    )

    def __init__(self, /, **data: Any) -> None:
        if _VALIDATING.get():
            # Built inside another model's validation: its error keeps its location there.
            super().__init__(**data)
            return
        token = _VALIDATING.set(True)
        try:
            super().__init__(**data)
        except ValidationError as exc:
            from thirdhand.errors import TaskFileError
            from thirdhand.task.errors import first_error

            raise TaskFileError(f"{type(self).__name__}: {first_error(exc)}") from None
        finally:
            _VALIDATING.reset(token)

    # Nested models are still validated by pydantic's core (strict JSON mode kept), not
    # through this ``__init__``: it only wraps a model built in code.
    __init__.__pydantic_base_init__ = True  # type: ignore[attr-defined]

    @classmethod
    def model_validate(cls, obj: Any, *args: Any, **kwargs: Any) -> Self:
        """Validate ``obj``; pydantic's ``ValidationError`` on failure (its callers place it)."""
        token = _VALIDATING.set(True)
        try:
            return super().model_validate(obj, *args, **kwargs)
        finally:
            _VALIDATING.reset(token)

    @classmethod
    def model_validate_json(cls, json_data: Any, *args: Any, **kwargs: Any) -> Self:
        """Validate a JSON document; pydantic's ``ValidationError`` on failure."""
        token = _VALIDATING.set(True)
        try:
            return super().model_validate_json(json_data, *args, **kwargs)
        finally:
            _VALIDATING.reset(token)

    @model_validator(mode="after")
    def _finite_extras(self) -> TaskModel:
        for key, value in (self.model_extra or {}).items():
            found = non_finite_path(value, key)
            if found is not None:
                raise ValueError(f"{found}: not a finite number (NaN or infinity)")
        return self


def _unit_quat(q: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
    norm = math.sqrt(sum(c * c for c in q))
    if norm < 1e-12:
        raise ValueError("quaternion has zero norm; expected a unit quaternion x y z w")
    if abs(norm - 1.0) <= QUAT_EXACT_TOL:
        return q
    if abs(norm - 1.0) > QUAT_NORM_TOL:
        raise ValueError(
            f"quaternion norm is {norm:.6g}; expected a unit quaternion x y z w "
            f"(norm within {QUAT_NORM_TOL} of 1)"
        )
    x, y, z, w = (c / norm for c in q)
    return (x, y, z, w)


def _unit_interval(v: float) -> float:
    if not 0.0 <= v <= 1.0:
        raise ValueError(f"expected a value in [0, 1], got {v}")
    return v


def _positive(v: float) -> float:
    if not v > 0.0:
        raise ValueError(f"expected a positive number, got {v}")
    return v


#: Largest coordinate a task file may hold, metres: anything farther is a unit
#: mistake (millimetres read as metres), and would make the planners' matrices
#: singular.
MAX_COORDINATE_M = 1000.0


def _plausible(v: tuple[float, float, float]) -> tuple[float, float, float]:
    if max(abs(c) for c in v) > MAX_COORDINATE_M:
        raise ValueError(
            f"coordinate {max(v, key=abs):g} m is beyond {MAX_COORDINATE_M:g} m; "
            "expected metres (millimetres read as metres?)"
        )
    return v


#: Position x y z, metres, each within ±MAX_COORDINATE_M.
Vec3 = Annotated[tuple[float, float, float], AfterValidator(_plausible)]
#: Unit quaternion x y z w: zero rejected, near-unit normalised.
Quat = Annotated[tuple[float, float, float, float], AfterValidator(_unit_quat)]
#: A number in [0, 1].
UnitInterval = Annotated[float, AfterValidator(_unit_interval)]
#: A number > 0.
Positive = Annotated[float, AfterValidator(_positive)]

IDENTITY_QUAT: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)
ORIGIN: tuple[float, float, float] = (0.0, 0.0, 0.0)


class Pose(TaskModel):
    """A rigid transform: the pose of a frame B in a frame A (maps B's coordinates into A's).

    Attributes
    ----------
    pos : tuple of 3 floats
        Origin of B in A, metres.
    quat : tuple of 4 floats
        Orientation of B in A, unit quaternion x y z w.
    """

    pos: Vec3 = ORIGIN
    quat: Quat = IDENTITY_QUAT

    @property
    def is_identity(self) -> bool:
        """True for the exact identity transform."""
        return self.pos == ORIGIN and self.quat == IDENTITY_QUAT

    def matrix(self) -> FloatArray:
        """Homogeneous transform, shape (4, 4), mapping B coordinates into A."""
        return matrix_from_pose(self.pos, self.quat)
