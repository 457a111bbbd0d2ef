"""Settings of ``thirdhand constraints fit`` (``[constraints.fit]`` of ``--config``)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, field_validator

from thirdhand.constraints.select import DEFAULT_MODELS
from thirdhand.constraints.types import MODEL_TYPES
from thirdhand.settings import Settings


class FitSettings(Settings):
    """The noise model and the candidate joint models of a fit.

    The default, the noise estimated from the track, is right on more real tracks
    than either floor (``research/notes/constraints.md``).
    """

    noise: Literal["auto", "mocap", "camera"] = Field(
        "auto",
        description="Noise: auto (estimated from the track), mocap (1 mm floor), camera "
        "(1 cm floor).",
    )
    models: list[str] = Field(
        default_factory=lambda: list(DEFAULT_MODELS), description="Candidate joint models."
    )

    @field_validator("models")
    @classmethod
    def _known(cls, v: list[str]) -> list[str]:
        bad = [m for m in v if m not in MODEL_TYPES]
        if bad or not v:
            raise ValueError(
                f"unknown model(s) {', '.join(map(repr, bad)) or '(none)'}; choose among "
                + ", ".join(MODEL_TYPES)
            )
        return v
