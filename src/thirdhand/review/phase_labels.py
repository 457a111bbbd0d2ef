"""Labelling interaction phases for calibration: active questions and a label file.

The segmentation stage gives, per body pair, the CRF's marginal ``p(y_t = 1)``
on its latent time axis (:class:`~thirdhand.segment.pipeline.PairResult`). A
person labels the pair's interaction intervals — where the hand actively
manipulates the object — starting from what the recording's labels say, or
else from the CRF's decoded intervals, and answering the **most uncertain
intervals first** (:func:`active_questions`): runs of latent steps whose
marginal lies in ``[0.5 - UNCERTAIN_BAND, 0.5 + UNCERTAIN_BAND]``, scored by
their mean closeness to 1/2 (``1 - |2p - 1|``, 1 for a coin flip) times their
length in seconds, so a long coin flip is asked before a short doubt.

The result is a kvg annotation file (``TS a b { lock { from=F to=T } … }``,
frames of the recording) written by :func:`write_phase_labels`, which
``thirdhand segment train --labels`` and ``thirdhand segment calibrate
--labels`` read (:func:`thirdhand.segment.cli.read_label_file`).
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from thirdhand.arrays import FloatArray
from thirdhand.demonstration import Demonstration, InteractionInterval, Labels
from thirdhand.errors import ThirdhandError

Span = tuple[float, float]
Pair = tuple[str, str]

#: Half-width of the marginal band asked about: p in [0.2, 0.8].
UNCERTAIN_BAND = 0.3


class PhaseLabelError(ThirdhandError, ValueError):
    """A phase label that cannot be set: unknown pair, empty or reversed interval."""


@dataclass(frozen=True)
class PhaseQuestion:
    """An interval of one pair the CRF is unsure about.

    Attributes
    ----------
    a, b : str
        The pair (a hand or finger, an object).
    start, end : float
        Seconds, on the latent axis's step edges.
    score : float
        Mean of ``1 - |2p - 1|`` over the interval times its length (s).
    probability : float
        Mean marginal over the interval.
    """

    a: str
    b: str
    start: float
    end: float
    score: float
    probability: float

    def text(self) -> str:
        """The question as asked."""
        return (
            f"Does {self.a} manipulate {self.b} from {self.start:.2f} s to {self.end:.2f} s? "
            f"(the model says {self.probability:.0%})"
        )


def uncertain_runs(
    probability: FloatArray, *, band: float = UNCERTAIN_BAND
) -> list[tuple[int, int]]:
    """Runs ``(first, last_exclusive)`` of steps with ``|p - 1/2| <= band`` (NaN: not asked)."""
    from thirdhand.segment.intervals import runs

    p = np.asarray(probability, dtype=np.float64)
    return runs((np.abs(p - 0.5) <= band).astype(np.int64))  # NaN compares False


def active_questions(
    pairs: Iterable[tuple[str, str, FloatArray]],
    edges: FloatArray,
    *,
    band: float = UNCERTAIN_BAND,
    answered: Mapping[Pair, Iterable[Span]] | None = None,
) -> list[PhaseQuestion]:
    """Questions over every pair's uncertain runs, the most uncertain first.

    Parameters
    ----------
    pairs : iterable of (a, b, probability)
        ``probability`` shape (n_steps,), the CRF marginal on the latent axis.
    edges : ndarray, shape (n_steps + 1,), seconds
    answered : mapping (a, b) -> spans, optional
        Intervals already answered per pair: a question inside one is left out.

    Returns
    -------
    list of PhaseQuestion
        By decreasing score; ties by time.
    """
    done: Mapping[Pair, Iterable[Span]] = answered or {}
    out = []
    for a, b, prob in pairs:
        p = np.asarray(prob, dtype=np.float64)
        spans = list(done.get((a, b), ()))
        for lo, hi in uncertain_runs(p, band=band):
            start, end = float(edges[lo]), float(edges[hi])
            if any(s <= start and end <= e for s, e in spans):
                continue
            closeness = 1.0 - np.abs(2.0 * p[lo:hi] - 1.0)
            out.append(
                PhaseQuestion(
                    a=a,
                    b=b,
                    start=start,
                    end=end,
                    score=float(closeness.mean()) * (end - start),
                    probability=float(p[lo:hi].mean()),
                )
            )
    out.sort(key=lambda q: (-q.score, q.start, q.a, q.b))
    return out


def set_span(spans: Sequence[Span], start: float, end: float, value: bool) -> list[Span]:
    """The intervals ``spans`` with ``[start, end]`` marked interacting (``value``) or not.

    Intervals are closed, in seconds; the result is sorted, and touching or
    overlapping intervals are merged.

    Raises
    ------
    PhaseLabelError
        ``start`` not before ``end``, or a non-finite bound.
    """
    if not (np.isfinite(start) and np.isfinite(end)) or not start < end:
        raise PhaseLabelError(f"interval [{start:g}, {end:g}] s: expected start < end, finite")
    out: list[Span] = []
    for s, e in spans:
        if e < start or s > end:
            out.append((s, e))
            continue
        if not value:  # keep the parts outside [start, end]
            if s < start:
                out.append((s, start))
            if e > end:
                out.append((end, e))
            continue
        start, end = min(s, start), max(e, end)
    if value:
        out.append((start, end))
    out.sort()
    merged: list[Span] = []
    for s, e in out:
        if merged and s <= merged[-1][1]:
            merged[-1] = (merged[-1][0], max(merged[-1][1], e))
        else:
            merged.append((s, e))
    return merged


def snap_to_frames(spans: Sequence[Span], t: FloatArray) -> list[Span]:
    """Each bound moved to the nearest frame time of ``t`` (what a kvg file can hold)."""
    from thirdhand.io.kvg import nearest_frames

    snapped = []
    for s, e in spans:
        i, j = nearest_frames(t, [s, e])
        if j > i:
            snapped.append((float(t[i]), float(t[j])))
    return snapped


def phase_labels(demo: Demonstration, labelled: Mapping[Pair, Sequence[Span]]) -> Labels:
    """The demonstration's labels with the pairs in ``labelled`` replaced.

    The other pairs' intervals, the constraints and the plan are kept; the
    labelled intervals are snapped to frame times.

    Raises
    ------
    PhaseLabelError
        A pair naming a body the recording does not have.
    """
    names = set(demo.body_names)
    for a, b in labelled:
        for n in (a, b):
            if n not in names:
                raise PhaseLabelError(f"pair ({a}, {b}): the recording has no body {n!r}")
    keys = {frozenset(p) for p in labelled}
    kept = [i for i in demo.labels.interactions if frozenset((i.a, i.b)) not in keys]
    new = [
        InteractionInterval(a, b, s, e)
        for (a, b), spans in labelled.items()
        for s, e in snap_to_frames(spans, demo.t)
    ]
    return dataclasses.replace(demo.labels, interactions=tuple(kept + new))


def write_phase_labels(
    path: str | os.PathLike[str],
    demo: Demonstration,
    labelled: Mapping[Pair, Sequence[Span]],
    *,
    force: bool = False,
) -> Path:
    """Write the labels as a kvg annotation file (``thirdhand segment train --labels``).

    Refused when ``path`` exists unless ``force`` (the old file is then kept as
    a numbered backup); written atomically.

    Returns
    -------
    Path
    """
    from thirdhand import fileops
    from thirdhand.io import kvg

    p = fileops.check_output(path, force=force)
    labels = phase_labels(demo, labelled)
    text = kvg.format_annotations(labels, frame_times=demo.t, bodies=demo.bodies, path=p)
    fileops.write_text(p, text)
    return p


class PhaseLabelling:
    """A person's labelling of interaction phases, question by question.

    Parameters
    ----------
    demo : Demonstration
    pairs : sequence of (a, b, probability, intervals)
        Per pair, the CRF marginal (n_steps,) and its decoded intervals (s).
    edges : ndarray, shape (n_steps + 1,), seconds
        The latent axis's step edges.

    Attributes
    ----------
    labelled : dict (a, b) -> list of (start, end)
        The intervals so far: the recording's labels of the pair when it has
        some, else the CRF's decoded intervals; then the person's answers and marks.
    answered : dict (a, b) -> list of (start, end)
        What the person answered or marked (not asked again).
    questions : list of PhaseQuestion
        The most uncertain first; ``index`` is the one asked.
    """

    def __init__(
        self,
        demo: Demonstration,
        pairs: Sequence[tuple[str, str, FloatArray, Sequence[Span]]],
        edges: FloatArray,
    ) -> None:
        from thirdhand.segment.intervals import pair_intervals

        self.demo = demo
        self.edges = np.asarray(edges, dtype=np.float64)
        self.probability = {(a, b): np.asarray(p, dtype=np.float64) for a, b, p, _ in pairs}
        self.labelled: dict[Pair, list[Span]] = {}
        for a, b, _, decoded in pairs:
            truth = pair_intervals(demo.labels, a, b)
            self.labelled[(a, b)] = (
                list(truth) if truth else [(float(s), float(e)) for s, e in decoded]
            )
        self.answered: dict[Pair, list[Span]] = {}
        self.questions = active_questions(
            [(a, b, p) for (a, b), p in self.probability.items()], self.edges
        )
        self.index = 0

    @classmethod
    def from_segmentation(
        cls,
        demo: Demonstration,
        result: Any,
        *,
        kinds: Sequence[str] = ("finger-object", "hand-object"),
    ) -> PhaseLabelling:
        """From a :class:`~thirdhand.segment.pipeline.SegmentationResult` of ``demo``;
        the pairs of ``kinds`` (hands and fingers with objects, what the labels hold)."""
        pairs = [(p.a, p.b, p.probability, p.intervals) for p in result.pairs if p.kind in kinds]
        if not pairs:
            raise PhaseLabelError("the recording has no hand-object pair to label")
        return cls(demo, pairs, result.edges)

    @property
    def pairs(self) -> list[Pair]:
        """The pairs that can be labelled."""
        return list(self.labelled)

    @property
    def question(self) -> PhaseQuestion | None:
        """The question asked now (None: every one answered)."""
        return self.questions[self.index] if self.index < len(self.questions) else None

    def mark(self, pair: Pair, start: float, end: float, value: bool) -> None:
        """Mark ``[start, end]`` s of ``pair`` interacting (``value``) or not.

        Raises
        ------
        PhaseLabelError
            An unknown pair, or a bad interval (:func:`set_span`).
        """
        if pair not in self.labelled:
            raise PhaseLabelError(
                f"no pair {pair[0]} - {pair[1]} to label; the pairs are "
                + ", ".join(f"{a} - {b}" for a, b in self.labelled)
            )
        self.labelled[pair] = set_span(self.labelled[pair], start, end, value)
        self.answered[pair] = set_span(self.answered.get(pair, []), start, end, True)

    def answer(self, yes: bool) -> PhaseQuestion | None:
        """Answer the question asked: its interval is (not) an interaction. The next one."""
        q = self.question
        if q is None:
            raise PhaseLabelError("no question left: every uncertain interval is answered")
        self.mark((q.a, q.b), q.start, q.end, yes)
        self.index += 1
        while self.question is not None and self._answered(self.question):
            self.index += 1
        return self.question

    def _answered(self, q: PhaseQuestion) -> bool:
        return any(s <= q.start and q.end <= e for s, e in self.answered.get((q.a, q.b), []))

    def write(self, path: str | os.PathLike[str], *, force: bool = False) -> Path:
        """Write the labels (every pair's) as a kvg file (:func:`write_phase_labels`)."""
        return write_phase_labels(path, self.demo, self.labelled, force=force)


__all__ = [
    "UNCERTAIN_BAND",
    "PhaseLabelError",
    "PhaseLabelling",
    "PhaseQuestion",
    "active_questions",
    "phase_labels",
    "set_span",
    "snap_to_frames",
    "uncertain_runs",
    "write_phase_labels",
]
