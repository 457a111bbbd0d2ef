"""The result of a constraint fit and the noise model that scores it."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.demonstration import DOF_NAMES as DOF_NAMES  # defined once, re-exported
from thirdhand.demonstration import FreeDofs
from thirdhand.errors import ThirdhandError

#: Every model :func:`thirdhand.constraints.fit_constraint` can choose from
#: (``screw`` only when asked for).
MODEL_TYPES: tuple[str, ...] = ("fixed", "prismatic", "revolute", "cylindrical", "screw", "free")


class ConstraintFitError(ThirdhandError, ValueError):
    """A track cannot be fitted: too few valid samples, wrong shapes, unknown model."""


@dataclass(frozen=True)
class NoiseModel:
    """Bounds on the sensor noise the constrained models may claim.

    Each constrained model (fixed, prismatic, revolute, cylindrical) estimates
    an isotropic Gaussian noise level from its residuals, clipped to
    ``[floor, ceiling]``. The floor keeps a noise-free track from scoring an
    infinite likelihood (and is the resolution below which deviations are not
    evidence of motion); the ceiling is what separates a constrained model from
    ``free``, whose spread is its own estimate and at least the ceiling: motion
    larger than the ceiling that no joint explains is free motion.

    Attributes
    ----------
    pos_floor, pos_ceiling : float
        Position noise bounds, metres (defaults 1 mm and 2.5 cm).
    rot_floor, rot_ceiling : float
        Rotation noise bounds, radians (defaults 0.5° and 6°).
    max_outliers : float
        Largest fraction of samples a model may explain as gross outliers.
    """

    pos_floor: float = 1e-3
    pos_ceiling: float = 0.025
    rot_floor: float = math.radians(0.5)
    rot_ceiling: float = math.radians(6.0)
    max_outliers: float = 0.25

    @classmethod
    def camera(cls) -> NoiseModel:
        """Bounds for camera-based tracking (fiducials, checkerboards, AR tags).

        A 1 cm position floor, the default ``sigma_position`` of Sturm et al.'s
        articulation toolkit: such trackers have slowly varying errors of several
        millimetres that a 1 mm floor would read as a curved or extra joint axis.
        """
        return cls(
            pos_floor=0.01,
            pos_ceiling=0.05,
            rot_floor=math.radians(2.0),
            rot_ceiling=math.radians(10.0),
        )

    def __post_init__(self) -> None:
        if not 0.0 < self.pos_floor <= self.pos_ceiling:
            raise ConstraintFitError(
                f"noise model: expected 0 < pos_floor <= pos_ceiling, got "
                f"{self.pos_floor} and {self.pos_ceiling}"
            )
        if not 0.0 < self.rot_floor <= self.rot_ceiling:
            raise ConstraintFitError(
                f"noise model: expected 0 < rot_floor <= rot_ceiling, got "
                f"{self.rot_floor} and {self.rot_ceiling}"
            )
        if not 0.0 <= self.max_outliers < 1.0:
            raise ConstraintFitError(
                f"noise model: expected 0 <= max_outliers < 1, got {self.max_outliers}"
            )


def _floats(a: FloatArray | None) -> list[Any] | None:
    return None if a is None else np.asarray(a, dtype=np.float64).tolist()


@dataclass(frozen=True, eq=False)
class JointFit:
    """A joint model fitted to the relative-pose track of a child in its parent.

    The kinematics of one constraint as a track shows them (axis, radius, pitch,
    residuals, confidence). The package's one constraint record is
    :class:`thirdhand.task.Constraint`; like it, a fit gives its free DOFs as a
    :class:`~thirdhand.demonstration.FreeDofs` (:attr:`free_dofs`).

    Attributes
    ----------
    type : str
        One of :data:`MODEL_TYPES`.
    frame_pos : ndarray, shape (3,)
        Origin of the constraint frame, metres, parent frame. For a joint, the point
        of the axis nearest the child's final position; otherwise the final position.
    frame_quat : ndarray, shape (4,)
        Orientation of the constraint frame in the parent, x y z w. Its x axis is the
        joint axis (so a revolute joint is free in ``rx``, a prismatic one in ``tx``);
        for a revolute or cylindrical joint its y axis points from the axis to the
        child; for fixed, free and prismatic joints it is the child's final
        orientation, turned (for prismatic) so that x lies on the axis.
    axis : ndarray, shape (3,) or None
        Unit joint axis, parent frame; oriented so that the track moves from its
        start to its end in the positive direction. None for fixed and free.
    origin : ndarray, shape (3,)
        A point of the axis, metres, parent frame (``frame_pos``).
    pos : ndarray, shape (3,)
        The child's position in the parent at the end of the track (the
        constrained pose, as predicted by the model), metres.
    quat : ndarray, shape (4,) or None
        The child's orientation in the parent at the end of the track, x y z w;
        None for a position-only track.
    ranges : ndarray, shape (6, 2)
        Observed ``[min, max]`` of tx ty tz (m) and rx ry rz (rad) in the constraint
        frame, relative to the final pose; ``[0, 0]`` is a locked DOF. Position-only
        tracks say nothing of rotations: their rotation rows are locked except a
        revolute joint's ``rx``.
    radius : float or None
        Distance of the child from a revolute, cylindrical or screw axis, metres.
    pitch : float or None
        Of a screw: translation along ``axis`` per radian turned about it, metres.
    rms_pos : float
        Root-mean-square position residual of the inliers, metres.
    rms_rot : float or None
        Root-mean-square rotation residual of the inliers, radians.
    sigma_pos, sigma_rot : float
        Noise levels of the model's likelihood, metres and radians (``sigma_rot``
        is NaN for a position-only track).
    outlier_fraction : float
        Fraction of samples the model explains as gross outliers.
    n_samples : int
        Valid samples used.
    log_likelihood : float
        Of the chosen model, nats.
    confidence : float
        Probability of the chosen type among those compared
        (:func:`thirdhand.constraints.select.type_probabilities`): the BIC scores'
        weights ``exp(-ΔBIC / (2 T))`` at the temperature ``T`` of
        :data:`~thirdhand.constraints.select.CONFIDENCE_TEMPERATURE`, mixed with a
        uniform share :data:`~thirdhand.constraints.select.CONFIDENCE_FLOOR`, both
        calibrated on synthetic tracks (see ``research/notes/constraints.md``). In [0, 1].
    scores : dict of str to float
        BIC of every model compared (lower is better).
    noise_pos, noise_rot : float
        Estimated white noise of the track, per axis, metres and radians (NaN
        when not estimated, or ``noise_rot`` for a position-only track).
    noise_source : str
        ``"estimated"`` when the noise bounds came from the track, ``"given"``
        when the caller passed a :class:`NoiseModel`.
    notes : tuple of str
        Why a better-scoring model was not chosen (a degenerate joint).
    runner_up : JointFit or None
        The most probable other type, fitted (its ``confidence`` is its
        probability, its own ``runner_up`` None); None when no other model was
        compared. When two types explain a track about equally, both
        probabilities are near one half and this says which and with what axis.
    """

    type: str
    frame_pos: FloatArray
    frame_quat: FloatArray
    axis: FloatArray | None
    origin: FloatArray
    pos: FloatArray
    quat: FloatArray | None
    ranges: FloatArray
    radius: float | None
    pitch: float | None
    rms_pos: float
    rms_rot: float | None
    sigma_pos: float
    sigma_rot: float
    outlier_fraction: float
    n_samples: int
    log_likelihood: float
    confidence: float = 1.0
    scores: dict[str, float] = field(default_factory=dict)
    noise_pos: float = math.nan
    noise_rot: float = math.nan
    noise_source: str = "given"
    notes: tuple[str, ...] = ()
    runner_up: JointFit | None = None

    @property
    def free_dofs(self) -> FreeDofs:
        """The ranges as the package's free-DOF value (``.free()``: the free DOFs' names)."""
        return FreeDofs.from_array(self.ranges)

    def frame_in_child(self) -> tuple[FloatArray, FloatArray]:
        """The constraint frame as a pose in the child's frame at the final pose.

        This is the form of ``thirdhand.task`` constraints and of the user-study
        rows, whose DOF ranges are in the child's frame when the frame is the identity.

        Returns
        -------
        pos : ndarray, shape (3,), metres, child frame
        quat : ndarray, shape (4,), x y z w

        Raises
        ------
        ConstraintFitError
            For a position-only fit (no child orientation).
        """
        if self.quat is None:
            raise ConstraintFitError(
                f"{self.type} constraint: the frame in the child needs the child's "
                "orientation; this fit is position-only"
            )
        p_inv, q_inv = se3.pose_invert(self.pos, self.quat)
        p, q = se3.pose_compose(p_inv, q_inv, self.frame_pos, self.frame_quat)
        return p, q

    def to_dict(self) -> dict[str, Any]:
        """A JSON-able dict of every field (arrays as lists, NaN as None)."""

        def num(v: float | None) -> float | None:
            return None if v is None or not math.isfinite(v) else float(v)

        return {
            "type": self.type,
            "frame": {"pos": _floats(self.frame_pos), "quat": _floats(self.frame_quat)},
            "axis": _floats(self.axis),
            "origin": _floats(self.origin),
            "pos": _floats(self.pos),
            "quat": _floats(self.quat),
            "ranges": {n: _floats(r) for n, r in zip(DOF_NAMES, self.ranges, strict=True)},
            "free_dofs": self.free_dofs.free(),
            "radius": num(self.radius),
            "pitch": num(self.pitch),
            "rms_pos": num(self.rms_pos),
            "rms_rot": num(self.rms_rot),
            "sigma_pos": num(self.sigma_pos),
            "sigma_rot": num(self.sigma_rot),
            "outlier_fraction": num(self.outlier_fraction),
            "n_samples": self.n_samples,
            "log_likelihood": num(self.log_likelihood),
            "confidence": num(self.confidence),
            "scores": {k: num(v) for k, v in self.scores.items()},
            "noise": {
                "source": self.noise_source,
                "sigma_pos": num(self.noise_pos),
                "sigma_rot": num(self.noise_rot),
            },
            "notes": list(self.notes),
            "runner_up": None if self.runner_up is None else self.runner_up.summary(),
        }

    def alternative(self) -> dict[str, Any]:
        """This fit as a task file's ``runner_up`` (:class:`thirdhand.task.constraint.RunnerUp`).

        The axis and origin are in the frame the track was given in (the parent's
        for a relative-pose track); ``travel`` is the range along the joint, metres
        for a slide and radians for a hinge.
        """
        dof = {"prismatic": 0, "revolute": 3}.get(self.type)
        travel = 0.0 if dof is None else float(self.ranges[dof, 1] - self.ranges[dof, 0])
        radius = self.radius if self.type == "revolute" else None
        return {
            "type": self.type,
            "probability": min(1.0, max(0.0, float(self.confidence))),
            "axis": None if self.axis is None or self.type == "fixed" else _floats(self.axis),
            "origin": _floats(self.origin) if self.type == "revolute" else None,
            "radius": None if radius is None or not math.isfinite(radius) else float(radius),
            "travel": max(travel, 0.0) if math.isfinite(travel) else 0.0,
        }

    def summary(self) -> dict[str, Any]:
        """The type, its probability and its geometry (a runner-up's JSON form)."""

        def num(v: float | None) -> float | None:
            return None if v is None or not math.isfinite(v) else float(v)

        return {
            "type": self.type,
            "probability": num(self.confidence),
            "axis": _floats(self.axis),
            "origin": _floats(self.origin),
            "radius": num(self.radius),
            "pitch": num(self.pitch),
            "ranges": {n: _floats(r) for n, r in zip(DOF_NAMES, self.ranges, strict=True)},
            "free_dofs": self.free_dofs.free(),
            "rms_pos": num(self.rms_pos),
            "outlier_fraction": num(self.outlier_fraction),
        }
