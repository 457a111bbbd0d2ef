"""Synthetic sweeps of constraint fits: accuracy by condition, axis errors, calibration.

One :class:`Condition` is a way of drawing tracks (noise level, samples, outliers,
slowly varying error, opening angle); :func:`run_sweep` fits every joint type,
oriented and position-only, under each condition and returns one :class:`Trial`
per track with the truth, the fit and its motion-to-noise ratio.
:func:`reliability` bins the confidences, :func:`fit_temperature` finds the
temperature that makes them calibrated (the one scalar
:data:`~thirdhand.constraints.select.CONFIDENCE_TEMPERATURE` holds).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from thirdhand.constraints.select import CONFIDENCE_TEMPERATURE, bic_weights, fit_constraint
from thirdhand.constraints.synthetic import random_joint_track

FloatArray = NDArray[np.float64]

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
        Slowly varying error per axis, in units of the white noise.
    span : float or None
        Opening angle of the turning joints, radians (default 40-150°).
    """

    name: str
    pos_noise: float
    n: int = 200
    outliers: float = 0.0
    drift: float = 0.0
    span: float | None = None


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

    @property
    def correct(self) -> bool:
        """Whether the predicted type is the true one."""
        return self.predicted == self.kind

    def probability(self, temperature: float) -> dict[str, float]:
        """The type probabilities at ``temperature`` (degenerate joints excluded)."""
        allowed = {k: (math.inf if k in self.excluded else v) for k, v in self.scores.items()}
        return bic_weights(allowed, temperature)


def _motion_ratio(kind: str, clean_pos: FloatArray, pos_noise: float) -> float:
    """Extent of the noise-free positions over the white position noise (inf for fixed)."""
    if kind == "fixed":
        return math.inf
    return float(np.ptp(clean_pos, axis=0).max()) / max(pos_noise, 1e-12)


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
        ``motion_ratio`` the track's extent over the white position noise.
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
                    excluded=tuple(note.split()[0] for note in c.notes),
                    motion_ratio=_motion_ratio(kind, clean, cond.pos_noise),
                    axis_error=err,
                )


def reliability(
    trials: Sequence[Trial], *, temperature: float = CONFIDENCE_TEMPERATURE, bins: int = 5
) -> tuple[list[tuple[float, float, float, int]], float]:
    """Reliability table and expected calibration error of the chosen types' confidence.

    Returns
    -------
    table : list of (bin low, mean confidence, accuracy, count)
    ece : float
        Count-weighted mean of ``|accuracy - confidence|`` over the bins.
    """
    conf = np.array([t.probability(temperature)[t.predicted] for t in trials])
    ok = np.array([t.correct for t in trials], dtype=np.float64)
    # Bins of equal width over [0.5, 1] with everything below 0.5 in the first one;
    # the last bin holds the confidences of at least 0.99.
    edges = np.array([0.0, 0.6, 0.8, 0.9, 0.99, 1.01])[: bins + 1]
    table = []
    ece = 0.0
    for lo, hi in itertools.pairwise(edges):
        m = (conf >= lo) & (conf < hi)
        if not m.any():
            continue
        table.append((float(lo), float(conf[m].mean()), float(ok[m].mean()), int(m.sum())))
        ece += m.sum() * abs(ok[m].mean() - conf[m].mean())
    return table, ece / max(len(trials), 1)


def log_loss(trials: Sequence[Trial], temperature: float) -> float:
    """Mean negative log probability of the true type at ``temperature``."""
    total = 0.0
    for t in trials:
        total -= math.log(max(t.probability(temperature).get(t.kind, 0.0), 1e-12))
    return total / max(len(trials), 1)


def fit_temperature(trials: Sequence[Trial], grid: Sequence[float] | None = None) -> float:
    """The temperature of least :func:`log_loss` over a logarithmic grid (1 to 100)."""
    values = list(grid) if grid is not None else list(np.geomspace(1.0, 100.0, 41))
    return float(min(values, key=lambda t: log_loss(trials, t)))
