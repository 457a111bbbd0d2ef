"""Kinematic constraints between two parts, fitted to their relative-pose track.

Models: ``fixed`` (constant relative pose), ``prismatic`` (translation along an
axis), ``revolute`` (rotation about an axis), ``cylindrical`` (both, about one
axis, independent), ``screw`` (both, coupled by a pitch; opt-in) and ``free``;
:func:`fit_constraint` fits them and chooses by BIC, with noise bounds estimated
from the track (:func:`estimate_noise`) unless a :class:`NoiseModel` is given, and
reports the calibrated probability of the chosen type (:func:`type_probabilities`).
"""

from thirdhand.constraints.models import (
    fit_cylindrical,
    fit_fixed,
    fit_free,
    fit_prismatic,
    fit_revolute,
    fit_screw,
    prepare_track,
)
from thirdhand.constraints.noise import NoiseEstimate, estimate_noise
from thirdhand.constraints.select import (
    bic_weights,
    demo_track,
    fit_constraint,
    fit_relative,
    type_probabilities,
)
from thirdhand.constraints.types import (
    DOF_NAMES,
    MODEL_TYPES,
    ConstraintFitError,
    JointFit,
    NoiseModel,
)

__all__ = [
    "DOF_NAMES",
    "MODEL_TYPES",
    "ConstraintFitError",
    "JointFit",
    "NoiseEstimate",
    "NoiseModel",
    "bic_weights",
    "demo_track",
    "estimate_noise",
    "fit_constraint",
    "fit_cylindrical",
    "fit_fixed",
    "fit_free",
    "fit_prismatic",
    "fit_relative",
    "fit_revolute",
    "fit_screw",
    "prepare_track",
    "type_probabilities",
]
