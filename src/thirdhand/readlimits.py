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

import contextlib
import json
import os
import re
import stat
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, BinaryIO

from thirdhand.errors import FormatError, ThirdhandError

#: Deepest nesting of a JSON, kvg or XML document any thirdhand file needs
#: (a task file is 6 levels deep, a segmentation model 5, ``meta.kvg`` 3).
MAX_DEPTH = 64
#: Largest JSON or kvg document read (task files, models, metadata), bytes.
MAX_DOCUMENT_BYTES = 256 * 2**20
#: Largest recording file read (``poses.dat``, articulation logs), bytes.
MAX_RECORDING_BYTES = 4 * 2**30
#: Largest settings file (``--config``), bytes: a few hundred settings at most.
MAX_CONFIG_BYTES = 2**20
#: Largest run (``execute --record`` trajectory JSON), bytes: hours of a 7-joint arm at 50 Hz.
MAX_RUN_BYTES = 256 * 2**20
#: Largest skill library (JSON of a few dozen Gaussians and transitions), bytes.
MAX_LIBRARY_BYTES = 16 * 2**20
#: Largest mesh file of a part (STL, OBJ), bytes: a scanned part of a few million triangles.
MAX_MESH_BYTES = 256 * 2**20
#: Largest scene or small side file (a scene's bodies, a phases file, a tracks CSV), bytes.
MAX_SIDE_BYTES = 64 * 2**20
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


@contextlib.contextmanager
def open_input(
    path: str | os.PathLike[str],
    *,
    what: str = "file",
    limit: int = MAX_RECORDING_BYTES,
    error: ErrorFactory | None = None,
) -> Iterator[BinaryIO]:
    """A regular file of at most ``limit`` bytes, open for reading in binary (a stream).

    For readers that seek or read a file in parts (C3D, Motive, parquet): the
    same checks as :func:`read_input` (a FIFO cannot hang it: the open is
    non-blocking), then an ordinary buffered file object.
    """
    p = Path(path)
    err = error or _default_error(p)
    fd = _open_regular(p, what=what, limit=limit, error=err)
    try:
        fh = os.fdopen(fd, "rb")
    except OSError as exc:
        os.close(fd)
        raise err(f"cannot read: {exc.strerror or exc}") from None
    with fh:
        yield fh


def _open_regular(p: Path, *, what: str, limit: int, error: ErrorFactory) -> int:
    """A blocking descriptor of the regular file ``p`` of at most ``limit`` bytes."""
    try:
        fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise error("no such file") from None
    except IsADirectoryError:
        raise error(f"is a folder, not a {what}") from None
    except OSError as exc:
        raise error(f"cannot read: {exc.strerror or exc}") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise error(f"is {_kind(st.st_mode)}, not a {what}")
        if st.st_size > limit:
            raise error(
                f"is {st.st_size / 2**20:.0f} MiB; a {what} of more than "
                f"{limit / 2**20:.0f} MiB is refused"
            )
        if hasattr(os, "set_blocking"):
            os.set_blocking(fd, True)
    except BaseException:
        os.close(fd)
        raise
    return fd


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
    fd = _open_regular(p, what=what, limit=limit, error=err)
    try:
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


def sniff_bytes(path: str | os.PathLike[str], n: int, *, offset: int = 0) -> bytes:
    """Up to ``n`` bytes at ``offset`` of a regular file; ``b""`` for anything else.

    For format detection: a FIFO, device, folder or unreadable path is no
    recording of any format (the reader then says why in one line).
    """
    p = Path(path)
    try:
        fd = _open_regular(
            p, what="file", limit=MAX_RECORDING_BYTES * 16, error=lambda m: FormatError(p, m)
        )
    except FormatError:
        return b""
    try:
        return os.pread(fd, n, offset) if offset else os.read(fd, n)
    except OSError:
        return b""
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


def unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """A JSON object's pairs as a dict; a key given twice is refused (not last-wins)."""
    out: dict[str, Any] = {}
    for k, v in pairs:
        if k in out:
            raise ValueError(f"the key {k!r} is given twice in one object")
        out[k] = v
    return out


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a JSON number (write null, or a finite number)")


def loads_json(
    text: str | bytes,
    *,
    error: ErrorFactory,
    limit: int = MAX_DEPTH,
    strict: bool = False,
    **kwargs: Any,
) -> Any:
    """``json.loads`` after :func:`check_json_depth`; a syntax error raises ``error``.

    With ``strict`` a key given twice in one object and the non-JSON literals
    ``NaN``/``Infinity`` are refused too (a file a person edits by hand).
    """
    if strict:
        kwargs.setdefault("object_pairs_hook", unique_keys)
        kwargs.setdefault("parse_constant", _no_constant)
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
    except ValueError as exc:  # a duplicate key or a NaN literal (strict)
        raise error(f"invalid JSON: {exc}") from None


def read_json(
    path: str | os.PathLike[str],
    *,
    what: str = "JSON file",
    limit: int = MAX_DOCUMENT_BYTES,
    error: ErrorFactory | None = None,
    strict: bool = False,
) -> Any:
    """The JSON document in the regular file ``path``: size, text and nesting bounded.

    :func:`read_text_input` then :func:`loads_json`; every failure is one ``error``.
    """
    p = Path(path)
    err = error or _default_error(p)
    return loads_json(
        read_text_input(p, what=what, limit=limit, error=err), error=err, strict=strict
    )


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
    "MAX_CONFIG_BYTES",
    "MAX_DEPTH",
    "MAX_DOCUMENT_BYTES",
    "MAX_LIBRARY_BYTES",
    "MAX_MESH_BYTES",
    "MAX_RECORDING_BYTES",
    "MAX_RUN_BYTES",
    "MAX_SIDE_BYTES",
    "check_json_depth",
    "check_regular",
    "check_xml_depth",
    "loads_json",
    "nesting_depth",
    "open_input",
    "read_input",
    "read_json",
    "read_text_input",
    "sniff_bytes",
    "unique_keys",
]
