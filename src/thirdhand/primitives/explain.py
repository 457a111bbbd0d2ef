"""Constraint motions explained by library skills: a leg insertion as transport, insert, turns.

The primitives stage learns one pose DMP per constraint. This module adds the
level below: one skill library (:class:`~thirdhand.primitives.skill_library.SkillLibrary`,
the product parser, a hidden semi-Markov model) learned over the motions of
*all* the task's constraints at once — the child's pose in the parent's frame,
from :func:`~thirdhand.primitives.segments.constraint_segments` — so that a
skill found in one motion (a screwing turn) is the same skill in every other;
every motion is then parsed into runs of skills with their time spans.

Channels (:data:`CHANNELS`): how fast the child moves and turns relative to its
parent (``logspeed``, ``logangular`` of :mod:`~thirdhand.primitives.pose_channels`),
both unchanged by where the task happened and by how the parent stood. Height
and vertical speed are left out: the parent's frame has no "up". No entry and
exit skills: a constraint motion ends when the constraint forms, so its last
run is the work itself (the last screwing turn), the same skill as the turns
before it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from thirdhand.primitives.checks import PrimitiveError
from thirdhand.primitives.pose_channels import LOG_UNIT, MIN_SAMPLES, UNITS, PoseTrack
from thirdhand.primitives.segments import ConstraintSegment
from thirdhand.primitives.skill_library import (
    MAX_SKILLS,
    SkillLibrary,
    SkillParserOptions,
    TrackParse,
)

#: Channels of a constraint motion: the child's speed and angular rate in the parent frame.
CHANNELS = ("logspeed", "logangular")
#: Grid rate of the channels, Hz.
RATE_HZ = 20.0

METHOD = (
    "skill library (hidden semi-Markov model over the child's speed and angular rate in "
    "the parent frame) learned over every constraint motion of the task; a run of one "
    "skill is one step"
)


def motion_options(n_skills: int | None = 4, *, seed: int = 0) -> SkillParserOptions:
    """The parser's settings for constraint motions (see the module docstring).

    Parameters
    ----------
    n_skills : int or None
        ``K``; None: chosen by BIC.
    seed : int
    """
    return SkillParserOptions(
        n_skills=n_skills, ends=False, channels=CHANNELS, rate_hz=RATE_HZ, seed=seed
    )


def _parseable(segment: ConstraintSegment) -> str:
    """Why a motion cannot be parsed, or ``""``."""
    if segment.t.size < MIN_SAMPLES or segment.duration * RATE_HZ + 1 < MIN_SAMPLES:
        return (
            f"{segment.duration:.2f} s, {segment.t.size} samples: shorter than "
            f"{MIN_SAMPLES} samples at {RATE_HZ:g} Hz"
        )
    return ""


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
    library : SkillLibrary
    explanations : list of MotionExplanation
        One per segment, in the order given.
    parses : list of TrackParse or None
        Per segment, the parse the explanation came from (None where not parsed).
    """

    library: SkillLibrary
    explanations: list[MotionExplanation]
    parses: list[TrackParse | None]

    def summary(self) -> list[dict[str, Any]]:
        """Per skill, what it does: its typical speed and angular rate, its share, its steps."""
        lib = self.library
        means = lib.model_.means_
        col = {c: i for i, c in enumerate(lib.channels_)}
        share = lib.skill_fractions([p for p in self.parses if p is not None])
        out = []
        for k in range(lib.n_skills_):
            spans = [s.end - s.start for e in self.explanations for s in e.steps if s.skill == k]
            # the channel's mean back in SI: the level at the skill's mean log magnitude
            out.append(
                {
                    "id": k,
                    "typical_speed_m_s": float(
                        UNITS["speed"] * np.expm1(means[k, col["logspeed"]] * LOG_UNIT)
                    ),
                    "typical_angular_speed_rad_s": float(
                        UNITS["angular"] * np.expm1(means[k, col["logangular"]] * LOG_UNIT)
                    ),
                    "share": float(share[k]),
                    "n_steps": len(spans),
                    "mean_step_s": float(np.mean(spans)) if spans else 0.0,
                }
            )
        return out

    def library_block(self) -> dict[str, Any]:
        """The ``stages.primitives.skill_library`` block: the saved library, and what it means.

        ``SkillLibrary.from_dict`` reads the block back (the extra keys are ignored).
        """
        doc = self.library.to_dict()
        for key in ("log_trans", "log_init", "log_final"):  # NaN (impossible) as null
            a = np.asarray(doc["skills"][key], dtype=object)
            a[np.isnan(a.astype(np.float64))] = None
            doc["skills"][key] = a.tolist()
        doc["method"] = METHOD
        doc["frame"] = "child pose in the parent part's frame"
        doc["summary"] = self.summary()
        return doc

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
    n_skills: int | None = 4,
    seed: int = 0,
    library: SkillLibrary | None = None,
) -> SkillLibraryResult:
    """Learn a skill library over constraint motions and parse each into skill steps.

    Parameters
    ----------
    segments : sequence of ConstraintSegment
        The motions (child in parent frame) of the task's constraints, all demonstrations.
    n_skills : int or None
        ``K``; None: chosen by BIC over 2…6 (:class:`SkillParserOptions`).
    seed : int
        Seeds the library's restarts.
    library : SkillLibrary, optional
        A library fitted before (on :data:`CHANNELS`): parse with it, learn nothing.

    Returns
    -------
    SkillLibraryResult

    Raises
    ------
    PrimitiveError
        If no segment is given, every motion is too short to parse, ``n_skills``
        is out of range, or ``library`` reads other channels.
    """
    if not segments:
        raise PrimitiveError("skill library: no constraint motion given")
    if n_skills is not None and not 1 <= n_skills <= MAX_SKILLS:
        raise PrimitiveError(f"skill library: 1 to {MAX_SKILLS} skills, got {n_skills}")
    notes = [_parseable(s) for s in segments]
    usable = [i for i, n in enumerate(notes) if not n]
    if not usable:
        raise PrimitiveError(f"skill library: every constraint motion is {notes[0]}")
    tracks = {
        i: PoseTrack(
            segments[i].t,
            segments[i].pos,
            segments[i].quat,
            name=f"{segments[i].source} {segments[i].key}",
        )
        for i in usable
    }
    if library is None:
        library = SkillLibrary(motion_options(n_skills, seed=seed)).fit(list(tracks.values()))
    elif tuple(library.channels_) != CHANNELS:
        raise PrimitiveError(
            f"skill library: reads channels {list(library.channels_)}; constraint motions "
            f"are parsed on {list(CHANNELS)}"
        )
    explained: list[MotionExplanation] = []
    parses: list[TrackParse | None] = []
    for i, seg in enumerate(segments):
        if i not in tracks:
            explained.append(MotionExplanation(seg.key, seg.source, (), notes[i]))
            parses.append(None)
            continue
        p = library.parse(tracks[i])
        bounds = [*p.starts.tolist(), seg.t.size - 1]
        steps = tuple(
            SkillStep(int(k), float(seg.t[bounds[j]]), float(seg.t[bounds[j + 1]]))
            for j, k in enumerate(p.skills.tolist())
        )
        explained.append(MotionExplanation(seg.key, seg.source, steps))
        parses.append(p)
    return SkillLibraryResult(library, explained, parses)
