"""The header of a Motive export: first-line keys, label rows, rate and units."""

from __future__ import annotations

import csv
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from thirdhand.errors import FormatError
from thirdhand.io.motive.constants import _MAGIC, ASSET_TYPES, LENGTH_UNITS

_LABELS = ("Type", "Name", "ID", "Parent")
_MAX_HEADER_LINES = 64


@dataclass
class _Header:
    """What the header lines say; ``rows`` maps a row role to its cells (padded)."""

    keys: dict[str, str]
    rows: dict[str, list[str]] = field(default_factory=dict)
    row_lines: dict[str, int] = field(default_factory=dict)
    n_cols: int = 0
    data_line: int = 0
    data_offset: int = 0


_INTEGER = re.compile(r"[+-]?\d+")


def sniff(path: Path) -> bool:
    """A file whose first line starts with ``Format Version,`` (Motive's CSV export)."""
    from thirdhand.readlimits import sniff_bytes

    head = sniff_bytes(path, 64)
    return head.removeprefix(b"\xef\xbb\xbf").startswith(_MAGIC.encode() + b",")


def _decode(raw: bytes) -> str:
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return raw.decode("cp1252", errors="replace")


def _cells(text: str, path: Path | None = None, line: int | None = None) -> list[str]:
    """The CSV cells of one line; a stray carriage return or quote is a FormatError."""
    try:
        return next(csv.reader([text]), [])
    except csv.Error as exc:
        raise FormatError(
            path if path is not None else "<csv>",
            f"cannot split the line into cells ({exc}); a stray carriage return or quote?",
            line=line,
        ) from None


def _read_header(path: Path) -> _Header:
    """Parse the key/value line and the header rows up to ``Frame,Time``."""
    from thirdhand.readlimits import open_input

    with open_input(path, what="Motive CSV file") as fh:
        first = fh.readline()
        if not first.strip():
            raise FormatError(
                path, "empty file: expected Motive's 'Format Version,...' line", line=1
            )
        text = _decode(first.removeprefix(b"\xef\xbb\xbf")).rstrip("\r\n")
        cells = _cells(text, path, 1)
        if not cells or cells[0].strip() != _MAGIC:
            raise FormatError(
                path,
                f"not a Motive CSV export: expected the first line to start with "
                f"'{_MAGIC},', found {text[:40]!r}",
                line=1,
            )
        keys = {
            cells[i].strip(): (cells[i + 1].strip() if i + 1 < len(cells) else "")
            for i in range(0, len(cells), 2)
            if cells[i].strip()
        }
        _check_first_line(path, keys)
        header = _Header(keys=keys)
        unlabelled: list[tuple[int, list[str]]] = []
        lineno = 1
        offset = len(first)
        while True:
            raw = fh.readline()
            lineno += 1
            offset += len(raw)
            if not raw:
                raise FormatError(
                    path,
                    "truncated header: the file ends before the 'Frame,Time (Seconds),...' row",
                    line=lineno,
                )
            if lineno > _MAX_HEADER_LINES:
                raise FormatError(
                    path,
                    f"no 'Frame,Time (Seconds),...' row in the first {_MAX_HEADER_LINES} lines",
                    line=lineno,
                )
            row = _cells(_decode(raw).rstrip("\r\n"), path, lineno)
            if not any(c.strip() for c in row):
                continue
            if _INTEGER.fullmatch(row[0].strip()):
                raise FormatError(
                    path,
                    f"a data row (frame {row[0].strip()}) above the 'Frame,Time (Seconds),...' "
                    "row; the Frame row must come right before the data",
                    line=lineno,
                )
            if row[0].strip() == "Frame":
                _finish_header(path, header, row, lineno, unlabelled)
                header.data_line = lineno + 1
                header.data_offset = offset
                return header
            label = row[1].strip() if len(row) > 1 else ""
            if label in _LABELS:
                role = label.lower()
                if role in header.rows:
                    raise FormatError(
                        path,
                        f"header row {label!r} appears twice (first at line "
                        f"{header.row_lines[role]})",
                        line=lineno,
                    )
                header.rows[role], header.row_lines[role] = row, lineno
            elif not label:
                unlabelled.append((lineno, row))


def _check_first_line(path: Path, keys: Mapping[str, str]) -> None:
    """Refuse, before reading further, a format or rotation type this reader cannot take."""
    version = keys.get(_MAGIC, "")
    number = re.match(r"\d+(\.\d+)?", version)
    version_ok = number is not None and float(number.group()) >= 1.2
    if not version_ok:
        raise FormatError(
            path,
            f"unsupported Format Version {version!r}; this reader handles 1.2 and later",
            line=1,
        )
    rotation = keys.get("Rotation Type", "Quaternion")
    if rotation.lower() != "quaternion":
        raise FormatError(
            path,
            f"Rotation Type is {rotation!r}; only Quaternion exports are supported",
            line=1,
        )


def _finish_header(
    path: Path,
    header: _Header,
    axis: list[str],
    axis_line: int,
    unlabelled: list[tuple[int, list[str]]],
) -> None:
    """Identify unlabelled rows, check every row's width, pad them to the axis row's."""
    if len(axis) < 2 or not axis[1].strip().startswith("Time"):
        found = axis[1] if len(axis) > 1 else "nothing"
        raise FormatError(
            path,
            f"expected 'Time (Seconds)' in column 2 of the Frame row, found {found!r}",
            line=axis_line,
        )
    others = []
    for lineno, row in unlabelled:
        if any(c.strip() in ("Position", "Rotation") for c in row):
            header.rows["component"], header.row_lines["component"] = row, lineno
        else:
            others.append((lineno, row))
    # Format 1.21 writes Type, Name and ID without labels, in that order.
    if "type" not in header.rows and others:
        lineno, row = others[0]
        if not any(c.strip() in ASSET_TYPES for c in row):
            raise FormatError(
                path,
                "unlabelled header row names no known asset type "
                f"({', '.join(sorted(ASSET_TYPES))}); expected the Type row",
                line=lineno,
            )
    for role in ("type", "name", "id"):
        if role not in header.rows and others:
            lineno, row = others.pop(0)
            header.rows[role], header.row_lines[role] = row, lineno
    for role, what in (
        ("type", "Type"),
        ("name", "Name"),
        ("component", "Rotation/Position"),
    ):
        if role not in header.rows:
            raise FormatError(
                path, f"missing header row {what!r} above the Frame,Time row", line=axis_line
            )
    n = len(axis)
    header.n_cols = n
    header.rows["axis"], header.row_lines["axis"] = axis, axis_line
    for role, row in header.rows.items():
        extra = [c for c in row[n:] if c.strip()]
        if extra:
            raise FormatError(
                path,
                f"header row has {len(row)} columns but the Frame,Time row has {n}",
                line=header.row_lines[role],
            )
        header.rows[role] = [c.strip() for c in row[:n]] + [""] * max(0, n - len(row))


def _rate(path: Path, keys: Mapping[str, str]) -> tuple[float, float | None]:
    """Export and capture frame rates, Hz (the export rate falls back on the capture rate)."""
    rates: dict[str, float | None] = {}
    for key in ("Export Frame Rate", "Capture Frame Rate"):
        value = keys.get(key, "")
        if not value:
            rates[key] = None
            continue
        try:
            r = float(value)
        except ValueError:
            r = math.nan
        if not math.isfinite(r) or r <= 0:
            raise FormatError(path, f"{key} must be a positive number, got {value!r}", line=1)
        rates[key] = r
    export = rates["Export Frame Rate"] or rates["Capture Frame Rate"]
    if export is None:
        raise FormatError(
            path, "the first line gives neither Export Frame Rate nor Capture Frame Rate", line=1
        )
    return export, rates["Capture Frame Rate"]


def _units_per_metre(path: Path, keys: Mapping[str, str], override: str | None) -> float:
    unit = override if override is not None else keys.get("Length Units", "Meters")
    try:
        return LENGTH_UNITS[unit.strip().lower()]
    except KeyError:
        raise FormatError(
            path,
            f"unknown length unit {unit!r}; expected Meters, Centimeters or Millimeters",
            line=None if override is not None else 1,
            where="length_units option" if override is not None else "Length Units",
        ) from None
