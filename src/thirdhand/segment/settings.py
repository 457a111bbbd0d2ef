"""Settings of ``segment train``, ``segment evaluate`` and ``segment calibrate``.

Their tables of ``--config`` (``[segment.train]``, ``[segment.evaluate]``,
``[segment.calibrate]``); the defaults are the ones the shipped model was
trained with (``research/notes/segmentation_results.md``).
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from thirdhand.settings import Settings


class TrainSettings(Settings):
    """The CRF's regularisation and its latent time grid."""

    l2: float = Field(1.0, ge=0.0, le=1e6, description="L2 penalty on the weights.")
    latent_rate: float = Field(10.0, gt=0.0, le=1000.0, description="Latent steps per second, Hz.")
    window: int = Field(5, ge=1, le=1000, description="Window length, latent steps.")


class EvaluateSettings(TrainSettings):
    """:class:`TrainSettings` and which hand's pairs train and test."""

    train_hand: Literal["auto", "left", "right"] = Field(
        "auto",
        description="Hand whose pairs train (auto: the left when both are labelled, "
        "else the labelled one).",
    )
    test_hand: Literal["auto", "left", "right"] = Field(
        "auto", description="Hand whose pairs test with split hand (auto: the other one)."
    )


class CalibrateSettings(Settings):
    """How far a calibration may move the model from where it was trained."""

    prior: float = Field(
        1.0, gt=0.0, le=1e6, description="Weight of the prior that keeps the fit near the model."
    )
    keep_scale: bool = Field(False, description="Refit the score offset only, not its scale.")
    keep_transitions: bool = Field(False, description="Keep the trained transition weights.")
