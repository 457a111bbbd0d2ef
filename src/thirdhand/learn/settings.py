"""Settings of ``thirdhand learn`` (``[learn]`` of ``--config``).

The defaults run every stage that needs no robot with the shipped models: the
segmentation CRF, a 4-skill library explaining each constraint's motion, the
relational reward, and plan steps kept by a majority of the recordings.
"""

from __future__ import annotations

from pydantic import Field

from thirdhand.settings import Settings


class LearnSettings(Settings):
    """Which stages ``learn`` runs, and the plan's vote."""

    segment: bool = Field(True, description="Run the interaction segmentation (CRF).")
    primitives: bool = Field(True, description="Fit the motor primitives (DMP + ProMP).")
    reward: bool = Field(True, description="Learn the relational reward (RCSI).")
    skills: int = Field(
        4,
        ge=0,
        le=20,
        description="Skills of the library that explains the constraint motions "
        "(stages.primitives.skill_library; 0: no library).",
    )
    skill_library: str | None = Field(
        None,
        description="A task file from an earlier `learn` (or a library saved by "
        "`primitives library -o` on the channels logspeed, logangular) whose skill library "
        "explains the new motions (stages.primitives.skill_library; default: learn one, "
        "`skills` skills).",
    )
    min_support: float = Field(
        0.5,
        ge=0.0,
        lt=1.0,
        description="A slot becomes a plan step when more than this fraction of the "
        "recordings that show any constraint have it (0.5: a majority; 0: every slot seen once).",
    )
    segment_model: str | None = Field(
        None,
        description="Segmentation model JSON (e.g. from `segment calibrate`) or built-in "
        "name (default: the shipped model).",
    )
