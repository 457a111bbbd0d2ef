"""Settings of ``thirdhand primitives fit`` (``[primitives.fit]`` of ``--config``)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from thirdhand.settings import Settings

#: Most basis weights per dimension a DMP or ProMP may have.
MAX_WEIGHTS = 1000


class FitSettings(Settings):
    """The primitives' sizes and how demonstrations are aligned before averaging."""

    weights: int | None = Field(
        None,
        ge=2,
        le=MAX_WEIGHTS,
        description="DMP weights per dimension (default: 15 per second of motion).",
    )
    promp_weights: int = Field(10, ge=2, le=MAX_WEIGHTS, description="ProMP weights per dimension.")
    align: Literal["phase", "dtw"] = Field(
        "phase", description="Alignment before averaging: phase or dtw."
    )
