"""Synthetic sweeps of constraint fits: accuracy by condition, axis errors, calibration.

One :class:`Condition` is a way of drawing tracks (noise level, samples, outliers,
slowly varying error, opening angle); :func:`run_sweep` fits every joint type,
oriented and position-only, under each condition and returns one :class:`Trial`
per track with the truth, the fit and its motion-to-noise ratio.
:func:`reliability` bins the confidences, :func:`fit_calibration` finds the
temperature, floor and passed-over weight that make them calibrated (the three
numbers :data:`~thirdhand.constraints.select.CONFIDENCE_TEMPERATURE`,
:data:`~thirdhand.constraints.select.CONFIDENCE_FLOOR` and
:data:`~thirdhand.constraints.select.PASSED_OVER_WEIGHT` hold).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from thirdhand.arrays import FloatArray
from thirdhand.constraints.robust import fit_model
from thirdhand.constraints.select import (
    CONFIDENCE_FLOOR,
    CONFIDENCE_TEMPERATURE,
    PASSED_OVER_WEIGHT,
    fit_constraint,
    passed_over_types,
    type_probabilities,
)
from thirdhand.constraints.types import NoiseModel
from thirdhand.datasets.joint_tracks import JointTrack, random_joint_track

#: Joint types and whether the track carries orientations. Cylindrical needs them.
CASES: tuple[tuple[str, bool], ...] = (
    ("fixed", True),
    ("prismatic", True),
    ("revolute", True),
    ("cylindrical", True),
    ("free", True),
    ("fixed", False),
    ("prismatic", False),
    ("revolute", False),
    ("free", False),
)
#: Rotation noise per metre of position noise: 1 mm goes with 0.5°.
ROT_PER_POS = math.radians(0.5) / 1e-3


@dataclass(frozen=True)
class Condition:
    """How tracks are drawn.

    Attributes
    ----------
    name : str
    pos_noise : float
        White position noise per axis, metres (rotation: ``ROT_PER_POS`` times it).
    n : int
        Samples per track.
    outliers : float
        Fraction of gross outliers.
    drift : float
        Error varying slowly with time, per axis, in units of the white noise.
    bias : float
        Error varying smoothly with the pose (a camera's distortion), per axis,
        in units of the white noise.
    colour : float
        Noise correlated over about 2 samples, per axis, in units of the white noise.
    span : float or None
        Opening angle of the turning joints, radians (default 40-150°).
    rail_bow : float
        A bowed rail or calibration warp, as a fraction of the path's extent
        (:func:`~thirdhand.datasets.joint_tracks.random_joint_track`).
    """

    name: str
    pos_noise: float
    n: int = 200
    outliers: float = 0.0
    drift: float = 0.0
    bias: float = 0.0
    colour: float = 0.0
    span: float | None = None
    rail_bow: float = 0.0

    @property
    def total_noise(self) -> float:
        """Standard deviation per axis of the whole position error, metres."""
        return self.pos_noise * math.sqrt(1.0 + self.drift**2 + self.bias**2 + self.colour**2)


@dataclass(frozen=True)
class Trial:
    """One synthetic track, its truth and the fit."""

    condition: Condition
    kind: str
    oriented: bool
    seed: int
    predicted: str
    confidence: float
    scores: dict[str, float]
    excluded: tuple[str, ...]
    motion_ratio: float
    axis_error: float
    dof_ratio: float = math.inf
    void: tuple[str, ...] = ()

    @property
    def correct(self) -> bool:
        """Whether the predicted type is the true one."""
        return self.predicted == self.kind

    def probability(
        self,
        temperature: float = CONFIDENCE_TEMPERATURE,
        floor: float = CONFIDENCE_FLOOR,
        passed_over_weight: float = PASSED_OVER_WEIGHT,
    ) -> dict[str, float]:
        """The type probabilities at a calibration (the noted joints passed over)."""
        return type_probabilities(
            self.scores,
            passed_over=self.excluded,
            void=self.void,
            temperature=temperature,
            floor=floor,
            passed_over_weight=passed_over_weight,
        )


def _motion_ratio(kind: str, clean_pos: FloatArray, pos_noise: float) -> float:
    """Extent of the noise-free positions over the position error (inf for fixed)."""
    if kind == "fixed":
        return math.inf
    return float(np.ptp(clean_pos, axis=0).max()) / max(pos_noise, 1e-12)


def _bow(clean_pos: FloatArray) -> float:
    """Largest distance of the noise-free positions from the chord of their two ends, metres."""
    a, b = clean_pos[0], clean_pos[-1]
    chord = b - a
    length = float(np.linalg.norm(chord))
    off = clean_pos - a
    if length > 0.0:
        off = off - np.outer(off @ (chord / length), chord / length)
    return float(np.linalg.norm(off, axis=1).max())


def _dof_ratio(
    kind: str, oriented: bool, track: JointTrack, clean: FloatArray, cond: Condition
) -> float:
    """Motion of the degree of freedom that sets the type apart, over its noise.

    The motion the nearest simpler type cannot reproduce. Prismatic: the stroke
    (against fixed); revolute: the path's bow away from its chord (against
    prismatic, in positions), or with orientations the turn over the rotation
    noise if larger; cylindrical: the smaller of its two distinguishing motions,
    the largest distance of its path from the best circle through it (against
    revolute: a slide along the axis that a tilted circle follows is no evidence
    of one) and its turn measured as a revolute joint's (against prismatic: a
    cylindrical joint that turns 10° at 5° of rotation noise is a slide whose turn
    is under 5 noise levels, as a revolute joint's would be); free: the extent;
    fixed: infinite. Noise is the whole error (:attr:`Condition.total_noise`, the
    same for rotations).
    """
    if kind == "fixed":
        return math.inf
    sp = max(cond.total_noise, 1e-12)
    sr = max(ROT_PER_POS * cond.total_noise, 1e-12)
    extent = float(np.ptp(clean, axis=0).max()) / sp
    if kind == "free":
        return extent
    stroke = float(np.ptp(track.ranges[0])) / sp
    if kind == "prismatic":
        return stroke
    turn = _bow(clean) / sp
    if oriented:
        turn = max(turn, float(np.ptp(track.ranges[3])) / sr)
    if kind == "cylindrical":
        exact = NoiseModel(pos_floor=1e-9, pos_ceiling=1.0, max_outliers=0.0)
        circle = fit_model("revolute", clean, None, noise=exact)
        slide = math.sqrt(float(circle.proj.d2_pos.max())) / sp if circle is not None else stroke
        return min(slide, turn)
    return turn


def run_sweep(
    conditions: Iterable[Condition],
    seeds: Sequence[int],
    *,
    cases: Sequence[tuple[str, bool]] = CASES,
) -> Iterator[Trial]:
    """Fit every case under every condition for every seed (default flags).

    Yields
    ------
    Trial
        ``axis_error`` in degrees for a correctly typed joint with an axis, else NaN;
        ``motion_ratio`` the track's extent over the whole position error;
        ``dof_ratio`` the motion of the type's distinguishing degree of freedom
        over its noise (:func:`_dof_ratio`).
    """
    for cond in conditions:
        for kind, oriented in cases:
            for seed in seeds:
                key = [seed, round(cond.pos_noise * 1e7), list(cases).index((kind, oriented))]
                rot = ROT_PER_POS * cond.pos_noise
                track = random_joint_track(
                    kind,
                    np.random.default_rng(key),
                    n=cond.n,
                    pos_noise=cond.pos_noise,
                    rot_noise=rot,
                    outliers=cond.outliers,
                    span=cond.span,
                    drift=cond.drift * cond.pos_noise,
                    rot_drift=cond.drift * rot,
                    bias=cond.bias * cond.pos_noise,
                    rot_bias=cond.bias * rot,
                    colour=cond.colour * cond.pos_noise,
                    rot_colour=cond.colour * rot,
                    rail_bow=cond.rail_bow,
                )
                # The same geometry without noise (the noise is drawn after it).
                clean = random_joint_track(
                    kind, np.random.default_rng(key), n=cond.n, span=cond.span
                ).pos
                c = fit_constraint(track.pos, track.quat if oriented else None)
                err = math.nan
                if c.type == kind and c.axis is not None and track.axis is not None:
                    err = math.degrees(math.acos(min(1.0, abs(float(c.axis @ track.axis)))))
                yield Trial(
                    condition=cond,
                    kind=kind,
                    oriented=oriented,
                    seed=seed,
                    predicted=c.type,
                    confidence=c.confidence,
                    scores=dict(c.scores),
                    excluded=passed_over_types(c.notes)[0],
                    motion_ratio=_motion_ratio(kind, clean, cond.total_noise),
                    axis_error=err,
                    dof_ratio=_dof_ratio(kind, oriented, track, clean, cond),
                    void=passed_over_types(c.notes)[1],
                )


def reliability(
    trials: Sequence[Trial],
    *,
    temperature: float = CONFIDENCE_TEMPERATURE,
    floor: float = CONFIDENCE_FLOOR,
    passed_over_weight: float = PASSED_OVER_WEIGHT,
) -> tuple[list[tuple[float, float, float, int]], float]:
    """Reliability table and expected calibration error of the chosen types' confidence.

    Bins: below 0.6, 0.6-0.8, 0.8-0.9, 0.9-0.99, at least 0.99.

    Returns
    -------
    table : list of (bin low, mean confidence, accuracy, count)
    ece : float
        Count-weighted mean of ``|accuracy - confidence|`` over the bins.
    """
    conf = np.array(
        [t.probability(temperature, floor, passed_over_weight)[t.predicted] for t in trials]
    )
    ok = np.array([t.correct for t in trials], dtype=np.float64)
    edges = np.array([0.0, 0.6, 0.8, 0.9, 0.99, 1.01])
    table = []
    ece = 0.0
    for lo, hi in itertools.pairwise(edges):
        m = (conf >= lo) & (conf < hi)
        if not m.any():
            continue
        table.append((float(lo), float(conf[m].mean()), float(ok[m].mean()), int(m.sum())))
        ece += m.sum() * abs(ok[m].mean() - conf[m].mean())
    return table, ece / max(len(trials), 1)


def log_loss(
    trials: Sequence[Trial],
    temperature: float,
    floor: float,
    passed_over_weight: float = PASSED_OVER_WEIGHT,
) -> float:
    """Mean negative log probability of the true type at a calibration (at least 1e-12)."""
    total = 0.0
    for t in trials:
        p = t.probability(temperature, floor, passed_over_weight).get(t.kind, 0.0)
        total -= math.log(max(p, 1e-12))
    return total / max(len(trials), 1)


def fit_calibration(
    trials: Sequence[Trial],
    *,
    temperatures: Sequence[float] | None = None,
    floors: Sequence[float] | None = None,
    passed_over_weights: Sequence[float] | None = None,
) -> tuple[float, float, float]:
    """The temperature (1 to 100), floor (0 to 0.3) and passed-over weight (0 to 1) of
    least :func:`log_loss`, on grids."""
    ts = list(temperatures) if temperatures is not None else list(np.geomspace(1.0, 100.0, 21))
    fs = (
        list(floors)
        if floors is not None
        else [0.0, 0.005, 0.01, 0.02, 0.03, 0.05, 0.1, 0.15, 0.2, 0.3]
    )
    es = (
        list(passed_over_weights)
        if passed_over_weights is not None
        else [0.0, 0.001, 0.01, 0.03, 0.1, 0.3, 1.0]
    )
    grid = [(t, f, e) for t in ts for f in fs for e in es]
    best = min(grid, key=lambda tfe: log_loss(trials, *tfe))
    return float(best[0]), float(best[1]), float(best[2])
