"""thirdhand: teach a robot an assembly task from human demonstrations.

``import thirdhand as th`` gives the core types and one verb per stage
(:mod:`thirdhand.api`); each stage is imported when its verb is called, and the
subpackages (``th.io``, ``th.synth``, ``th.taskfile``…) on first use.
"""

from __future__ import annotations

import importlib
from types import ModuleType

from thirdhand._version import __version__
from thirdhand.api import (
    detect_constraints,
    execute_task,
    fit_primitives,
    learn_reward,
    learn_skills,
    plan_assembly,
    segment_phases,
)
from thirdhand.demonstration import (
    BodyInfo,
    ConstraintEvent,
    Demonstration,
    InteractionInterval,
    Labels,
    PlanStep,
)
from thirdhand.errors import DemonstrationError, FormatError, TaskFileError, ThirdhandError
from thirdhand.learn.results import LearnedTask, RecordingStages
from thirdhand.learn.run import learn_task

#: Subpackages and modules reachable as attributes, imported on first use.
_LAZY_MODULES = frozenset(
    {
        "constraints",
        "execute",
        "io",
        "perception",
        "plan",
        "primitives",
        "relational",
        "review",
        "se3",
        "segment",
        "synth",
        "task",
        "taskfile",
    }
)


def __getattr__(name: str) -> ModuleType:
    if name in _LAZY_MODULES:
        return importlib.import_module(f"thirdhand.{name}")
    raise AttributeError(f"module 'thirdhand' has no attribute {name!r}")


__all__ = [
    "BodyInfo",
    "ConstraintEvent",
    "Demonstration",
    "DemonstrationError",
    "FormatError",
    "InteractionInterval",
    "Labels",
    "LearnedTask",
    "PlanStep",
    "RecordingStages",
    "TaskFileError",
    "ThirdhandError",
    "__version__",
    "detect_constraints",
    "execute_task",
    "fit_primitives",
    "learn_reward",
    "learn_skills",
    "learn_task",
    "plan_assembly",
    "segment_phases",
]
