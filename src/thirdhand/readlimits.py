"""Bounded reads: every text input (JSON, kvg, XML, models) is checked before it is parsed.

- :func:`read_input`: the path must be a regular file (a FIFO, a device such as
  ``/dev/zero`` or a folder is refused before a byte is read: opening is
  non-blocking, so a FIFO without a writer cannot hang the command) no larger
  than a limit; the bytes are read in chunks, so Ctrl-C and SIGTERM stop a
  read at once.
- :func:`nesting_depth` / :func:`loads_json`: JSON nested deeper than
  :data:`MAX_DEPTH` is refused before ``json`` recurses into it (a
  ``RecursionError`` otherwise).
- :func:`check_xml_depth`: the same for XML, with expat's streaming parser.

Errors are the caller's type (``error(message)``), so a task file still raises
:class:`~thirdhand.errors.TaskFileError` and a recording ``FormatError``.
"""

from __future__ import annotations

import json
import os
import re
import stat
from collections.abc import Callable
from pathlib import Path
from typing import Any

from thirdhand.errors import FormatError, ThirdhandError

#: Deepest nesting of a JSON, kvg or XML document any thirdhand file needs
#: (a task file is 6 levels deep, a segmentation model 5, ``meta.kvg`` 3).
MAX_DEPTH = 64
#: Largest JSON or kvg document read (task files, models, metadata), bytes.
MAX_DOCUMENT_BYTES = 256 * 2**20
#: Largest recording file read (``poses.dat``, articulation logs), bytes.
MAX_RECORDING_BYTES = 4 * 2**30
_CHUNK = 2**20

ErrorFactory = Callable[[str], ThirdhandError]


def _default_error(path: Path) -> ErrorFactory:
    return lambda message: FormatError(path, message)


def _kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def check_regular(
    path: str | os.PathLike[str], *, what: str = "file", error: ErrorFactory | None = None
) -> Path:
    """Refuse a path that is not a regular file (following links), without opening it."""
    p = Path(path)
    err = error or _default_error(p)
    try:
        st = os.stat(p)
    except FileNotFoundError:
        raise err("no such file") from None
    except OSError as exc:
        raise err(f"cannot read: {exc.strerror or exc}") from None
    if not stat.S_ISREG(st.st_mode):
        raise err(f"is {_kind(st.st_mode)}, not a {what}")
    return p


def read_input(
    path: str | os.PathLike[str],
    *,
    what: str = "file",
    limit: int = MAX_DOCUMENT_BYTES,
    error: ErrorFactory | None = None,
) -> bytes:
    """The bytes of a regular file of at most ``limit`` bytes.

    Parameters
    ----------
    path : path-like
    what : str
        What the file should be, for the message (``"task file"``).
    limit : int
        Largest size accepted, bytes.
    error : callable, optional
        Makes the exception from a message; ``FormatError(path, message)`` by default.

    Raises
    ------
    ThirdhandError
        Missing, not a regular file, larger than ``limit``, or unreadable.
    """
    p = Path(path)
    err = error or _default_error(p)
    try:
        fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise err("no such file") from None
    except IsADirectoryError:
        raise err(f"is a folder, not a {what}") from None
    except OSError as exc:
        raise err(f"cannot read: {exc.strerror or exc}") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise err(f"is {_kind(st.st_mode)}, not a {what}")
        if st.st_size > limit:
            raise err(
                f"is {st.st_size / 2**20:.0f} MiB; a {what} of more than "
                f"{limit / 2**20:.0f} MiB is refused"
            )
        if hasattr(os, "set_blocking"):
            os.set_blocking(fd, True)
        parts: list[bytes] = []
        total = 0
        while True:
            chunk = os.read(fd, _CHUNK)
            if not chunk:
                break
            total += len(chunk)
            if total > limit:  # the file grew while it was read
                raise err(f"grew past {limit / 2**20:.0f} MiB while it was read")
            parts.append(chunk)
        return b"".join(parts)
    except OSError as exc:
        raise err(f"cannot read: {exc.strerror or exc}") from None
    finally:
        os.close(fd)


def read_text_input(
    path: str | os.PathLike[str],
    *,
    what: str = "file",
    limit: int = MAX_DOCUMENT_BYTES,
    error: ErrorFactory | None = None,
) -> str:
    """:func:`read_input` decoded as UTF-8 (an error names the byte offset)."""
    p = Path(path)
    err = error or _default_error(p)
    data = read_input(p, what=what, limit=limit, error=err)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise err(f"not UTF-8 text (byte {exc.start}); not a {what}") from None


_STRING = re.compile(r'"(?:[^"\\]|\\.)*"', re.DOTALL)


def nesting_depth(text: str) -> int:
    """Deepest nesting of ``[``/``{`` in a JSON text, strings skipped (linear, vectorised)."""
    import numpy as np

    code = np.frombuffer(_STRING.sub('""', text).encode("utf-8", "replace"), dtype=np.uint8)
    step = np.isin(code, (0x5B, 0x7B)).astype(np.int64) - np.isin(code, (0x5D, 0x7D))
    return int(np.cumsum(step).max(initial=0))


def check_json_depth(text: str, *, error: ErrorFactory, limit: int = MAX_DEPTH) -> None:
    """Refuse JSON nested deeper than ``limit`` before a recursive parser sees it."""
    if text.count("[") + text.count("{") <= limit:
        return
    depth = nesting_depth(text)
    if depth > limit:
        raise error(f"JSON nested {depth} levels deep; more than {limit} is refused")


def loads_json(
    text: str | bytes, *, error: ErrorFactory, limit: int = MAX_DEPTH, **kwargs: Any
) -> Any:
    """``json.loads`` after :func:`check_json_depth`; a syntax error raises ``error``."""
    if isinstance(text, bytes):
        try:
            text = text.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise error(f"not UTF-8 JSON (byte {exc.start})") from None
    check_json_depth(text, error=error, limit=limit)
    try:
        return json.loads(text, **kwargs)
    except json.JSONDecodeError as exc:
        raise error(f"line {exc.lineno} column {exc.colno}: invalid JSON: {exc.msg}") from None
    except RecursionError:  # pragma: no cover - the depth check comes first
        raise error("JSON nested too deeply") from None


def check_xml_depth(data: bytes, *, error: ErrorFactory, limit: int = MAX_DEPTH) -> None:
    """Refuse XML nested deeper than ``limit`` (or not well formed) with expat, streaming."""
    from xml.parsers import expat

    parser = expat.ParserCreate()
    depth = [0]

    class _TooDeep(Exception):
        pass

    def start(_name: str, _attrs: Any) -> None:
        depth[0] += 1
        if depth[0] > limit:
            raise _TooDeep

    def end(_name: str) -> None:
        depth[0] -= 1

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    try:
        parser.Parse(data, True)
    except _TooDeep:
        raise error(f"XML nested more than {limit} elements deep; refused") from None
    except expat.ExpatError as exc:
        raise error(
            f"line {exc.lineno}: not well-formed XML: {expat.ErrorString(exc.code)}"
        ) from None
    except (LookupError, ValueError) as exc:  # an unknown encoding declared in the prolog
        raise error(f"not readable XML: {exc}") from None


__all__ = [
    "MAX_DEPTH",
    "MAX_DOCUMENT_BYTES",
    "MAX_RECORDING_BYTES",
    "check_json_depth",
    "check_regular",
    "check_xml_depth",
    "loads_json",
    "nesting_depth",
    "read_input",
    "read_text_input",
]
