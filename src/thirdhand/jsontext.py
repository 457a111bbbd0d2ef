"""Strict JSON text for every file thirdhand writes: no ``NaN`` or ``Infinity`` literals.

``json.dumps`` writes ``NaN`` by default, which is not JSON (RFC 8259) and which
other readers refuse. :func:`dumps` refuses instead, in one line naming where
the value is, so a stage that produced a non-finite number is found, not hidden
in a file.
"""

from __future__ import annotations

import json
import math
from typing import Any

from thirdhand.errors import OutputError


def non_finite_path(value: Any, path: str = "$") -> str | None:
    """The JSON location (``$.skills.means[2][0]``) of the first non-finite number, or None."""
    if isinstance(value, float):
        return None if math.isfinite(value) else f"{path} = {value}"
    if isinstance(value, dict):
        for k, v in value.items():
            found = non_finite_path(v, f"{path}.{k}")
            if found is not None:
                return found
    if isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            found = non_finite_path(v, f"{path}[{i}]")
            if found is not None:
                return found
    return None


def dumps(value: Any, *, what: str, **options: Any) -> str:
    """``json.dumps(value, allow_nan=False, **options)``.

    Parameters
    ----------
    value : JSON-able
    what : str
        The output, for the message (a path or a description).

    Raises
    ------
    OutputError
        A NaN or infinite number in ``value`` (the message gives its location).
    """
    try:
        return json.dumps(value, allow_nan=False, **options)
    except ValueError:
        where = non_finite_path(value)
        if where is None:
            raise
        raise OutputError(f"{what}: not written, {where} is not a number JSON can hold") from None
