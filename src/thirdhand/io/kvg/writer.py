"""Labels to annotation-file text, frames nearest to label times."""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from thirdhand.demonstration import BodyInfo, ConstraintEvent, FreeDofs, Labels
from thirdhand.errors import FormatError
from thirdhand.io.kvg.graph import Value
from thirdhand.io.kvg.syntax import _BARE_WORD, format_value


def nearest_frames(frame_times: ArrayLike, times: ArrayLike) -> np.ndarray:
    """Index of the frame nearest to each time.

    Parameters
    ----------
    frame_times : array_like, shape (n_frames,), seconds, increasing
    times : array_like, shape (n,), seconds

    Returns
    -------
    ndarray of int, shape (n,)
    """
    ft = np.asarray(frame_times, dtype=np.float64)
    tt = np.atleast_1d(np.asarray(times, dtype=np.float64))
    hi = np.clip(np.searchsorted(ft, tt), 1, max(ft.size - 1, 1))
    lo = hi - 1
    if ft.size == 1:
        return np.zeros(tt.shape, dtype=np.int64)
    return np.where(np.abs(tt - ft[lo]) <= np.abs(ft[hi] - tt), lo, hi).astype(np.int64)


def _name(name: str) -> str:
    """A body name as a key: bare when it can be, quoted otherwise."""
    return name if _BARE_WORD.fullmatch(name) else format_value(name)


def _lock_text(start: int, end: int, extra: dict[str, Value]) -> str:
    fields = f"from={start}  to={end}"
    for k, v in extra.items():
        fields += f"  {k}={format_value(v)}"
    return f"lock {{ {fields} }}"


def _constraint_extras(c: ConstraintEvent) -> dict[str, Value]:
    """Keys beyond the original syntax, only where ``c`` differs from a default ``CE``."""
    extra: dict[str, Value] = {}
    if c.type != "fixed":
        extra["type"] = c.type
    if c.symbol is not None:
        extra["symbol"] = c.symbol
    if c.pos != (0.0, 0.0, 0.0):
        extra["pos"] = tuple(float(x) for x in c.pos)
    if c.quat != (0.0, 0.0, 0.0, 1.0):
        extra["quat"] = tuple(float(x) for x in c.quat)
    if c.free_dofs != FreeDofs():
        extra["free_dofs"] = tuple(x for r in c.free_dofs.ranges() for x in r)
    return extra


def format_annotations(
    labels: Labels,
    *,
    frame_times: ArrayLike,
    bodies: Sequence[BodyInfo] = (),
    path: str | os.PathLike[str] = "ann_kvg.kvg",
) -> str:
    """Text of an annotation file for ``labels``; the inverse of :func:`read_annotations`.

    Times become the nearest frame of ``frame_times`` (exact for labels on frame
    times). Interactions of every tracked finger of a hand that is not itself a body,
    with the same object and identical intervals, are written once under the hand's
    label (``TS /human/rh ...``), as the original files do.

    Parameters
    ----------
    labels : Labels
    frame_times : array_like, shape (n_frames,), seconds
    bodies : sequence of BodyInfo
        The recording's bodies, to group fingers into hands.
    path : path-like
        Named in errors.

    Raises
    ------
    FormatError
        A constraint removal with no onset just before it (the syntax cannot hold it).
    """
    ft = np.asarray(frame_times, dtype=np.float64)
    last = ft.size - 1

    def frame(t: float) -> int:
        return int(nearest_frames(ft, [t])[0])

    lines: list[str] = []
    names = {b.name for b in bodies}
    hands: dict[str, list[str]] = {}
    for info in bodies:
        if info.hand_body is not None and info.hand_body not in names:
            hands.setdefault(info.hand_body, []).append(info.name)
    finger_hand = {f: h for h, fs in hands.items() for f in fs}
    runs: list[tuple[str, str, list[tuple[float, float]]]] = []
    for it in labels.interactions:
        if runs and runs[-1][:2] == (it.a, it.b):
            runs[-1][2].append((it.start, it.end))
        else:
            runs.append((it.a, it.b, [(it.start, it.end)]))
    i = 0
    while i < len(runs):
        a, b, spans = runs[i]
        hand = finger_hand.get(a)
        label, step = a, 1
        if hand is not None and hands[hand][0] == a:
            group = runs[i : i + len(hands[hand])]
            fingers = hands[hand]
            if len(group) == len(fingers) and all(
                g == (f, b, spans) for g, f in zip(group, fingers, strict=True)
            ):
                label, step = hand, len(fingers)
        locks = "  ".join(_lock_text(frame(s), frame(e), {}) for s, e in spans)
        lines.append(f" TS {_name(label)} {_name(b)} {{ {locks} }}")
        i += step
    cons = list(labels.constraints)
    k = 0
    while k < len(cons):
        c = cons[k]
        if c.removed:
            raise FormatError(
                path,
                f"constraint {c.parent} -> {c.child} removed at {c.time:.9g} s has no onset "
                "just before it; the CE syntax cannot hold it",
            )
        end = last
        nxt = cons[k + 1] if k + 1 < len(cons) else None
        if (
            nxt is not None
            and nxt.removed
            and nxt == dataclasses.replace(c, time=nxt.time, removed=True)
        ):
            end = frame(nxt.time)
            k += 1
        lock = _lock_text(frame(c.time), end, _constraint_extras(c))
        lines.append(f" CE {_name(c.parent)} {_name(c.child)} {{ {lock} }}")
        k += 1
    for st in labels.plan:
        fields = "" if st.time is None else f"frame={frame(st.time)}  "
        if st.symbol is not None:
            fields += f"symbol={format_value(st.symbol)} "
        lines.append(f" PS {_name(st.parent)} {_name(st.child)} {{ step {{ {fields}}} }}")
    return "\n".join(lines) + "\n"
