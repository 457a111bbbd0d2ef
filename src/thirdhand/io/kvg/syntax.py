"""The ``.kvg`` text syntax: parsing it into a :class:`~thirdhand.io.kvg.Graph`, writing values."""

from __future__ import annotations

import os
import re
from pathlib import Path

from thirdhand.errors import FormatError
from thirdhand.io.kvg.graph import Graph, Node, Value
from thirdhand.readlimits import MAX_DEPTH, read_text_input

_TOKEN = re.compile(
    r"""(?P<nl>\n)|(?P<ws>[ \t\r\f\v]+)|(?P<comment>\#[^\n]*)
    |(?P<str>"(?:[^"\\\n]|\\.)*")|(?P<punct>[{}()\[\]=,;])
    |(?P<word>[^\s{}()\[\]=,;"'\#]+)""",
    re.VERBOSE,
)
_BARE_WORD = re.compile(r"[^\s{}()\[\]=,;\"'#]+")


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
        self.depth = 0

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
            self.depth += 1
            if self.depth > MAX_DEPTH:
                raise self.error(f"braces nested more than {MAX_DEPTH} deep; refused", line)
            graph = self.graph(opened_at=line)
            self.depth -= 1
            return graph
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
    return parse(read_text_input(p, what="kvg file"), p)


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
