"""The task file ``thirdhand.task/2``: everything learned about one task, in one JSON document.

::

    from thirdhand.taskfile import TaskFile, load_task, save_task

    task = load_task("chair.task.json")
    task.constraint_by_id("c2").free_dofs.rz
    save_task(task, "chair.task.json")   # atomic; the old file is kept as .bak

The models live in :mod:`thirdhand.task`; this module is their public face.
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
from thirdhand.task.stages import Stages
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
    "Stages",
    "TaskFile",
    "TaskObject",
    "TaskStep",
    "dump_task",
    "infer_constraint_type",
    "load_task",
    "parse_task",
    "save_task",
]
