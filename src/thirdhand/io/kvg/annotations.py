"""3rdHand annotation entries (``TS`` / ``CE`` / ``PS`` nodes) and their frame spans."""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from thirdhand.errors import FormatError
from thirdhand.io.kvg.graph import Graph, Value
from thirdhand.io.kvg.syntax import read


@dataclass(frozen=True)
class Annotation:
    """One labelled body pair of an annotation file, before its times are resolved.

    Attributes
    ----------
    tag : {"TS", "CE", "PS"}
        Hand-object interaction, object-object constraint, or plan step.
    a, b : str
        The names as written (a hand label such as ``/human/rh`` stays as is).
    spans : tuple of (start, end)
        Frames (``.kvg``) or seconds (ELAN), in file order.
    extras : tuple of dict
        Per span, the keys beyond ``from``/``to`` (constraint type, symbol...).
    line : int or None
        1-based line of the entry (ELAN: of its tier; None if it cannot be found).
    """

    tag: str
    a: str
    b: str
    spans: tuple[tuple[float, float], ...]
    extras: tuple[dict[str, Value], ...]
    line: int | None


TAGS = ("TS", "CE", "PS")


def parse_annotations(path: str | os.PathLike[str]) -> list[Annotation]:
    """The entries of an ``ann_kvg.kvg`` file, spans in frames.

    Raises
    ------
    FormatError
        A syntax error, an entry that is not ``TS|CE|PS a b { lock {from= to=} ... }``,
        or a lock whose ``from`` is after its ``to``.
    """
    p = Path(path)
    graph = read(p)
    if not len(graph):
        raise FormatError(p, "empty annotation file: expected TS/CE entries")
    out: list[Annotation] = []
    for node in graph:
        if len(node.keys) != 3 or node.keys[0] not in TAGS or not isinstance(node.value, Graph):
            raise FormatError(
                p,
                "expected an entry 'TS|CE|PS <a> <b> { lock { from=F to=T } ... }', got keys "
                f"{' '.join(node.keys) or '(none)'}",
                line=node.line,
            )
        spans: list[tuple[float, float]] = []
        extras: list[dict[str, Value]] = []
        child = "step" if node.keys[0] == "PS" else "lock"
        for sub in node.value:
            if sub.keys != (child,) or not isinstance(sub.value, Graph):
                raise FormatError(
                    p,
                    f"expected '{child} {{ ... }}' inside a {node.keys[0]} entry, got "
                    f"{' '.join(sub.keys) or repr(sub.value)}",
                    line=sub.line,
                )
            fields = {n.keys[0]: n.value for n in sub.value if n.keys}
            spans.append(_span(fields, child, p, sub.line))
            extras.append(fields)
        out.append(
            Annotation(
                node.keys[0], node.keys[1], node.keys[2], tuple(spans), tuple(extras), node.line
            )
        )
    return out


def _frame_value(v: Value, what: str, path: Path, line: int) -> int:
    if not isinstance(v, int) or isinstance(v, bool):
        raise FormatError(path, f"{what} must be an integer frame, got {v!r}", line=line)
    return v


def _span(fields: dict[str, Value], child: str, path: Path, line: int) -> tuple[float, float]:
    """Pop the frame span of a ``lock`` (``from``/``to``) or ``step`` (optional ``frame``)."""
    if child == "step":
        if "frame" not in fields:
            return (float("nan"), float("nan"))
        start = end = _frame_value(fields.pop("frame"), "step frame=", path, line)
    else:
        start = _frame_value(fields.pop("from", None), "lock from=", path, line)
        end = _frame_value(fields.pop("to", None), "lock to=", path, line)
    if not 0 <= start <= end:
        raise FormatError(
            path, f"{child} from={start} to={end}: expected 0 <= from <= to", line=line
        )
    return (float(start), float(end))


def last_span_end(entries: Sequence[Annotation]) -> float:
    """The largest ``TS``/``CE`` span end of a file: the recording's end when unknown."""
    ends = [t for e in entries if e.tag != "PS" for _, t in e.spans]
    return max(ends) if ends else 0.0
