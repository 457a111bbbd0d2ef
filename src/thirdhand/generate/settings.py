"""Settings of ``thirdhand generate`` (``[generate]`` of ``--config``; physics: ``[simulate]``)."""

from __future__ import annotations

from pydantic import Field

from thirdhand.settings import Settings


class GenerateSettings(Settings):
    """How each simulated episode is sampled into the dataset.

    The physics (grasp mode, friction, timing, tolerances) is the ``[simulate]``
    table's :class:`~thirdhand.simulate.settings.SimulateSettings`; its video
    ``fps``, ``width`` and ``height`` are not used.
    """

    fps: int = Field(
        10,
        ge=1,
        le=100,
        description="Frames per second of the dataset; a whole number of physics steps "
        "(the [simulate] timestep) must make one frame.",
    )
    width: int = Field(224, ge=16, le=1024, description="Camera image width, pixels (even).")
    height: int = Field(224, ge=16, le=1024, description="Camera image height, pixels (even).")
