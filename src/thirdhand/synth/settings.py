"""Settings of ``thirdhand synth`` (``[synth]`` of ``--config``)."""

from __future__ import annotations

from pydantic import Field

from thirdhand.settings import Settings

#: Most pointing gestures a synthetic scene opens with.
MAX_POINTING = 50


class SynthSettings(Settings):
    """What the synthetic person does besides assembling."""

    head: bool = Field(False, description="Track the person's head too.")
    pointing: int = Field(
        0,
        ge=0,
        le=MAX_POINTING,
        description="Open with this many pointing gestures (targets in the metadata).",
    )
