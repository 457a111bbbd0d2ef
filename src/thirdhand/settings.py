"""The base of the commands' settings records (:mod:`thirdhand.config` reads them).

Kept apart from :mod:`thirdhand.config` so that the command line imports pydantic
only when a command that has settings runs, not to print its help.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict


class Settings(BaseModel):
    """Base of the commands' settings records: unknown keys are errors, values immutable."""

    model_config = ConfigDict(extra="forbid", frozen=True)
