"""Constraint motions explained by library skills: a leg insertion as transport, insert, screw.

The primitives stage learns one pose DMP per constraint. This module adds the
level below: one primitive library (:class:`~thirdhand.primitives.library.PrimitiveLibrary`)
learned over the motions of *all* the task's constraints at once — the child's
pose in the parent's frame, from :func:`~thirdhand.primitives.segments.constraint_segments`
— so that a skill found in one motion (a screwing turn) is the same skill in
every other; every motion is then parsed into a sequence of skills with their
time spans, consecutive segments of one skill merged into one step (a screwing
phase of several turns is one step).

Channels of a motion, on a regular grid of ``rate`` Hz (gaps in the tracking
interpolated):

- shape: the child's position in the parent frame (:data:`SHAPE_UNITS` ``pos``)
  and its accumulated rotation, the sum of the sample-to-sample rotation
  vectors in the parent frame (a leg turned four times by 100° about its axis
  reads 7 rad along that axis, where a log map would wrap at π);
- levels: speed and angular speed (smoothed over ``window`` samples).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.ndimage import uniform_filter1d

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.primitives._checks import PrimitiveError
from thirdhand.primitives.library import PrimitiveLibrary
from thirdhand.primitives.segments import ConstraintSegment
from thirdhand.primitives.serialize import promp_to_dict

#: Unit of each shape channel (values are divided by it): metres, radians.
SHAPE_UNITS = {"pos": 0.02, "rot": 0.1}
#: Unit of each level channel: m/s, rad/s.
LEVEL_UNITS = {"speed": 0.02, "angular": 0.1}
#: Shortest segment, grid samples (0.2 s at 20 Hz); shorter motions are not parsed.
MIN_SAMPLES = 4

METHOD = (
    "primitive library (mixture of ProMPs over segments, exact DP over candidate cuts) "
    "learned over every constraint motion of the task; consecutive segments of one skill "
    "are one step"
)


@dataclass(frozen=True)
class MotionChannels:
    """A constraint motion on a regular grid, in channel units.

    Attributes
    ----------
    t : ndarray, shape (n,)
        Seconds on the demonstration's clock.
    shape : ndarray, shape (n, 6)
        Position (``/ SHAPE_UNITS["pos"]``), then accumulated rotation
        (``/ SHAPE_UNITS["rot"]``), parent frame.
    levels : ndarray, shape (n, 2)
        Speed (``/ LEVEL_UNITS["speed"]``) and angular speed (``/ LEVEL_UNITS["angular"]``).
    """

    t: FloatArray
    shape: FloatArray
    levels: FloatArray


def accumulated_rotation(quat: FloatArray) -> FloatArray:
    """Sum of the sample-to-sample rotation vectors, shape (n, 3), radians, the quaternions' frame.

    Parameters
    ----------
    quat : ndarray, shape (n, 4), x y z w
        Orientation of a body in some frame (sign-continuous or not).
    """
    q = np.asarray(quat, dtype=np.float64)
    step = se3.quat_to_rotvec(se3.quat_multiply(q[1:], se3.quat_conjugate(q[:-1])))
    return np.vstack([np.zeros((1, 3)), np.cumsum(step, axis=0)])


def motion_channels(
    segment: ConstraintSegment, *, rate: float = 20.0, window: int = 3
) -> MotionChannels:
    """The channels of one constraint motion (see the module docstring).

    Parameters
    ----------
    segment : ConstraintSegment
    rate : float
        Grid rate, Hz.
    window : int
        Smoothing of the level channels, grid samples.
    """
    t0, t1 = float(segment.t[0]), float(segment.t[-1])
    n = max(int(np.floor((t1 - t0) * rate)) + 1, 2)
    t = np.linspace(t0, t0 + (n - 1) / rate, n)
    # average over one grid step first: tracker noise resampled as it is would
    # read as speed at the grid's rate
    per_step = (
        max(round(1.0 / (rate * float(np.median(np.diff(segment.t))))), 1) | 1
    )  # odd: centred
    raw = np.hstack([segment.pos, accumulated_rotation(segment.quat)])
    raw = uniform_filter1d(raw, size=per_step, axis=0, mode="nearest")
    pos = np.stack([np.interp(t, segment.t, c) for c in raw[:, :3].T], axis=1)
    rot = np.stack([np.interp(t, segment.t, c) for c in raw[:, 3:].T], axis=1)
    dt = 1.0 / rate
    speed = np.linalg.norm(np.gradient(pos, dt, axis=0), axis=1)
    angular = np.linalg.norm(np.gradient(rot, dt, axis=0), axis=1)
    lev = np.stack([speed / LEVEL_UNITS["speed"], angular / LEVEL_UNITS["angular"]], axis=1)
    lev = uniform_filter1d(lev, size=max(window, 1), axis=0, mode="nearest")
    shape = np.hstack([pos / SHAPE_UNITS["pos"], rot / SHAPE_UNITS["rot"]])
    return MotionChannels(t, shape, np.asarray(lev, dtype=np.float64))


@dataclass(frozen=True)
class SkillStep:
    """One step of an explained motion: a skill applied from ``start`` to ``end`` (seconds)."""

    skill: int
    start: float
    end: float


@dataclass(frozen=True)
class MotionExplanation:
    """A constraint motion as a sequence of skills.

    Attributes
    ----------
    key : str
        The constraint's symbol.
    source : str
        The demonstration it came from.
    steps : tuple of SkillStep
        In time order, consecutive steps of different skills (empty when the
        motion was too short to parse; ``note`` says why).
    note : str
    """

    key: str
    source: str
    steps: tuple[SkillStep, ...]
    note: str = ""

    @property
    def skills(self) -> tuple[int, ...]:
        """The skill sequence."""
        return tuple(s.skill for s in self.steps)


@dataclass(frozen=True)
class SkillLibraryResult:
    """The library learned over a task's constraint motions and every motion's parse.

    Attributes
    ----------
    library : PrimitiveLibrary
    explanations : list of MotionExplanation
        One per segment, in the order given.
    rate : float
        Grid rate of the channels, Hz.
    """

    library: PrimitiveLibrary
    explanations: list[MotionExplanation]
    rate: float

    def skill_dicts(self) -> list[dict[str, Any]]:
        """Each skill's parameters (JSON-able), ids 0…K−1."""
        mix = self.library.mixture_
        lev_mean = mix.level_mean_
        out = []
        for k, promp in enumerate(self.library.skills()):
            spans = [s.end - s.start for e in self.explanations for s in e.steps if s.skill == k]
            out.append(
                {
                    "id": k,
                    "weight": float(mix.weights_[k]),
                    "mean_speed_m_s": float(lev_mean[k, 0] * LEVEL_UNITS["speed"]),
                    "mean_angular_speed_rad_s": float(lev_mean[k, 1] * LEVEL_UNITS["angular"]),
                    "n_steps": len(spans),
                    "mean_step_s": float(np.mean(spans)) if spans else 0.0,
                    "level_mean": [float(v) for v in lev_mean[k]],
                    "level_var": [float(v) for v in mix.level_var_[k]],
                    "promp": promp_to_dict(promp),
                }
            )
        return out

    def library_block(self) -> dict[str, Any]:
        """The ``stages.primitives.skill_library`` block."""
        lib = self.library
        return {
            "method": METHOD,
            "frame": "child pose in the parent part's frame",
            "rate_hz": self.rate,
            "shape_channels": [
                {"name": "pos", "unit": SHAPE_UNITS["pos"], "si": "m", "columns": 3},
                {"name": "rot", "unit": SHAPE_UNITS["rot"], "si": "rad", "columns": 3},
            ],
            "level_channels": [
                {"name": "speed", "unit": LEVEL_UNITS["speed"], "si": "m/s", "columns": 1},
                {
                    "name": "angular_speed",
                    "unit": LEVEL_UNITS["angular"],
                    "si": "rad/s",
                    "columns": 1,
                },
            ],
            "promp_segment": "time scaled to [0, 1], translated to start at 0, turned about z",
            "n_skills": lib.n_skills,
            "switch_penalty": lib.switch_penalty,
            "log_likelihood": float(lib.log_likelihood_),
            "skills": self.skill_dicts(),
        }

    def steps_by_key(self) -> dict[str, list[dict[str, Any]]]:
        """Per constraint symbol, its explained examples (JSON-able, one per demonstration)."""
        out: dict[str, list[dict[str, Any]]] = {}
        for e in self.explanations:
            ex: dict[str, Any] = {
                "source": e.source,
                "steps": [{"skill": s.skill, "start": s.start, "end": s.end} for s in e.steps],
            }
            if e.note:
                ex["note"] = e.note
            out.setdefault(e.key, []).append(ex)
        return out


def explain_constraint_motions(
    segments: Sequence[ConstraintSegment],
    *,
    n_skills: int = 3,
    rate: float = 20.0,
    grid: float | None = 0.25,
    switch_penalty: float = 0.0,
    n_init: int = 2,
    seed: int = 0,
) -> SkillLibraryResult:
    """Learn a skill library over constraint motions and parse each into skill steps.

    Parameters
    ----------
    segments : sequence of ConstraintSegment
        The motions (child in parent frame) of the task's constraints, all demonstrations.
    n_skills : int
        ``K``; lowered to the number of possible segments when there are fewer.
    rate : float
        Grid of the channels, Hz.
    grid : float or None
        Extra candidate cuts every ``grid`` seconds (beside the speed minima).
    switch_penalty : float
        Cost of a change of skill in the parse, nats.
    n_init : int
        Restarts of the library's EM.
    seed : int

    Returns
    -------
    SkillLibraryResult

    Raises
    ------
    PrimitiveError
        If no segment is given or a motion is shorter than one speed window.
    """
    if not segments:
        raise PrimitiveError("skill library: no constraint motion given")
    if n_skills < 1:
        raise PrimitiveError(f"skill library: at least 1 skill, got {n_skills}")
    chans = [motion_channels(s, rate=rate) for s in segments]
    usable = [i for i, c in enumerate(chans) if c.t.size >= MIN_SAMPLES]
    if not usable:
        raise PrimitiveError(
            f"skill library: every constraint motion is shorter than {MIN_SAMPLES} samples "
            f"at {rate:g} Hz"
        )
    tracks = [(chans[i].t, chans[i].shape, chans[i].levels) for i in usable]
    peaks = [
        float(np.linalg.norm(np.gradient(y, 1.0 / rate, axis=0), axis=1).max())
        for _, y, _ in tracks
    ]

    def library(k: int) -> PrimitiveLibrary:
        return PrimitiveLibrary(
            k,
            # candidate cuts where a motion is nearly still, relative to how fast they go
            threshold=0.05 * float(np.median(peaks)),
            window=3,
            min_length=MIN_SAMPLES,
            grid=grid,
            switch_penalty=switch_penalty,
            n_init=n_init,
            seed=seed,
        )

    lib = library(n_skills)
    n_possible = lib.n_possible_segments(tracks)
    if n_possible < n_skills:
        lib = library(n_possible)
    lib.fit(tracks)
    explained = []
    for i, (seg, c) in enumerate(zip(segments, chans, strict=True)):
        if i not in usable:
            note = f"{seg.duration:.2f} s: shorter than one segment of {MIN_SAMPLES} samples"
            explained.append(MotionExplanation(seg.key, seg.source, (), note))
            continue
        parse = lib.parse(c.t, c.shape, levels=c.levels, name=f"{seg.source} {seg.key}").merged()
        b = parse.bounds
        steps = tuple(
            SkillStep(int(k), float(c.t[b[j]]), float(c.t[b[j + 1]]))
            for j, k in enumerate(parse.labels)
        )
        explained.append(MotionExplanation(seg.key, seg.source, steps))
    return SkillLibraryResult(lib, explained, rate)
