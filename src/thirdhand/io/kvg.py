"""The MLR key-value graph syntax (``.kvg``) and the 3rdHand annotation files written in it.

A graph is a sequence of nodes. A node is a list of keys (bare words or quoted
strings), optionally parents in parentheses, and optionally a value::

    agents {                                        # keys ["agents"], value: a subgraph
      /human/rh/thumb = { type = digit, rn = 0 }    # keys ["/human/rh/thumb"], value: a subgraph
    }
    TS /human/rh /toolbox/side_front { lock { from=2392 to=2505 } }

A value after ``=`` is a number, ``true``/``false``, a bare word or quoted string, a
``[ ... ]`` array of numbers, or a ``{ ... }`` subgraph; a ``{ ... }`` right after
the keys is a subgraph too. Nodes are separated by newlines, commas or
semicolons; ``#`` starts a comment.

Annotation files (``ann_kvg.kvg``) hold one node per labelled body pair:

- ``TS hand object { lock { from=F to=T } ... }``: the hand touches the object
  over frames ``F..T`` (hand-object interaction phases);
- ``CE parent child { lock { from=F to=T } ... }``: a constraint between two
  objects holds over frames ``F..T``; ``F`` is its onset.

Frames are 0-based indices into ``poses.dat``'s blocks (the toolbox_3 labels of a
22,548-frame recording end at frame 22547). The file does not say which kind of
constraint a ``CE`` is: it reads as ``type="fixed"`` (the toolbox sides are
screwed together). A ``CE`` lock ending before the last frame of the recording
also yields a removal event at ``T``. thirdhand writes extra keys inside a lock
only when a label carries more than the original syntax holds (``type``,
``symbol``, ``pos``, ``quat``, ``free_dofs``), and ``PS parent child { step {
frame=F symbol=S } }`` nodes for plan steps, so that labels round-trip.
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Union

import numpy as np
from numpy.typing import ArrayLike

from thirdhand.demonstration import (
    BodyInfo,
    ConstraintEvent,
    InteractionInterval,
    Labels,
    PlanStep,
)
from thirdhand.errors import FormatError, ThirdhandError

Value = Union[None, bool, int, float, str, tuple[float, ...], "Graph"]

_TOKEN = re.compile(
    r"""(?P<nl>\n)|(?P<ws>[ \t\r\f\v]+)|(?P<comment>\#[^\n]*)
    |(?P<str>"(?:[^"\\\n]|\\.)*")|(?P<punct>[{}()\[\]=,;])
    |(?P<word>[^\s{}()\[\]=,;"'\#]+)""",
    re.VERBOSE,
)
_BARE_WORD = re.compile(r"[^\s{}()\[\]=,;\"'#]+")


@dataclass(frozen=True)
class Node:
    """One node of a key-value graph.

    Attributes
    ----------
    keys : tuple of str
    parents : tuple of str
        Names in parentheses after the keys (rare in MLR files).
    value : None, bool, int, float, str, tuple of float or Graph
        None for a node with keys only.
    line : int
        1-based line of the node's first token.
    """

    keys: tuple[str, ...]
    parents: tuple[str, ...]
    value: Value
    line: int


@dataclass(frozen=True)
class Graph:
    """A parsed key-value graph: its nodes in file order."""

    nodes: tuple[Node, ...]

    def __iter__(self) -> Iterator[Node]:
        return iter(self.nodes)

    def __len__(self) -> int:
        return len(self.nodes)

    def find(self, key: str) -> Node | None:
        """The first node whose first key is ``key``, or None."""
        return next((n for n in self.nodes if n.keys and n.keys[0] == key), None)

    def get(self, key: str, default: Value = None) -> Value:
        """Value of the first node whose first key is ``key``."""
        node = self.find(key)
        return default if node is None else node.value

    def to_dict(self) -> dict[str, object]:
        """Scalar and array entries keyed by their first key (subgraphs as nested dicts)."""
        out: dict[str, object] = {}
        for n in self.nodes:
            if n.keys:
                out[n.keys[0]] = n.value.to_dict() if isinstance(n.value, Graph) else n.value
        return out


# ------------------------------------------------------------------ parsing
def _tokenize(text: str, path: Path) -> list[tuple[str, str, int]]:
    tokens: list[tuple[str, str, int]] = []
    line, pos = 1, 0
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if m is None:
            what = (
                "unterminated string" if text[pos] == '"' else f"unexpected character {text[pos]!r}"
            )
            raise FormatError(path, what, line=line)
        kind = m.lastgroup or ""
        if kind == "nl":
            tokens.append(("nl", "\n", line))
            line += 1
        elif kind in ("str", "punct", "word"):
            tokens.append((kind, m.group(), line))
        pos = m.end()
    return tokens


class _Parser:
    def __init__(self, tokens: list[tuple[str, str, int]], path: Path) -> None:
        self.tokens = tokens
        self.path = path
        self.i = 0

    def peek(self) -> tuple[str, str, int]:
        if self.i < len(self.tokens):
            return self.tokens[self.i]
        last = self.tokens[-1][2] if self.tokens else 1
        return ("eof", "", last)

    def error(self, message: str, line: int) -> FormatError:
        return FormatError(self.path, message, line=line)

    def graph(self, opened_at: int | None) -> Graph:
        nodes: list[Node] = []
        while True:
            kind, text, line = self.peek()
            if kind == "nl" or text in (",", ";"):
                self.i += 1
            elif kind == "eof":
                if opened_at is not None:
                    raise self.error(
                        f"unbalanced braces: '{{' opened on line {opened_at} is never closed",
                        opened_at,
                    )
                return Graph(tuple(nodes))
            elif text == "}":
                if opened_at is None:
                    raise self.error("unbalanced braces: '}' without a matching '{'", line)
                self.i += 1
                return Graph(tuple(nodes))
            else:
                nodes.append(self.node())

    def node(self) -> Node:
        keys: list[str] = []
        parents: list[str] = []
        first_line = self.peek()[2]
        while self.peek()[0] in ("word", "str"):
            keys.append(_unquote(self.peek()[1]))
            self.i += 1
        kind, text, line = self.peek()
        if text == "(":
            self.i += 1
            while self.peek()[0] in ("word", "str", "nl") or self.peek()[1] == ",":
                if self.peek()[0] in ("word", "str"):
                    parents.append(_unquote(self.peek()[1]))
                self.i += 1
            if self.peek()[1] != ")":
                raise self.error(f"expected ')' closing the parents list, got {self._desc()}", line)
            self.i += 1
            kind, text, line = self.peek()
        value: Value = None
        if text == "=":
            self.i += 1
            while self.peek()[0] == "nl":
                self.i += 1
            value = self.value()
        elif text in ("{", "["):
            value = self.value()
        elif not (kind in ("nl", "eof") or text in (",", ";", "}")):
            raise self.error(f"unexpected {self._desc()}", line)
        elif not keys and not parents:
            raise self.error(f"expected a key, got {self._desc()}", line)
        return Node(tuple(keys), tuple(parents), value, first_line)

    def value(self) -> Value:
        kind, text, line = self.peek()
        self.i += 1
        if text == "{":
            return self.graph(opened_at=line)
        if text == "[":
            items: list[float] = []
            while True:
                k, t, ln = self.peek()
                if k == "eof":
                    raise self.error(f"'[' opened on line {line} is never closed", line)
                self.i += 1
                if t == "]":
                    return tuple(items)
                if k == "nl" or t in (",", ";"):
                    continue
                try:
                    items.append(float(t))
                except ValueError:
                    raise self.error(f"array element {t!r} is not a number", ln) from None
        if kind == "str":
            return _unquote(text)
        if kind == "word":
            return _scalar(text)
        self.i -= 1
        raise self.error(f"expected a value after '=', got {self._desc()}", line)

    def _desc(self) -> str:
        kind, text, _ = self.peek()
        return "end of file" if kind == "eof" else ("end of line" if kind == "nl" else repr(text))


def _unquote(token: str) -> str:
    if len(token) >= 2 and token[0] == '"' and token[-1] == '"':
        return re.sub(r"\\(.)", r"\1", token[1:-1])
    return token


def _scalar(word: str) -> bool | int | float | str:
    if word in ("true", "false"):
        return word == "true"
    try:
        return int(word)
    except ValueError:
        pass
    try:
        return float(word)
    except ValueError:
        return word


def parse(text: str, path: str | os.PathLike[str] = "<string>") -> Graph:
    """Parse key-value graph text.

    Raises
    ------
    FormatError
        Naming the line of a syntax error (unbalanced brace, unterminated string...).
    """
    p = Path(path)
    return _Parser(_tokenize(text, p), p).graph(opened_at=None)


def read(path: str | os.PathLike[str]) -> Graph:
    """Read and parse a ``.kvg`` file."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise FormatError(p, f"cannot read: {exc}") from None
    return parse(text, p)


def format_value(value: Value) -> str:
    """Text of a scalar or array value; floats with full precision (``repr`` round-trips)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float):
        return repr(value) if isinstance(value, float) else str(value)
    if isinstance(value, str):
        if _BARE_WORD.fullmatch(value) and isinstance(_scalar(value), str):
            return value
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, tuple):
        return "[" + " ".join(repr(float(x)) for x in value) + "]"
    raise TypeError(f"cannot format {type(value).__name__} as a kvg scalar")


# -------------------------------------------------------------- annotations
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
            free_dofs=tuple((dofs[2 * k], dofs[2 * k + 1]) for k in range(6)),
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


def last_span_end(entries: Sequence[Annotation]) -> float:
    """The largest ``TS``/``CE`` span end of a file: the recording's end when unknown."""
    ends = [t for e in entries if e.tag != "PS" for _, t in e.spans]
    return max(ends) if ends else 0.0


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


# ------------------------------------------------------------------ writing
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
    if c.free_dofs != ((0.0, 0.0),) * 6:
        extra["free_dofs"] = tuple(float(x) for r in c.free_dofs for x in r)
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


__all__ = [
    "TAGS",
    "Annotation",
    "Graph",
    "Node",
    "annotations_to_labels",
    "format_annotations",
    "format_value",
    "frame_converter",
    "last_span_end",
    "nearest_frames",
    "parse",
    "parse_annotations",
    "read",
    "read_annotations",
    "resolve_body",
]
