"""Interaction-phase segmentation: a pair-wise linear-chain CRF over pose-variance features.

The model of the 3rdHand report's annex "Temporal segmentation of pair-wise
interaction phases": per body pair, a binary latent label per latent step
(interacting or not), windowed variances of each body's pose and of their
relative pose as state features, learned by maximum likelihood, decoded by
Viterbi. Hands interact with an object when enough of their fingers do.

Entry point: :func:`segment_demonstration`, with the model shipped in
``thirdhand/data/segment_default.json`` by default. The shipped model runs at 20
latent steps per second with the report's four features over a 0.25 s, a 0.5 s
and a 0.1 s window, the pair's mean distance and its bounding-box contact
distance (see :mod:`thirdhand.segment.design`, :mod:`thirdhand.segment.contact`,
``research/scripts/train_default_segmenter.py`` and ``research/notes/segmentation_results.md``).
``research/segment_diagnose.py`` (in the repository) breaks errors down (boundary shifts, missed
and extra intervals) and audits labels against the kinematics.
"""

from thirdhand.segment.crf import PairCRF
from thirdhand.segment.design import DemoFeatures, FeatureConfig, pair_design
from thirdhand.segment.features import SegmentationError
from thirdhand.segment.logistic import LogisticSegmenter
from thirdhand.segment.model import SegmentModel, default_model, load_model
from thirdhand.segment.pipeline import (
    SegmentationResult,
    default_pairs,
    segment_demonstration,
)

__all__ = [
    "DemoFeatures",
    "FeatureConfig",
    "LogisticSegmenter",
    "PairCRF",
    "SegmentModel",
    "SegmentationError",
    "SegmentationResult",
    "default_model",
    "default_pairs",
    "load_model",
    "pair_design",
    "segment_demonstration",
]
