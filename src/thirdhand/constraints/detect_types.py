"""Results and options of constraint detection (see :mod:`thirdhand.constraints.detect`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from thirdhand.arrays import FloatArray
from thirdhand.constraints.hmm import HMMParams
from thirdhand.constraints.types import DOF_NAMES, ConstraintFitError, JointFit
from thirdhand.demonstration import Demonstration, FreeDofs

if TYPE_CHECKING:
    from thirdhand.segment.pipeline import SegmentationResult


@dataclass
class ConstraintInstance:
    """A constraint detected in one demonstration.

    Attributes
    ----------
    parent, child : str
        Body names; the pose is the child's in the parent's frame.
    type : str
        ``fixed`` or ``revolute`` (a free spin), see the module notes.
    start : float
        Seconds: when the constraint is established.
    end : float or None
        Seconds: when it is removed; None if it lasts to the end of the recording.
    pos : ndarray, shape (3,)
        Child position in the parent, metres (EM estimate over the constrained steps).
    quat : ndarray, shape (4,)
        Child orientation in the parent, x y z w.
    frame_pos, frame_quat : ndarray, shape (3,) and (4,)
        The constraint frame as a pose in the child frame (identity unless a free
        axis is not one of the child's axes).
    ranges : ndarray, shape (6, 2)
        ``[min, max]`` of tx ty tz (m), rx ry rz (rad) in the constraint frame.
    confidence : float
        Mean posterior of the constrained state over the instance's steps, in [0, 1].
    spin : float
        Total rotation about the dominant axis in the approach window, radians.
    demo : str or None
        Name of the demonstration it comes from.
    symbol : str or None
        Filled by :mod:`thirdhand.plan.symbols`.
    runner_up : JointFit or None
        For a joint chosen among types (a slide, a hinge): the next most probable
        type, fitted in the parent's frame; None otherwise.
    """

    parent: str
    child: str
    type: str
    start: float
    end: float | None
    pos: FloatArray
    quat: FloatArray
    frame_pos: FloatArray = field(default_factory=lambda: np.zeros(3))
    frame_quat: FloatArray = field(default_factory=lambda: np.array([0.0, 0.0, 0.0, 1.0]))
    ranges: FloatArray = field(default_factory=lambda: np.zeros((6, 2)))
    confidence: float = 1.0
    spin: float = 0.0
    demo: str | None = None
    symbol: str | None = None
    runner_up: JointFit | None = None

    @property
    def free_dofs(self) -> FreeDofs:
        """The ranges as the package's free-DOF value (``.free()``: the free DOFs' names)."""
        return FreeDofs.from_array(self.ranges)

    def to_dict(self) -> dict[str, Any]:
        """JSON-able form."""
        return {
            "parent": self.parent,
            "child": self.child,
            "type": self.type,
            "start": self.start,
            "end": self.end,
            "pos": self.pos.tolist(),
            "quat": self.quat.tolist(),
            "frame": {"pos": self.frame_pos.tolist(), "quat": self.frame_quat.tolist()},
            "ranges": {n: r.tolist() for n, r in zip(DOF_NAMES, self.ranges, strict=True)},
            "confidence": self.confidence,
            "spin_deg": math.degrees(self.spin),
            "symbol": self.symbol,
            "runner_up": None if self.runner_up is None else self.runner_up.alternative(),
        }


@dataclass
class DetectionResult:
    """Constraint states of every part pair over time, and the instances found.

    Attributes
    ----------
    times : ndarray, shape (n_steps,), seconds
        Centres of the latent steps.
    pairs : list of (str, str)
        Part pairs ``(a, b)``; the HMM tracks ``b`` in ``a``.
    posterior : ndarray, shape (n_pairs, n_steps)
        ``p(constrained)``.
    instances : list of ConstraintInstance
        Direct constraints, in order of creation.
    root : str or None
        The base of the assembly.
    params : HMMParams
        The EM-learned HMM parameters.
    """

    times: FloatArray
    pairs: list[tuple[str, str]]
    posterior: FloatArray
    instances: list[ConstraintInstance]
    root: str | None
    params: HMMParams

    def pair_posterior(self, a: str, b: str) -> FloatArray:
        """``p(constrained)`` of the unordered pair {a, b}, shape (n_steps,)."""
        for k, (x, y) in enumerate(self.pairs):
            if {x, y} == {a, b}:
                return self.posterior[k]
        raise ConstraintFitError(f"pair ({a!r}, {b!r}) was not tracked")


@dataclass(frozen=True)
class PairTracks:
    """The step-sampled tracks constraint detection works on (one record, not 12 arguments).

    Attributes
    ----------
    times : ndarray, shape (n_steps,)
        Step centres, seconds.
    pairs : list of (str, str)
        The part pairs, in the order of the first axis of ``rel_p`` and ``rel_q``.
    world : dict of str to (ndarray (n_steps, 3), ndarray (n_steps, 4))
        Per part, its step pose in the world frame (metres; x y z w), NaN where unseen.
    rel_p, rel_q : ndarray, shapes (n_pairs, n_steps, 3) and (n_pairs, n_steps, 4)
        Per pair ``(a, b)``, ``b``'s pose in ``a``'s frame, NaN where either is unseen.
    phases : SegmentationResult, optional
        The recording's interaction phases (hands holding parts).
    demo : Demonstration, optional
        The recording itself: a free spin is measured on its samples, not on step
        means (a step of the phases can last longer than a quarter turn).
    edges : ndarray, shape (n_steps + 1,), optional
        The steps' edges, seconds.
    """

    times: FloatArray
    pairs: list[tuple[str, str]]
    world: dict[str, tuple[FloatArray, FloatArray]]
    rel_p: FloatArray
    rel_q: FloatArray
    phases: SegmentationResult | None = None
    demo: Demonstration | None = None
    edges: FloatArray | None = None

    @property
    def step(self) -> float:
        """The step length, seconds (0.1 for a single step)."""
        return float(self.times[1] - self.times[0]) if self.times.size > 1 else 0.1


@dataclass(frozen=True)
class DetectOptions:
    """Settings of :func:`detect_constraints`.

    Attributes
    ----------
    step : float
        Latent step, seconds (ignored when segmentation phases give the steps).
    min_duration : float
        Shortest constrained run kept, seconds (a run reaching the end of the
        recording is always kept).
    same_pose : tuple of (float, float)
        Consecutive constrained runs of a pair whose poses agree within these
        bounds (metres, radians) are one constraint.
    simultaneity : float
        Runs of several pairs starting within this many seconds of each other are
        candidates for one new constraint (the child joins a rigid group of parts:
        every pair with a member starts together).
    near_ratio : float
        Parent choice: among the parts of a group within ``near_ratio`` times the
        nearest part's distance (plus 1 cm) of the child, the one with most direct
        constraints so far (the hub: a chair's back goes onto the seat, not onto
        the leg next to it; a screw onto its board, not onto the box's base).
    co_motion : tuple of (float, float)
        World motion of a part during a run that counts as co-motion, metres and
        radians.
    approach_motion : tuple of (float, float)
        Relative motion in the ``approach_window`` before a run that counts as an
        approach, metres and radians.
    approach_window : float
        Seconds before a run's start searched for relative motion; seconds of
        observation: steps where a part was not tracked do not count.
    contact_distance : float
        Largest distance between the origins of two parts an approach may join, metres.
    approach_radius : float
        Distance of the child from its constrained position within which its
        rotations count towards a free spin, metres.
    full_turn : float
        Rotation about one axis, radians, beyond which that rotation is free over
        ``[−π, π]``.
    n_iter : int
        EM iterations.
    max_poses : int
        Most constraint poses per pair (an assembly repeated after taking it apart
        puts a leg in another slot).
    """

    step: float = 0.1
    min_duration: float = 0.5
    simultaneity: float = 1.0
    same_pose: tuple[float, float] = (0.02, math.radians(10.0))
    near_ratio: float = 1.5
    co_motion: tuple[float, float] = (0.03, math.radians(10.0))
    approach_motion: tuple[float, float] = (0.01, math.radians(5.0))
    approach_window: float = 3.0
    contact_distance: float = 0.5
    approach_radius: float = 0.05
    full_turn: float = math.radians(90.0)
    n_iter: int = 8
    max_poses: int = 3
