"""The skill library users fit and reuse: learn skills from demonstrations, parse new ones.

:class:`SkillLibrary` fits a hidden semi-Markov model
(:class:`~thirdhand.primitives.hsmm.HiddenSemiMarkov`, hard EM without labels) over
the pose channels of :mod:`~thirdhand.primitives.pose_channels` — speed, angular
rate, height above the work, forces when present — on every given track at
once, so a skill means the same in every track, and parses any track into runs
of skills. It is saved as one versioned JSON document (:data:`SCHEMA`) and read
back by :meth:`SkillLibrary.from_dict`, so that a library fitted on earlier
demonstrations parses new ones.

With ``K ≥ 3`` skills, two of them are an *entry* (only a track's first run: the
approach) and an *exit* (only its last: the withdrawal), around ``K − 2`` skills
of the work repeated in any order (``ends``); with ``K = 2`` both alternate
freely. Without ``K``, it is chosen over :attr:`SkillParserOptions.k_range` by
BIC on the training tracks.

The seed's parser (candidate cuts at speed minima + a mixture of ProMP skills,
:class:`~thirdhand.primitives.primitive_library.PrimitiveLibrary`) stays reachable as
``parser="cuts"`` for comparison; it is not saved.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from thirdhand.arrays import FloatArray, IntArray
from thirdhand.errors import ThirdhandError
from thirdhand.primitives.checks import PrimitiveError
from thirdhand.primitives.hsmm import HiddenSemiMarkov, runs
from thirdhand.primitives.pose_channels import CHANNELS, PoseTrack, default_channels, pose_channels
from thirdhand.task.skill_model import MAX_RATE_HZ, MAX_WINDOW, skill_model_problem

if TYPE_CHECKING:
    from thirdhand.task.stages import SkillLibraryRecord

#: Schema of a saved library.
SCHEMA = "thirdhand.skill-library/1"
#: Most skills a library may have.
MAX_SKILLS = 100


@dataclass(frozen=True)
class SkillParserOptions:
    """Settings of the skill parser; the defaults are the best measured
    (research/notes/primitives.md).

    Attributes
    ----------
    parser : {"hsmm", "cuts"}
        ``hsmm``: the product parser; ``cuts``: the seed's candidate cuts + ProMP skills.
    n_skills : int or None
        ``K``, entry and exit included; None: chosen by BIC over ``k_range``.
    k_range : tuple of int
    ends : bool or None
        Entry and exit skills; None: when ``K ≥ 3``.
    channels : tuple of str or None
        Channels (:data:`~thirdhand.primitives.pose_channels.CHANNELS`); None: the
        pose channels of the first track, forces when present
        (:func:`~thirdhand.primitives.pose_channels.default_channels`).
    rate_hz : float
        Rate the tracks are parsed at, Hz.
    window : int
        Smoothing of the channels, samples at ``rate_hz``; each sample's evidence
        is counted ``1 / window`` times against the durations.
    n_init : int
        Restarts of the hard EM (the best training score is kept).
    seed : int
    """

    parser: Literal["hsmm", "cuts"] = "hsmm"
    n_skills: int | None = None
    k_range: tuple[int, ...] = (2, 3, 4, 5, 6)
    ends: bool | None = None
    channels: tuple[str, ...] | None = None
    rate_hz: float = 20.0
    window: int = 8
    n_init: int = 4
    seed: int = 0

    def __post_init__(self) -> None:
        if self.parser not in ("hsmm", "cuts"):
            raise PrimitiveError(f"parser must be hsmm or cuts, got {self.parser!r}")
        for k in (self.n_skills, *self.k_range):
            if k is not None and not 1 <= k <= MAX_SKILLS:
                raise PrimitiveError(f"skills: expected 1 to {MAX_SKILLS}, got {k}")
        if self.channels is not None:
            bad = [c for c in self.channels if c not in CHANNELS]
            if bad or not self.channels:
                raise PrimitiveError(
                    f"channels {list(self.channels)}: expected some of {', '.join(CHANNELS)}"
                )
        if not (np.isfinite(self.rate_hz) and 0 < self.rate_hz <= MAX_RATE_HZ):
            raise PrimitiveError(
                f"rate must be a number of Hz in (0, {MAX_RATE_HZ:g}], got {self.rate_hz}"
            )
        if not (1 <= self.window <= MAX_WINDOW) or self.n_init < 1:
            raise PrimitiveError(
                f"window must be 1 to {MAX_WINDOW} and restarts ≥ 1, got {self.window}, "
                f"{self.n_init}"
            )


@dataclass(frozen=True)
class TrackParse:
    """One track parsed into runs of skills.

    Attributes
    ----------
    labels : ndarray of int, shape (n,)
        Skill of every sample of the track (its own times).
    starts : ndarray of int, shape (r,)
        First sample of each run.
    skills : ndarray of int, shape (r,)
        Skill of each run (consecutive runs differ).
    cuts_s : ndarray, shape (r − 1,)
        Times the runs after the first start, seconds (the track's clock).
    score : float
        ``log p(x, z)`` of the parse.
    """

    labels: IntArray
    starts: IntArray
    skills: IntArray
    cuts_s: FloatArray
    score: float


def _ends_for(k: int, ends: bool | None) -> bool:
    return k >= 3 if ends is None else ends


def _hsmm(k: int, opts: SkillParserOptions) -> HiddenSemiMarkov:
    ends = _ends_for(k, opts.ends)
    if ends and k < 3:
        raise PrimitiveError(f"entry and exit skills need at least 3 skills, got {k}")
    return HiddenSemiMarkov(
        k - 2 if ends else k,
        ends=ends,
        emission_weight=1.0 / opts.window,
        # the entry and exit are one run per track: their covariances need the prior
        cov_prior_runs=1.0,
        seed=opts.seed,
    )


def _n_params(model: HiddenSemiMarkov) -> int:
    s, c = model.means_.shape
    return s * (c + c * (c + 1) // 2 + 2) + int(np.isfinite(model.log_trans_).sum()) - s


class SkillLibrary:
    """Skills learned from unlabelled demonstrations; parses any track into them.

    Parameters
    ----------
    options : SkillParserOptions, optional

    Attributes
    ----------
    model_ : HiddenSemiMarkov
    channels_ : tuple of str
    n_skills_ : int
        ``K``, entry and exit included.
    bic_ : dict of int to float
        When ``K`` was chosen: the BIC of each candidate.
    """

    def __init__(self, options: SkillParserOptions | None = None) -> None:
        self.options = options or SkillParserOptions()
        if self.options.parser != "hsmm":
            raise PrimitiveError("SkillLibrary is the hsmm parser; use fit_skill_parses for cuts")

    def _features(self, tracks: Sequence[PoseTrack]) -> list[tuple[FloatArray, FloatArray]]:
        o = self.options
        return [
            pose_channels(tr, self.channels_, rate_hz=o.rate_hz, window=o.window) for tr in tracks
        ]

    def fit(self, tracks: Sequence[PoseTrack]) -> SkillLibrary:
        """Learn ``K`` skills from the tracks together (no labels).

        Raises
        ------
        PrimitiveError
            No track, tracks lacking a channel, or fewer samples than skills need.
        """
        if not tracks:
            raise PrimitiveError("skill library: no track given")
        o = self.options
        self.channels_ = o.channels or default_channels(tracks[0])
        xs = [x for _, x in self._features(tracks)]
        n = sum(x.shape[0] for x in xs)
        ks = [o.n_skills] if o.n_skills is not None else list(o.k_range)
        # a run of a skill is at least one sample: fewer samples than runs is hopeless
        ks = [k for k in ks if k <= n]
        if not ks:
            raise PrimitiveError(
                f"skill library: {o.n_skills} skills for {n} samples at {o.rate_hz:g} Hz "
                f"in {len(xs)} tracks; give fewer skills or longer tracks"
            )
        best: tuple[float, HiddenSemiMarkov] | None = None
        self.bic_: dict[int, float] = {}
        for k in ks:
            if _ends_for(k, o.ends) and min(x.shape[0] for x in xs) < 3:
                continue
            model = _hsmm(k, o).fit_unsupervised(xs, n_init=o.n_init)
            # BIC in independent samples: each is a mean over ``window`` of them
            b = -2.0 * model.score_ + _n_params(model) * float(np.log(max(n / o.window, 2.0)))
            self.bic_[k] = b
            if best is None or b < best[0]:
                best = (b, model)
        if best is None:
            raise PrimitiveError("skill library: entry and exit skills need tracks of 3 samples")
        self.model_ = best[1]
        self.n_skills_ = int(self.model_.means_.shape[0])
        if o.n_skills is not None:
            self.bic_ = {}
        return self

    def parse(self, track: PoseTrack) -> TrackParse:
        """The most likely runs of skills of a track, at the track's own samples."""
        if not hasattr(self, "model_"):
            raise PrimitiveError("skill library: fit or load a library before parsing")
        ((tg, x),) = self._features([track])
        z, score = self.model_.decode(x)
        # each sample takes the skill of the nearest grid time
        idx = np.clip(
            np.rint((track.t - tg[0]) * self.options.rate_hz).astype(np.int64), 0, tg.size - 1
        )
        labels = z[idx].astype(np.int64)
        starts, _, skills = runs(labels)
        return TrackParse(labels, starts, skills, track.t[starts[1:]].astype(np.float64), score)

    # ------------------------------------------------------------ persistence
    def to_dict(self) -> dict[str, Any]:
        """The fitted library as a JSON-able document (:data:`SCHEMA`)."""
        if not hasattr(self, "model_"):
            raise PrimitiveError("skill library: nothing to save before fitting")
        m, o = self.model_, self.options

        def finite(a: FloatArray) -> Any:
            return [finite(v) for v in a] if a.ndim else (float(a) if np.isfinite(a) else None)

        return {
            "schema": SCHEMA,
            "parser": "hsmm",
            "n_skills": self.n_skills_,
            "ends": bool(m.ends_),
            "channels": list(self.channels_),
            "rate_hz": o.rate_hz,
            "window": o.window,
            "seed": o.seed,
            "skills": {
                "means": m.means_.tolist(),
                "covs": m.covs_.tolist(),
                "duration_log_mean": m.dur_mu_.tolist(),
                "duration_log_sd": m.dur_sd_.tolist(),
                "max_duration": int(m.max_duration_),
                # log-probabilities; null where a move is impossible (−inf)
                "log_trans": finite(m.log_trans_),
                "log_init": finite(m.log_init_),
                "log_final": finite(m.log_final_),
            },
        }

    @classmethod
    def from_dict(cls, doc: Any, *, source: str = "library") -> SkillLibrary:
        """A library from :meth:`to_dict`'s document, validated.

        Raises
        ------
        PrimitiveError
            Another schema or version, or a field missing or of the wrong shape.
        """
        if not isinstance(doc, dict) or "schema" not in doc:
            raise PrimitiveError(f"{source}: not a skill library (no 'schema' field)")
        if doc["schema"] != SCHEMA:
            raise PrimitiveError(
                f"{source}: a document of schema {doc['schema']!r}, not a skill library this "
                f"thirdhand reads ({SCHEMA!r})"
            )
        try:
            channels = tuple(str(c) for c in doc["channels"])
            opts = SkillParserOptions(
                n_skills=int(doc["n_skills"]),
                ends=bool(doc["ends"]),
                channels=channels,
                rate_hz=float(doc["rate_hz"]),
                window=int(doc["window"]),
                seed=int(doc["seed"]),
            )
            sk = doc["skills"]
            s, c = int(doc["n_skills"]), len(channels)

            def arr(key: str, shape: tuple[int, ...]) -> FloatArray:
                a = np.asarray(sk[key], dtype=np.float64)
                if a.shape != shape:
                    raise PrimitiveError(
                        f"{source}: skills.{key} has shape {a.shape}, expected {shape}"
                    )
                return a

            def logp(key: str, shape: tuple[int, ...]) -> FloatArray:
                a = arr(key, shape)
                return np.where(np.isnan(a), -np.inf, a)

            model = HiddenSemiMarkov(
                s - 2 if opts.ends else s, ends=bool(opts.ends), emission_weight=1.0 / opts.window
            )
            model.means_ = arr("means", (s, c))
            model.covs_ = arr("covs", (s, c, c))
            model.dur_mu_ = arr("duration_log_mean", (s,))
            model.dur_sd_ = arr("duration_log_sd", (s,))
            model.max_duration_ = int(sk["max_duration"])
            model.log_trans_ = logp("log_trans", (s, s))
            model.log_init_ = logp("log_init", (s,))
            model.log_final_ = logp("log_final", (s,))
            model.ends_ = bool(opts.ends)
            model.states_ = np.arange(s)
            problem = skill_model_problem(
                channels=channels, rate_hz=opts.rate_hz, window=opts.window,
                means=sk["means"], covs=sk["covs"], duration_log_mean=sk["duration_log_mean"],
                duration_log_sd=sk["duration_log_sd"], max_duration=model.max_duration_,
                # NaN for an impossible move in files of earlier versions: read as null
                log_trans=model.log_trans_, log_init=model.log_init_, log_final=model.log_final_,
            )  # fmt: skip
            if problem is not None:
                raise PrimitiveError(f"{source}: {problem}")
        except (KeyError, TypeError, ValueError, np.linalg.LinAlgError) as exc:
            if isinstance(exc, PrimitiveError):
                raise
            raise PrimitiveError(
                f"{source}: a damaged skill library ({type(exc).__name__}: {exc})"
            ) from None
        lib = cls(opts)
        lib.channels_ = channels
        lib.model_ = model
        lib.n_skills_ = s
        lib.bic_ = {}
        return lib

    def skill_fractions(self, parses: Sequence[TrackParse]) -> list[float]:
        """Share of all parsed samples in each skill, shape (K,)."""
        counts = np.zeros(self.n_skills_)
        for p in parses:
            np.add.at(counts, p.labels, 1.0)
        return (counts / max(counts.sum(), 1.0)).tolist()


def read_skill_library(path: Path) -> SkillLibrary:
    """A saved skill library: the file ``primitives library -o`` writes, or a task's.

    Parameters
    ----------
    path : Path
        A ``thirdhand.skill-library/1`` document, or a task file
        (``thirdhand.task/…``) whose ``stages.primitives.skill_library`` is read.

    Raises
    ------
    ThirdhandError
        No such file, not JSON, a task without a skill library, or a damaged library
        (one line naming the file).
    """
    from thirdhand.readlimits import MAX_DOCUMENT_BYTES, read_json

    doc = read_json(path, what="skill library or task file", limit=MAX_DOCUMENT_BYTES)
    if isinstance(doc, dict) and str(doc.get("schema", "")).startswith("thirdhand.task/"):
        from thirdhand.taskfile import load_task

        prim = load_task(path).stages.primitives
        if prim is None or prim.skill_library is None:
            raise ThirdhandError(
                f"{path}: the task has no stages.primitives.skill_library "
                "(learn it with primitives on and skills > 0)"
            )
        return skill_library_from_record(prim.skill_library)
    return SkillLibrary.from_dict(doc, source=str(path))


def skill_library_from_record(record: SkillLibraryRecord) -> SkillLibrary:
    """The fitted library a task file's ``stages.primitives.skill_library`` saved."""
    doc = record.model_dump(mode="json", by_alias=True)
    return SkillLibrary.from_dict(doc, source="skill_library")


def cuts_parses(
    tracks: Sequence[PoseTrack], options: SkillParserOptions
) -> tuple[Any, list[TrackParse]]:
    """The seed's parser on the tracks' positions: a fitted PrimitiveLibrary and each parse.

    Candidate cuts where the smoothed speed falls under 5 % of the median peak
    speed, ProMP skills over the segments (``K`` = ``n_skills`` or 3).
    """
    from thirdhand.primitives.primitive_library import PrimitiveLibrary
    from thirdhand.primitives.segment_features import smoothed_speed

    data = [(tr.t, tr.pos) for tr in tracks]
    peaks = [smoothed_speed(y, float(np.median(np.diff(t))), 5).max() for t, y in data]
    lib = PrimitiveLibrary(
        options.n_skills or 3, threshold=0.05 * float(np.median(peaks)), seed=options.seed
    ).fit(data)
    out = []
    for t, y in data:
        p = lib.parse(t, y)
        labels = p.frame_labels()[: t.size]
        starts = p.bounds[:-1].astype(np.int64)
        out.append(TrackParse(labels, starts, p.labels, t[p.cuts].astype(np.float64), p.log_prob))
    return lib, out
