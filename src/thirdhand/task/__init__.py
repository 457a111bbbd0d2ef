"""The task file ``thirdhand.task/1``: models, validation, atomic load and save.

The public entry point is :mod:`thirdhand.taskfile`.
"""

from thirdhand.task.constraint import (
    CONSTRAINT_TYPES,
    Constraint,
    ConstraintType,
    infer_constraint_type,
)
from thirdhand.task.geometry import DOF_NAMES, FreeDofs, Pose
from thirdhand.task.model import (
    SCHEMA,
    Correction,
    InputFile,
    Provenance,
    TaskFile,
    TaskObject,
    TaskStep,
)
from thirdhand.task.store import dump_task, load_task, parse_task, save_task

__all__ = [
    "CONSTRAINT_TYPES",
    "DOF_NAMES",
    "SCHEMA",
    "Constraint",
    "ConstraintType",
    "Correction",
    "FreeDofs",
    "InputFile",
    "Pose",
    "Provenance",
    "TaskFile",
    "TaskObject",
    "TaskStep",
    "dump_task",
    "infer_constraint_type",
    "load_task",
    "parse_task",
    "save_task",
]
