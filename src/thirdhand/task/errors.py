"""Flatten pydantic's list of validation errors into one line that says where."""

from __future__ import annotations

import re
from collections.abc import Sequence

from pydantic import ValidationError


def json_location(loc: Sequence[int | str]) -> str:
    """A pydantic ``loc`` as a JSON path.

    ``("plan", 2, "keyframe", "leg1")`` -> ``plan[2].keyframe.leg1``.
    """
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += f".{part}" if out else str(part)
    return out


#: A check's message that starts with the location inside the checked model
#: (``"steps[2].start: ..."``), joined to the model's own location.
_INNER_LOCATION = re.compile(r"^([A-Za-z_][\w]*(?:\[\d+\])*(?:\.[A-Za-z_\w]+(?:\[\d+\])*)*): ")


def flatten_errors(exc: ValidationError) -> list[str]:
    """Each error of ``exc`` as ``"<location>: <message>"``.

    Errors of the whole document (cross-field checks) carry their location in
    their message already.
    """
    lines = []
    for err in exc.errors(include_url=False):
        ctx = err.get("ctx") or {}
        if err["type"] in ("value_error", "assertion_error") and "error" in ctx:
            msg = str(ctx["error"])
        else:
            msg = err["msg"]
        if err["type"] == "finite_number":
            got = err.get("input")
            msg = f"{got!r} is not a finite number (a task file holds no NaN or infinity)"
        if err["type"] == "missing":
            msg = "required field is missing"
        if err["type"] == "json_invalid":
            msg = f"invalid JSON: {ctx.get('error', msg)}"
        loc = json_location(err["loc"])
        if loc and err["type"] == "value_error" and _INNER_LOCATION.match(msg):
            loc, msg = f"{loc}.{msg.split(': ', 1)[0]}", msg.split(": ", 1)[1]
        lines.append(f"{loc}: {msg}" if loc else msg)
    return lines


def first_error(exc: ValidationError) -> str:
    """The first error of ``exc`` on one line, with a count of the others."""
    lines = flatten_errors(exc)
    more = (
        f" (and {len(lines) - 1} more error{'s' if len(lines) > 2 else ''})"
        if len(lines) > 1
        else ""
    )
    return lines[0] + more
