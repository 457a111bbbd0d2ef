"""Segment many recordings as independent units: serially, in processes or on Dask.

``thirdhand segment batch INPUT… -o FOLDER`` expands its inputs with
:func:`recordings_in` (a recording stays itself; a folder that is no recording
gives the readable recordings directly inside it), names one output per
recording with :func:`output_names`, and runs :func:`segment_unit` on each
through :func:`thirdhand.batch.parallel_map`. A unit reads its recording and the
model itself (only paths travel to a worker) and returns the phases document and
the scores; the parent writes every file, so a worker never writes.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from thirdhand.errors import FormatError, ThirdhandError

#: Suffix of the phases file written per recording.
PHASES_SUFFIX = ".phases.json"


@dataclass(frozen=True)
class SegmentJob:
    """One unit: a recording and the model to segment it with.

    Attributes
    ----------
    recording : str
        Path of a recording of any readable format (a file or a recording folder).
    model : str or None
        A model JSON or a built-in model name; None for the default model.
    """

    recording: str
    model: str | None = None


@dataclass(frozen=True)
class SegmentOutcome:
    """What one unit returns: the phases document, or why the recording failed.

    Attributes
    ----------
    recording : str
        The unit's recording.
    phases : dict or None
        The ``thirdhand.phases/1`` document (``SegmentationResult.to_dict()``).
    scores : dict
        Frame F1 and interval IoU per pair kind against the recording's own labels
        (empty without labels).
    n_pairs, n_steps : int
        Pairs segmented and latent steps.
    error : str or None
        The one-line error of a recording that could not be read or segmented.
    """

    recording: str
    phases: dict[str, Any] | None
    scores: dict[str, dict[str, float]]
    n_pairs: int = 0
    n_steps: int = 0
    error: str | None = None


def segment_unit(job: SegmentJob) -> SegmentOutcome:
    """Read and segment one recording (the unit of ``segment batch``; runs on any worker).

    A bad recording is an outcome with its error, not an exception, so one
    malformed file among hundreds does not lose the others' results.
    """
    from thirdhand import io, options
    from thirdhand.segment.model import resolve_model
    from thirdhand.segment.pipeline import scores_by_kind, segment_demonstration

    try:
        demo = io.load(job.recording)
        options.body_pairs(len(demo), job.recording)
        result = segment_demonstration(demo, resolve_model(job.model))
    except ThirdhandError as exc:
        return SegmentOutcome(job.recording, None, {}, error=" ".join(str(exc).split()))
    return SegmentOutcome(
        job.recording,
        result.to_dict(),
        scores_by_kind(result),
        n_pairs=len(result.pairs),
        n_steps=len(result.times),
    )


def recordings_in(inputs: Iterable[Path]) -> list[Path]:
    """The recordings named by ``inputs``, in order (a folder's entries sorted by name).

    An input that a reader recognises is a recording (a 3rdHand or ROS 2 folder
    included); any other folder stands for the recordings directly inside it.

    Raises
    ------
    FormatError
        An input does not exist, is neither a recording nor a folder, or is a
        folder with no readable recording in it.
    """
    from thirdhand import io

    found: list[Path] = []
    for p in inputs:
        try:
            io.detect(p)
        except FormatError:
            if not p.is_dir():
                raise
            inside = []
            for entry in sorted(p.iterdir()):
                try:
                    io.detect(entry)
                except FormatError:
                    continue
                inside.append(entry)
            if not inside:
                raise FormatError(p, "the folder holds no readable recording") from None
            found.extend(inside)
        else:
            found.append(p)
    seen: set[Path] = set()
    unique = []
    for p in found:
        key = p.resolve()
        if key not in seen:
            seen.add(key)
            unique.append(p)
    return unique


def output_names(recordings: Sequence[Path]) -> list[str]:
    """One file name per recording: ``<stem>.phases.json``, ``<name>.phases.json`` on a clash.

    Two recordings of the same stem (``a.csv``, ``a.c3d``) keep their extensions;
    two of the same name in different folders are an error.

    Raises
    ------
    ThirdhandError
        Two recordings would get the same output name.
    """
    stems = [p.stem if p.is_file() else p.name for p in recordings]
    names = [
        (p.name if stems.count(s) > 1 else s) + PHASES_SUFFIX
        for p, s in zip(recordings, stems, strict=True)
    ]
    first: dict[str, Path] = {}
    for p, n in zip(recordings, names, strict=True):
        if n in first:
            raise ThirdhandError(
                f"{first[n]} and {p} would both be written as {n}; "
                "segment them into separate --output folders"
            )
        first[n] = p
    return names


__all__ = [
    "PHASES_SUFFIX",
    "SegmentJob",
    "SegmentOutcome",
    "output_names",
    "recordings_in",
    "segment_unit",
]
