"""Settings of ``thirdhand review`` (``[review]`` of ``--config``)."""

from __future__ import annotations

from pydantic import Field

from thirdhand.settings import Settings


class ReviewSettings(Settings):
    """Where meshes the task file does not find are looked up, and how the scene is drawn."""

    meshes: list[str] = Field(
        default_factory=list,
        description="Folders of part meshes the task file does not find (older task files).",
    )
    light: bool = Field(False, description="No environment map or shadows (for software WebGL).")
