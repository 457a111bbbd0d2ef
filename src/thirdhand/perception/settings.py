"""Settings of ``headpose``, ``gestures`` and ``attention`` (their tables of ``--config``)."""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, field_validator, model_validator

from thirdhand.settings import Settings


class HeadposeSettings(Settings):
    """Which frames of a video are tracked, and the camera."""

    calibrate: int | None = Field(
        None, ge=0, description="Frame whose pose is zero (default: the first with a face)."
    )
    start: int = Field(0, ge=0, description="First frame.")
    stop: int | None = Field(None, ge=1, description="Stop before this frame (default: the end).")
    step: int = Field(1, ge=1, description="Process every step-th frame.")
    focal: float | None = Field(
        None, gt=0.0, le=1e6, description="Focal length, pixels (default: the frame's width)."
    )
    static: bool = Field(False, description="Detect in each frame alone (no tracking).")

    @model_validator(mode="after")
    def _stop_after_start(self) -> HeadposeSettings:
        if self.stop is not None and self.stop <= self.start:
            raise ValueError(f"stop = {self.stop}: expected a frame after start = {self.start}")
        return self


class GestureSettings(Settings):
    """How a pointing gesture is recognised."""

    ray: Literal["auto", "index", "head"] = Field(
        "auto", description="Pointing ray: auto (head when tracked), index or head."
    )
    dwell: float = Field(0.4, ge=0.0, le=60.0, description="Shortest held posture, seconds.")
    cone: float = Field(
        15.0, gt=0.0, le=90.0, description="Half-angle of the target cone, degrees."
    )


class AttentionSettings(Settings):
    """How the attended object is decided from a tracked head."""

    forward: tuple[float, float, float] = Field(
        (1.0, 0.0, 0.0), description="Viewing axis in the head frame, x y z (not all zero)."
    )
    cone: float = Field(15.0, gt=0.0, le=90.0, description="Half-angle of the cone, degrees.")
    hysteresis: float = Field(3.0, ge=0.0, le=90.0, description="Switching margin, degrees.")
    min_duration: float = Field(0.2, ge=0.0, le=3600.0, description="Shortest interval, seconds.")

    @field_validator("forward")
    @classmethod
    def _axis(cls, v: tuple[float, float, float]) -> tuple[float, float, float]:
        if not all(math.isfinite(x) for x in v) or not any(v):
            raise ValueError("expected three finite numbers, not all zero")
        return v
