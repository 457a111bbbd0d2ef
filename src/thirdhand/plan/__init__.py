"""From detected constraints to the task: keyframes, symbols, the assembly plan.

- :mod:`~thirdhand.plan.keyframes`: a snapshot of every body when a constraint appears.
- :mod:`~thirdhand.plan.symbols`: constraint instances clustered into slot symbols
  ``c1…cK`` across demonstrations (a spin about a free axis is the same slot).
- :mod:`~thirdhand.plan.assembly`: the plan ``action(parent, child, symbol)`` with
  its partial order, the relational trajectory, symbolic execution.
"""

from thirdhand.plan.assembly import AssemblyPlan, PlanAction, plan_from_demos, plan_success
from thirdhand.plan.keyframes import Keyframe, keyframes
from thirdhand.plan.symbols import Symbol, assign_symbols

__all__ = [
    "AssemblyPlan",
    "Keyframe",
    "PlanAction",
    "Symbol",
    "assign_symbols",
    "keyframes",
    "plan_from_demos",
    "plan_success",
]
