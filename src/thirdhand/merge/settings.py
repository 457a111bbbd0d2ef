"""Settings of ``thirdhand merge`` (``[merge]`` of ``--config``)."""

from __future__ import annotations

from pydantic import Field

from thirdhand.settings import Settings


class MergeSettings(Settings):
    """How recordings of one session are aligned and resampled onto one time axis."""

    drift: bool = Field(True, description="Estimate a clock drift rate.")
    smooth: bool = Field(
        False,
        description="Fit the clock last on smoothed tracks (noisy, slow, evenly sampled "
        "trackers; docs/how-to/merge.md).",
    )
    rate: float | None = Field(
        None, gt=0.0, le=100000.0, description="Output rate, Hz (default: the highest)."
    )
    max_gap: float = Field(
        0.1, ge=0.0, le=3600.0, description="Longest interval interpolated across, seconds."
    )
