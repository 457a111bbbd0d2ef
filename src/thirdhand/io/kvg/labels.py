"""Annotation entries to :class:`~thirdhand.demonstration.Labels`: bodies, frames to seconds."""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from thirdhand.demonstration import (
    BodyInfo,
    ConstraintEvent,
    FreeDofs,
    InteractionInterval,
    Labels,
    PlanStep,
)
from thirdhand.errors import FormatError, ThirdhandError
from thirdhand.io.kvg.annotations import Annotation, last_span_end, parse_annotations
from thirdhand.io.kvg.graph import Value


def resolve_body(
    name: str,
    bodies: Sequence[BodyInfo] | None,
    *,
    path: Path,
    line: int | None,
    single: bool = False,
) -> list[str]:
    """Body names a label stands for.

    A label naming a body is that body. A label naming no body but the
    ``hand_body`` of some fingers (``/human/rh`` while only ``/human/rh/thumb``
    ... are tracked) stands for all those fingers, in body order. Without
    ``bodies`` (a label file read alone) every label is kept as written.

    Raises
    ------
    FormatError
        The label names no body of the recording, or names a hand where one body is
        needed (``single``).
    """
    if bodies is None:
        return [name]
    names = [b.name for b in bodies]
    if name in names:
        return [name]
    fingers = [b.name for b in bodies if b.hand_body == name]
    if fingers and not single:
        return fingers
    if fingers:
        raise FormatError(
            path, f"label names hand {name!r} where one body is expected (a constraint)", line=line
        )
    raise FormatError(
        path,
        f"label names body {name!r}, which is not in the recording (bodies: {', '.join(names)})",
        line=line,
    )


def annotations_to_labels(
    entries: Sequence[Annotation],
    to_seconds: Callable[[float, int | None], float],
    *,
    path: Path,
    last: float,
    bodies: Sequence[BodyInfo] | None = None,
) -> Labels:
    """Labels from parsed annotation entries.

    Parameters
    ----------
    entries : sequence of Annotation
    to_seconds : callable (value, line) -> float
        Converts a span bound (frame or seconds) to the demonstration's time axis;
        raises FormatError for a value out of range.
    path : Path
        The label file, for error messages.
    last : float
        The last frame/time of the recording, in the spans' unit: a ``CE`` span ending
        before it yields a removal event.
    bodies : sequence of BodyInfo, optional
        The recording's bodies: names are checked and hand labels expanded to fingers.
    """
    inter: list[InteractionInterval] = []
    cons: list[ConstraintEvent] = []
    plan: list[PlanStep] = []
    for e in entries:
        if e.tag == "TS":
            for a in resolve_body(e.a, bodies, path=path, line=e.line):
                for b in resolve_body(e.b, bodies, path=path, line=e.line):
                    inter.extend(
                        InteractionInterval(a, b, to_seconds(s, e.line), to_seconds(t, e.line))
                        for s, t in e.spans
                    )
            continue
        (parent,) = resolve_body(e.a, bodies, path=path, line=e.line, single=True)
        (child,) = resolve_body(e.b, bodies, path=path, line=e.line, single=True)
        for (s, t), extra in zip(e.spans, e.extras, strict=True):
            if e.tag == "PS":
                sym = extra.get("symbol")
                when = None if math.isnan(s) else to_seconds(s, e.line)
                plan.append(PlanStep(parent, child, None if sym is None else str(sym), when))
                continue
            onset = _constraint(parent, child, to_seconds(s, e.line), extra, path=path, line=e.line)
            cons.append(onset)
            if t < last:
                cons.append(dataclasses.replace(onset, time=to_seconds(t, e.line), removed=True))
    return Labels(interactions=tuple(inter), constraints=tuple(cons), plan=tuple(plan))


def _constraint(
    parent: str, child: str, time: float, extra: dict[str, Value], *, path: Path, line: int | None
) -> ConstraintEvent:
    try:
        dofs = extra.get("free_dofs", (0.0,) * 12)
        if not isinstance(dofs, tuple) or len(dofs) != 12:
            raise ValueError(f"free_dofs needs 12 numbers (6 min/max pairs), got {dofs!r}")
        sym = extra.get("symbol")
        return ConstraintEvent(
            time=time,
            parent=parent,
            child=child,
            type=str(extra.get("type", "fixed")),
            pos=tuple(_floats(extra.get("pos", (0.0, 0.0, 0.0)), 3, "pos")),  # type: ignore[arg-type]
            quat=tuple(_floats(extra.get("quat", (0.0, 0.0, 0.0, 1.0)), 4, "quat")),  # type: ignore[arg-type]
            free_dofs=FreeDofs(*((float(dofs[2 * k]), float(dofs[2 * k + 1])) for k in range(6))),
            symbol=None if sym is None else str(sym),
        )
    except (ThirdhandError, ValueError) as exc:
        raise FormatError(path, f"constraint {parent} -> {child}: {exc}", line=line) from None


def _floats(v: Value, n: int, what: str) -> list[float]:
    if not isinstance(v, tuple) or len(v) != n:
        raise ValueError(f"{what} needs {n} numbers, got {v!r}")
    return [float(x) for x in v]


def frame_converter(
    path: Path, *, frame_times: ArrayLike | None, rate: float | None
) -> Callable[[float, int | None], float]:
    """Frame index -> seconds, through ``frame_times`` (0-based) or a constant ``rate``."""
    if frame_times is not None:
        ft = np.asarray(frame_times, dtype=np.float64)

        def through_times(frame: float, line: int | None) -> float:
            f = int(frame)
            if not 0 <= f < ft.size:
                raise FormatError(
                    path,
                    f"frame {f} is outside the recording's {ft.size} frames (0..{ft.size - 1})",
                    line=line,
                )
            return float(ft[f])

        return through_times
    if rate is None or not np.isfinite(rate) or rate <= 0:
        raise FormatError(
            path, f"frames need a time base: pass frame_times= or a positive rate= (got {rate})"
        )
    r = float(rate)
    return lambda frame, line: float(frame) / r


def read_annotations(
    path: str | os.PathLike[str],
    *,
    frame_times: ArrayLike | None = None,
    rate: float | None = None,
    bodies: Sequence[BodyInfo] | None = None,
) -> Labels:
    """Read an MLR annotation file (``ann_kvg.kvg``) into Labels.

    Parameters
    ----------
    path : path-like
    frame_times : array_like, shape (n_frames,), seconds, optional
        Time of each 0-based frame (a recording's ``poses.dat.times``).
    rate : float, optional
        Frame rate, Hz, when no frame times are known: frame ``f`` is at ``f / rate`` s.
    bodies : sequence of BodyInfo, optional
        The recording's bodies: names are checked and hand labels (``/human/rh``)
        expanded to the hand's tracked fingers.

    Returns
    -------
    Labels
        ``TS`` entries as interaction intervals (hand or finger, object), ``CE``
        entries as ``fixed`` constraint onsets (plus removals for locks ending before
        the last frame: ``len(frame_times) - 1``, else the largest frame in the file).
    """
    p = Path(path)
    entries = parse_annotations(p)
    to_seconds = frame_converter(p, frame_times=frame_times, rate=rate)
    if frame_times is not None:
        last = float(np.asarray(frame_times).size - 1)
    else:
        last = last_span_end(entries)
    return annotations_to_labels(entries, to_seconds, path=p, last=last, bodies=bodies)
