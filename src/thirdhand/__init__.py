"""thirdhand: teach a robot an assembly task from human demonstrations."""

from thirdhand.demonstration import (
    BodyInfo,
    ConstraintEvent,
    Demonstration,
    InteractionInterval,
    Labels,
    PlanStep,
)
from thirdhand.errors import DemonstrationError, FormatError, TaskFileError, ThirdhandError

__version__ = "0.1.0"

__all__ = [
    "BodyInfo",
    "ConstraintEvent",
    "Demonstration",
    "DemonstrationError",
    "FormatError",
    "InteractionInterval",
    "Labels",
    "PlanStep",
    "TaskFileError",
    "ThirdhandError",
    "__version__",
]
