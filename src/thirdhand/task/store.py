"""Reading and writing task files: validated load, atomic save with a backup of the previous file.

A user's corrected task is never lost: before a file is replaced, its exact
bytes are kept as its next numbered backup (``<name>.bak``, ``<name>.bak.1``,
…), and the new content goes to a uniquely named temporary file beside it, is
flushed to disk, then renamed over the original in one step.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from thirdhand.errors import OutputError, TaskFileError
from thirdhand.fileops import write_text
from thirdhand.readlimits import check_json_depth, read_text_input
from thirdhand.task.errors import first_error
from thirdhand.task.migrate import migrate
from thirdhand.task.model import TaskFile


def _reject_duplicate_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in pairs:
        if k in out:
            raise ValueError(f"duplicate key {k!r} in a JSON object")
        out[k] = v
    return out


def _reject_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a JSON number (no NaN or infinity in a task file)")


def parse_task(text: str, *, name: str = "<task>") -> TaskFile:
    """Validate the JSON text of a task file (an earlier schema's migrated first).

    Parameters
    ----------
    text : str
        The document.
    name : str
        How to name the document in error messages (a file name).

    Raises
    ------
    TaskFileError
        ``"<name> line L column C: ..."`` for bad JSON, ``"<name>: <location>: ..."``
        for the first invalid field, e.g.
        ``task.json: constraints[2].child: unknown object 'leg7'``.
    """
    check_json_depth(text, error=lambda m: TaskFileError(f"{name}: {m}"))
    try:
        data = json.loads(
            text, object_pairs_hook=_reject_duplicate_keys, parse_constant=_reject_constant
        )
    except json.JSONDecodeError as exc:
        raise TaskFileError(
            f"{name} line {exc.lineno} column {exc.colno}: invalid JSON: {exc.msg}"
        ) from None
    except ValueError as exc:
        raise TaskFileError(f"{name}: invalid JSON: {exc}") from None
    if not isinstance(data, dict):
        raise TaskFileError(f"{name}: expected a JSON object, got {type(data).__name__}")
    migrated = migrate(data, name=name)
    if migrated is not data:
        text = json.dumps(migrated, allow_nan=False)
    try:
        # Strict JSON validation: no "1.5" strings for numbers, no numbers for names.
        return TaskFile.model_validate_json(text, strict=True)
    except ValidationError as exc:
        raise TaskFileError(f"{name}: {first_error(exc)}") from None


def load_task(path: str | os.PathLike[str]) -> TaskFile:
    """Read and validate a task file.

    Raises
    ------
    TaskFileError
        If the file cannot be read, is not JSON (the message gives line and
        column) or is not a valid ``thirdhand.task/2`` document (nor one of an
        earlier schema, migrated) (the message gives
        the JSON location of the first error).
    """
    p = Path(path)
    text = read_text_input(
        p, what="task file", error=lambda m: TaskFileError(f"{p}: cannot read task file: {m}")
    )
    return parse_task(text, name=str(p))


def _format(value: Any, indent: str) -> str:
    """JSON of ``value``: objects one key a line, arrays of scalars on one line."""
    inner = indent + "  "
    if isinstance(value, dict):
        if not value:
            return "{}"
        items = [
            f"{inner}{json.dumps(k, ensure_ascii=False, allow_nan=False)}: {_format(v, inner)}"
            for k, v in value.items()
        ]
        return "{\n" + ",\n".join(items) + "\n" + indent + "}"
    if isinstance(value, list):
        if not any(isinstance(v, dict | list) for v in value):
            return json.dumps(value, ensure_ascii=False, allow_nan=False, separators=(", ", ": "))
        items = [inner + _format(v, inner) for v in value]
        return "[\n" + ",\n".join(items) + "\n" + indent + "]"
    return json.dumps(value, ensure_ascii=False, allow_nan=False)


def dump_task(task: TaskFile) -> str:
    """The JSON text of ``task``.

    Indented, keys in schema order (unknown keys after, in the order read), flat
    number arrays on one line, floats as their shortest exact repr (they read back
    bit for bit).
    """
    return _format(task.to_json_dict(), "") + "\n"


def save_task(task: TaskFile, path: str | os.PathLike[str], *, backup: bool = True) -> None:
    """Write ``task`` to ``path`` atomically, keeping the previous file as a numbered backup.

    The task is validated again first (in-memory edits may have broken it), then
    written to a uniquely named temporary file beside ``path``, flushed to disk
    and renamed over ``path`` (:func:`thirdhand.fileops.atomic_output`). If
    ``path`` exists, it is kept as its next backup (``path.bak``, then
    ``path.bak.1``, …) under a lock on the folder, so concurrent saves from
    several processes each back up the version they replace and a reader only
    ever sees a complete task file.

    Parameters
    ----------
    task : TaskFile
    path : path-like
    backup : bool
        Keep the previous file (default). Only for a file the same run wrote
        moments before.

    Raises
    ------
    TaskFileError
        If the task is invalid (nothing is written) or the file cannot be written
        (the previous file is left as it was).
    """
    p = Path(path)
    try:
        text = dump_task(task)
    except ValueError as exc:
        raise TaskFileError(f"{p}: cannot write task: {exc}") from None
    parse_task(text, name=str(p))
    try:
        write_text(p, text, backup=backup)
    except OutputError as exc:
        reason = str(exc).removeprefix(f"{p}: cannot write: ")
        raise TaskFileError(f"{p}: cannot write task file: {reason}") from None
