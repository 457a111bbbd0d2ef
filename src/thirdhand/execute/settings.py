"""Settings of ``thirdhand execute`` (``[execute]`` of ``--config``).

The defaults are the ones ``research/notes/execution.md`` measures best: goals sampled
inside the free DOFs, the base placed by geometry unless a part reaches no goal
there (then by reach), the regrasp on.
"""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, field_validator

from thirdhand.settings import Settings


class ExecuteSettings(Settings):
    """How the simulated robot searches grasps, goals and paths for each step."""

    free_dofs: bool = Field(
        True, description="Sample goals inside the free DOFs when a goal fails."
    )
    step_time: float = Field(60.0, gt=0.0, le=86400.0, description="Time limit per step, seconds.")
    plan_time: float = Field(
        5.0, gt=0.0, le=86400.0, description="Time limit per planning query, seconds."
    )
    order: Literal["auto", "plan", "parents"] = Field(
        "auto",
        description="What binds the step order: auto (the plan's order when learned from "
        "several demonstrations), plan, or parents (only parents first).",
    )
    max_grasps: int = Field(24, ge=1, le=10_000, description="Grasp candidates tried per step.")
    goals: int = Field(24, ge=1, le=10_000, description="Goal poses tried per step (free DOFs).")
    assembly_at: tuple[float, float] | None = Field(
        None, description="World x y (m) where the assembly is built (default: the robot's)."
    )
    placement: Literal["auto", "geometry", "reach"] = Field(
        "auto",
        description="How the base stands: geometry (lowest, nearest), reach (the arm reaches "
        "the goals best) or auto (geometry unless a part reaches no goal there).",
    )
    start_grasps: int = Field(
        0,
        ge=0,
        le=1000,
        description="Lay a part farther than 0.55 m from the arm only where at least this "
        "many of its grasps are reachable (0: anywhere in the robot's band).",
    )
    regrasp: bool = Field(
        True,
        description="When no grasp reached where a part lies can place it, put it down near "
        "the arm and pick it again.",
    )
    meshes: list[str] = Field(
        default_factory=list,
        description="Folders searched for part meshes the task file does not find.",
    )

    @field_validator("assembly_at")
    @classmethod
    def _within_reach_of_a_room(cls, v: tuple[float, float] | None) -> tuple[float, float] | None:
        if v is not None and not all(math.isfinite(x) and abs(x) <= 10.0 for x in v):
            raise ValueError("expected two finite numbers within ±10 m")
        return v
