"""OptiTrack Motive CSV exports: rigid bodies (and labelled markers) in, 1.23-style exports out.

A Motive export (format versions 1.2x, written by Motive 1.10 to 3.x) looks like::

    Format Version,1.23,Take Name,T1,...,Export Frame Rate,120.000000,...,Length Units,Meters,...
    <blank line>
    ,Type,Rigid Body,Rigid Body,...,Marker,...
    ,Name,seat,seat,...,seat:Marker1,...
    ,ID,1,1,...
    ,Parent,...                                  (newer versions only)
    ,,Rotation,Rotation,Rotation,Rotation,Position,Position,Position,Mean Marker Error,...
    Frame,Time (Seconds),X,Y,Z,W,X,Y,Z,,...
    0,0.000000,0.001,...

Rows come and go between versions (format 1.21 has no ``Type``/``Name``/``ID``
labels, some exports add a ``TimeCode`` column after the time), so header rows are
found by their label, or by their content when unlabelled, never by position.
Blank cells mean "not tracked". The numeric block is handed to Arrow's
multi-threaded CSV parser; the header is parsed in Python.

The writer appends one key to the first line, ``Up Axis``, which Motive does not
write; readers that parse the first line by position are not affected.
"""

from __future__ import annotations

import csv
import math
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from thirdhand.demonstration import (
    BODY_KINDS,
    MAX_PLAUSIBLE_POSITION_M,
    BodyInfo,
    BodyKind,
    Demonstration,
)
from thirdhand.errors import FormatError, ThirdhandError

#: Length unit (lower case, as written in the header or abbreviated) -> units per metre.
LENGTH_UNITS: dict[str, float] = {
    "meters": 1.0,
    "metres": 1.0,
    "m": 1.0,
    "centimeters": 100.0,
    "centimetres": 100.0,
    "cm": 100.0,
    "millimeters": 1000.0,
    "millimetres": 1000.0,
    "mm": 1000.0,
}
#: Asset types Motive writes in the ``Type`` row (used to recognise an unlabelled Type row).
ASSET_TYPES = frozenset(
    {
        "Rigid Body",
        "Rigid Body Marker",
        "Marker",
        "Bone",
        "Bone Marker",
        "Skeleton",
        "Trained Markerset",
        "Trained Markerset Marker",
        "Force Plate",
    }
)
_MAGIC = "Format Version"
_LABELS = ("Type", "Name", "ID", "Parent")
_MAX_HEADER_LINES = 64
#: Smallest plausible extent of a capture, metres: every position of every body closer
#: to the origin than this means metres were exported under a mm/cm label.
_MIN_PLAUSIBLE_EXTENT_M = 0.005
_WRITE_VERSION = "1.23"

FloatArray = NDArray[np.float64]


@dataclass
class _Header:
    """What the header lines say; ``rows`` maps a row role to its cells (padded)."""

    keys: dict[str, str]
    rows: dict[str, list[str]] = field(default_factory=dict)
    row_lines: dict[str, int] = field(default_factory=dict)
    n_cols: int = 0
    data_line: int = 0
    data_offset: int = 0


@dataclass
class _BodySpec:
    """Columns of one body: ``quat`` (x y z w) is None for a position-only marker."""

    name: str
    asset: str
    pos: list[int]
    quat: list[int] | None
    ident: str = ""


# ----------------------------------------------------------------------- sniff
def sniff(path: Path) -> bool:
    """A file whose first line starts with ``Format Version,`` (Motive's CSV export)."""
    if not path.is_file():
        return False
    with open(path, "rb") as fh:
        head = fh.read(64)
    return head.removeprefix(b"\xef\xbb\xbf").startswith(_MAGIC.encode() + b",")


# ---------------------------------------------------------------------- header
def _decode(raw: bytes) -> str:
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return raw.decode("cp1252", errors="replace")


def _cells(text: str) -> list[str]:
    return next(csv.reader([text]), [])


def _read_header(path: Path) -> _Header:
    """Parse the key/value line and the header rows up to ``Frame,Time``."""
    with open(path, "rb") as fh:
        first = fh.readline()
        if not first.strip():
            raise FormatError(
                path, "empty file: expected Motive's 'Format Version,...' line", line=1
            )
        text = _decode(first.removeprefix(b"\xef\xbb\xbf")).rstrip("\r\n")
        cells = _cells(text)
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
            row = _cells(_decode(raw).rstrip("\r\n"))
            if not any(c.strip() for c in row):
                continue
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


# ---------------------------------------------------------------------- bodies
def _find_bodies(path: Path, header: _Header, include_markers: bool) -> list[_BodySpec]:
    """Group the columns of rigid bodies (and labelled markers) by asset."""
    rows = header.rows
    types, names, comps, axes = rows["type"], rows["name"], rows["component"], rows["axis"]
    ids = rows.get("id", [""] * header.n_cols)
    wanted = {"Rigid Body"} | ({"Marker"} if include_markers else set())
    found: dict[tuple[str, str], dict[tuple[str, str], int]] = {}
    for j in range(2, header.n_cols):
        asset, name = types[j], names[j]
        if asset not in wanted or (asset == "Marker" and name.startswith("Unlabeled")):
            continue
        if not name:
            raise FormatError(
                path, f"column {j + 1} ({asset}) has no name", line=header.row_lines["name"]
            )
        cols = found.setdefault((asset, name), {})
        key = (comps[j], axes[j])
        if key in cols and comps[j] in ("Position", "Rotation"):
            raise FormatError(
                path,
                f"{comps[j]} {axes[j]} appears twice (columns {cols[key] + 1} and {j + 1})",
                line=header.row_lines["axis"],
                where=f"body {name!r}",
            )
        cols.setdefault(key, j)
    specs: list[_BodySpec] = []
    seen: dict[str, str] = {}
    for (asset, name), cols in found.items():
        if name in seen:
            raise FormatError(
                path,
                f"name used by a {seen[name]} and a {asset}",
                line=header.row_lines["name"],
                where=f"body {name!r}",
            )
        seen[name] = asset
        pos = _columns(path, header, name, cols, "Position", "XYZ")
        quat = None
        if asset == "Rigid Body":
            if ("Rotation", "W") not in cols and ("Rotation", "X") in cols:
                raise FormatError(
                    path,
                    "rotation has no W column (Euler angles?); re-export with Rotation Type "
                    "Quaternion",
                    line=header.row_lines["axis"],
                    where=f"body {name!r}",
                )
            quat = _columns(path, header, name, cols, "Rotation", "XYZW")
        first = min(pos)
        specs.append(_BodySpec(name, asset, pos, quat, ids[first]))
    return specs


def _columns(
    path: Path,
    header: _Header,
    name: str,
    cols: Mapping[tuple[str, str], int],
    comp: str,
    axes: str,
) -> list[int]:
    missing = [a for a in axes if (comp, a) not in cols]
    if missing:
        raise FormatError(
            path,
            f"no {comp} {'/'.join(missing)} column; expected {comp} {' '.join(axes)}",
            line=header.row_lines["component"],
            where=f"body {name!r}",
        )
    return [cols[(comp, a)] for a in axes]


# ------------------------------------------------------------------ data block
def _data_end(path: Path, start: int) -> int:
    """Byte offset just past the last non-blank data line (trailing newlines dropped)."""
    size = path.stat().st_size
    with open(path, "rb") as fh:
        end = size
        while end > start:
            chunk_start = max(start, end - 4096)
            fh.seek(chunk_start)
            chunk = fh.read(end - chunk_start)
            stripped = chunk.rstrip(b"\r\n")
            if stripped:
                return chunk_start + len(stripped)
            end = chunk_start
    return start


def _read_block(path: Path, header: _Header, columns: list[int]) -> dict[int, Any]:
    """Parse the numeric block with Arrow; returns column index -> Arrow array."""
    import pyarrow as pa
    import pyarrow.csv as pacsv

    end = _data_end(path, header.data_offset)
    if end <= header.data_offset:
        raise FormatError(
            path,
            "truncated file: the header is complete but no data row follows",
            line=header.data_line,
        )
    names = [f"c{j}" for j in range(header.n_cols)]
    types = {names[j]: (pa.int64() if j == 0 else pa.float64()) for j in columns}
    with pa.memory_map(str(path)) as mm:
        mm.seek(header.data_offset)
        buf = mm.read_buffer(end - header.data_offset)
        try:
            table = pacsv.read_csv(
                pa.BufferReader(buf),
                read_options=pacsv.ReadOptions(column_names=names, block_size=1 << 22),
                parse_options=pacsv.ParseOptions(ignore_empty_lines=False),
                convert_options=pacsv.ConvertOptions(
                    column_types=types,
                    include_columns=[names[j] for j in columns],
                    null_values=[""],
                    quoted_strings_can_be_null=True,
                ),
            )
        except (pa.ArrowInvalid, pa.ArrowTypeError) as exc:
            raise _diagnose(path, header, columns, end) or FormatError(
                path, f"data block could not be parsed: {exc}"
            ) from None
    return {j: table.column(names[j]) for j in columns}


def _diagnose(path: Path, header: _Header, columns: list[int], end: int) -> FormatError | None:
    """Find the first bad line of a block Arrow rejected (slow; runs only on error)."""
    names = header.rows["axis"]
    with open(path, "rb") as fh:
        fh.seek(header.data_offset)
        lineno = header.data_line - 1
        pos = header.data_offset
        while pos < end:
            raw = fh.readline()
            pos += len(raw)
            lineno += 1
            row = _cells(_decode(raw).rstrip("\r\n"))
            if len(row) != header.n_cols:
                kind = "blank line" if not raw.strip() else f"{len(row)} columns"
                return FormatError(
                    path,
                    f"expected {header.n_cols} columns as in the Frame,Time row "
                    f"(line {header.row_lines['axis']}), got {kind}",
                    line=lineno,
                )
            for j in columns:
                cell = row[j].strip()
                if not cell:
                    continue
                try:
                    int(cell) if j == 0 else float(cell)
                except ValueError:
                    what = "an integer frame number" if j == 0 else "a number"
                    return FormatError(
                        path,
                        f"expected {what} or a blank cell, found {cell!r}",
                        line=lineno,
                        where=f"column {j + 1} {names[j] or '?'}",
                    )
    return None


def _as_float(col: Any) -> FloatArray:
    """Arrow column -> float64 array, NaN where the cell was blank."""
    arr: FloatArray = np.asarray(col.to_numpy(zero_copy_only=False), dtype=np.float64)
    return arr


def _first_null(path: Path, header: _Header, col: Any, what: str) -> None:
    if col.null_count:
        import pyarrow.compute as pc

        i = int(np.flatnonzero(pc.is_null(col).to_numpy(zero_copy_only=False))[0])
        raise FormatError(path, f"blank {what} cell", line=header.data_line + i)


def _time_axis(
    path: Path,
    header: _Header,
    frame: NDArray[np.int64],
    time: FloatArray,
    rates: tuple[float, ...],
) -> FloatArray:
    """Time stamps from the frame numbers and the frame rate, cross-checked with Time.

    Frame numbers count at the export rate (``rates[0]``); the other rates (the
    capture rate) are tried when the Time column contradicts it, as frames of a
    down-sampled export may keep their capture numbers. The Time column of a Motive
    export is rounded to microseconds, so the axis is ``frame / rate``; when the
    Time column agrees with it to within 1 ns it was written at full precision (by
    :func:`write`) and is taken as is.
    """
    line0 = header.data_line
    bad = np.flatnonzero(np.diff(frame) <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        raise FormatError(
            path,
            f"frame numbers must increase: frame {frame[i - 1]} then {frame[i]}",
            line=line0 + i,
        )
    bad = np.flatnonzero(~(np.diff(time) > 0))
    if bad.size or not np.isfinite(time[0]):
        i = int(bad[0]) + 1 if bad.size else 0
        before = f"{float(time[i - 1])!r} s then " if i else ""
        raise FormatError(path, f"time must increase: {before}{float(time[i])!r} s", line=line0 + i)
    first_error = None
    for rate in dict.fromkeys(rates):
        tol = max(0.25 / rate, 2e-6)
        t_frame = frame / rate
        if abs(time[0] - t_frame[0]) > tol:
            # The Time column starts its own clock (e.g. a custom start frame).
            t_frame = (frame - frame[0]) / rate + time[0]
        dev = np.abs(time - t_frame)
        far = np.flatnonzero(dev > tol)
        if not far.size:
            return time if float(dev.max()) <= 1e-9 else t_frame
        if first_error is None:
            i = int(far[0])
            first_error = FormatError(
                path,
                f"Time column says {time[i]:.9g} s but frame {frame[i]} at the export rate "
                f"{rate:g} Hz is {t_frame[i]:.9g} s",
                line=line0 + i,
            )
    assert first_error is not None
    raise first_error


# ------------------------------------------------------------------------ read
def read(
    path: str | os.PathLike[str],
    *,
    include_markers: bool = False,
    kinds: Mapping[str, str] | None = None,
    default_kind: str = "part",
    length_units: str | None = None,
    up_axis: str = "y",
) -> Demonstration:
    """Read a Motive CSV export.

    Parameters
    ----------
    path : path-like
        The ``.csv`` file exported by Motive (format 1.2x).
    include_markers : bool
        Also return every labelled marker (``Marker`` columns whose name does not
        start with ``Unlabeled``) as a position-only body (``oriented=False``).
        Rigid-body marker constraints and unlabelled markers are always skipped.
    kinds : mapping body name -> kind, optional
        Kind of some bodies (``part``, ``tool``, ``finger``, ``hand``, ``head``, ``other``).
    default_kind : str
        Kind of the bodies ``kinds`` does not name.
    length_units : str, optional
        Override the header's ``Length Units`` (``Meters``, ``Centimeters``,
        ``Millimeters`` or ``m``, ``cm``, ``mm``), for a file exported with a wrong label.
    up_axis : {"x", "y", "z"}
        Up axis recorded in ``meta["up_axis"]`` unless the file states one; Motive
        exports are Y-up by default. The data are not rotated.

    Returns
    -------
    Demonstration
        ``t`` in seconds (frame number / export frame rate), positions in metres
        (world frame, as exported), quaternions x y z w, ``valid`` False where cells
        were blank. ``meta`` holds ``source``, ``format``, ``format_version``,
        ``take_name``, ``capture_frame_rate``, ``export_frame_rate``,
        ``length_units``, ``rotation_type``, ``coordinate_space``, ``up_axis``,
        ``motive_ids`` (body -> Motive ID) and ``motive_header`` (every key/value
        pair of the first line).

    Raises
    ------
    FormatError
        Naming the file, the line and the column or body: empty or truncated file,
        missing header rows, unknown length unit, non-numeric cell, wrong column
        count, non-increasing frames or times, zero-norm quaternion, positions
        implausible for the stated unit, no rigid body.
    """
    p = Path(path)
    header = _read_header(p)
    keys = header.keys
    rotation = keys.get("Rotation Type", "Quaternion")
    scale = _units_per_metre(p, keys, length_units)
    rate, capture_rate = _rate(p, keys)
    up = keys.get("Up Axis", up_axis).strip().lower()
    if up not in ("x", "y", "z"):
        raise FormatError(p, f"up axis must be x, y or z, got {up!r}", where="Up Axis")
    kinds = dict(kinds or {})
    for name, kind in [*kinds.items(), ("default_kind", default_kind)]:
        if kind not in BODY_KINDS:
            raise FormatError(
                p,
                f"kind must be one of {', '.join(BODY_KINDS)}, got {kind!r}",
                where=f"kinds option, {name!r}",
            )

    specs = _find_bodies(p, header, include_markers)
    if not specs:
        present = sorted({t for t in header.rows["type"][2:] if t})
        hint = (
            " (markers are present: pass include_markers=True)"
            if "Marker" in present and not include_markers
            else ""
        )
        raise FormatError(
            p,
            f"no rigid body in the file; asset types found: {', '.join(present) or 'none'}" + hint,
            line=header.row_lines["type"],
        )
    unknown = sorted(set(kinds) - {s.name for s in specs})
    if unknown:
        raise FormatError(
            p,
            f"kinds names bodies not in the file: {', '.join(unknown)}; bodies are "
            f"{', '.join(s.name for s in specs)}",
            where="kinds option",
        )

    columns = sorted({0, 1} | {j for s in specs for j in (*s.pos, *(s.quat or []))})
    block = _read_block(p, header, columns)
    _first_null(p, header, block[0], "Frame")
    _first_null(p, header, block[1], "Time")
    frame = np.asarray(block[0].to_numpy(zero_copy_only=False), dtype=np.int64)
    rates = (rate,) if capture_rate is None else (rate, capture_rate)
    t = _time_axis(p, header, frame, _as_float(block[1]), rates)

    bodies, pos, quat, valid = [], {}, {}, {}
    extent = 0.0
    for s in specs:
        pr, qr, v, reach = _body_arrays(p, header, s, block, scale)
        extent = max(extent, reach)
        kind = cast(BodyKind, kinds.get(s.name, default_kind))
        bodies.append(BodyInfo(s.name, kind, oriented=s.quat is not None))
        pos[s.name], quat[s.name], valid[s.name] = pr, qr, v
    if scale != 1.0 and 0.0 < extent < _MIN_PLAUSIBLE_EXTENT_M:
        raise FormatError(
            p,
            f"every position lies within {extent * 1000:.3g} mm of the origin: the values "
            f"look like metres under a {'mm' if scale == 1000 else 'cm'} label; pass "
            "length_units='m'",
            line=1,
            where="Length Units",
        )

    meta: dict[str, Any] = {
        "source": str(p),
        "format": "motive",
        "format_version": keys[_MAGIC],
        "take_name": keys.get("Take Name", ""),
        "capture_frame_rate": capture_rate,
        "export_frame_rate": rate,
        "length_units": length_units
        if length_units is not None
        else keys.get("Length Units", "Meters"),
        "rotation_type": rotation,
        "coordinate_space": keys.get("Coordinate Space", ""),
        "up_axis": up,
        "motive_ids": {s.name: s.ident for s in specs},
        "motive_header": dict(keys),
    }
    if "Capture Start Time" in keys:
        meta["capture_start_time"] = keys["Capture Start Time"]
    try:
        return Demonstration(t, bodies, pos, quat, valid, meta=meta)
    except ThirdhandError as exc:
        raise FormatError(p, str(exc)) from None


def _body_arrays(
    path: Path, header: _Header, spec: _BodySpec, block: Mapping[int, Any], scale: float
) -> tuple[FloatArray, FloatArray, NDArray[np.bool_], float]:
    """One body's arrays, checked column by column (1-D passes are the fast ones).

    Returns
    -------
    pos : ndarray, shape (n_frames, 3), metres, world frame; NaN where blank
    quat : ndarray, shape (n_frames, 4), x y z w; NaN for a position-only marker
    valid : ndarray of bool, shape (n_frames,): every cell of the body present
    reach : float
        Largest absolute coordinate over the valid frames, metres (0 if none).
    """
    pcols = [_as_float(block[j]) for j in spec.pos]
    qcols = [_as_float(block[j]) for j in spec.quat] if spec.quat is not None else []
    valid = np.isfinite(pcols[0])
    for c in (*pcols[1:], *qcols):
        valid &= np.isfinite(c)
    where = f"body {spec.name!r}"
    if qcols:
        sq = qcols[0] * qcols[0] + qcols[1] * qcols[1] + qcols[2] * qcols[2] + qcols[3] * qcols[3]
        zero = np.flatnonzero(valid & (sq < 1e-18))
        if zero.size:
            i = int(zero[0])
            found = tuple(float(c[i]) for c in qcols)
            raise FormatError(
                path, f"zero-norm quaternion {found}", line=header.data_line + i, where=where
            )
    if scale != 1.0:
        pcols = [c / scale for c in pcols]
    mag = np.maximum(np.maximum(np.abs(pcols[0]), np.abs(pcols[1])), np.abs(pcols[2]))
    far = np.flatnonzero(valid & (mag > MAX_PLAUSIBLE_POSITION_M))
    if far.size:
        i = int(far[0])
        hint = "; are these millimetres? pass length_units='mm'" if scale == 1.0 else ""
        raise FormatError(
            path,
            f"position {mag[i] * scale:.6g} in the file's length unit is {mag[i]:.6g} m from "
            f"the origin, beyond the plausible {MAX_PLAUSIBLE_POSITION_M:g} m{hint}",
            line=header.data_line + i,
            where=where,
        )
    reach = float(mag[valid].max()) if valid.any() else 0.0
    pos = np.column_stack(pcols)
    n = pos.shape[0]
    quat = np.column_stack(qcols) if qcols else np.full((n, 4), np.nan)
    return pos, quat, valid, reach


# ----------------------------------------------------------------------- write
def _snap_rate(rate: float) -> tuple[float, str]:
    """The rate as Motive writes it (six decimals) when that is within 1e-9 of it."""
    s = f"{rate:.6f}"
    return (float(s), s) if abs(float(s) - rate) <= 1e-9 * rate else (rate, repr(rate))


def _frame_numbers(path: Path, t: FloatArray, rate: float) -> NDArray[np.int64]:
    """Frame numbers on the ``rate`` grid; the time axis must sit on it."""
    frame0 = round(float(t[0]) * rate)
    frames = frame0 + np.rint((t - t[0]) * rate).astype(np.int64)
    dev = np.abs((frames - frame0) / rate + t[0] - t)
    bad = np.flatnonzero(dev > 0.1 / rate)
    if bad.size or np.any(np.diff(frames) <= 0):
        i = int(bad[0]) if bad.size else int(np.flatnonzero(np.diff(frames) <= 0)[0]) + 1
        raise FormatError(
            path,
            f"a Motive CSV needs a regular time axis: frame {i} at {t[i]:.9g} s is off the "
            f"{rate:g} Hz grid; resample the demonstration first",
            where=f"frame {i}",
        )
    return frames


def write(
    demo: Demonstration,
    path: str | os.PathLike[str],
    *,
    take_name: str | None = None,
    rate: float | None = None,
) -> None:
    """Write ``demo`` as a Motive 1.23-style CSV export (atomically: temp file, then rename).

    Oriented bodies become rigid bodies (Rotation X Y Z W, Position X Y Z),
    position-only bodies become markers (Position X Y Z). Units are metres,
    invalid frames are blank cells, numbers are written in their shortest exact
    form so that :func:`read` gives back bit-identical ``t``, ``pos``, ``quat``,
    ``valid`` and names (markers need ``include_markers=True``). ``meta["up_axis"]``
    (default ``y``) is recorded as an ``Up Axis`` key; the data are not rotated.

    Parameters
    ----------
    demo : Demonstration
        Its time axis must be regular (frames on a ``rate`` grid, to within a tenth
        of a frame; stamps off the grid by more than 1 ns read back on the grid).
    path : path-like
        Destination ``.csv`` file.
    take_name : str, optional
        Defaults to ``demo.meta["take_name"]`` or the file's stem.
    rate : float, optional
        Export frame rate, Hz; defaults to ``demo.meta["export_frame_rate"]`` or the
        demonstration's nominal rate.
    """
    import pyarrow as pa
    import pyarrow.csv as pacsv

    p = Path(path)
    if not len(demo):
        raise FormatError(p, "the demonstration has no body to write")
    for name in demo.body_names:
        if name != name.strip() or any(c in name for c in "\r\n"):
            raise FormatError(
                p,
                "body names written to a Motive CSV cannot hold line breaks or start or end "
                "with white space",
                where=f"body {name!r}",
            )
    if rate is None:
        rate = demo.meta.get("export_frame_rate") or (demo.rate if demo.n_frames > 1 else 120.0)
    rate = float(rate)
    if not math.isfinite(rate) or rate <= 0:
        raise FormatError(p, f"export rate must be a positive number of Hz, got {rate}")
    rate, rate_s = _snap_rate(rate)
    frames = _frame_numbers(p, demo.t, rate)
    up = str(demo.meta.get("up_axis", "y")).upper()
    first = [
        ("Format Version", _WRITE_VERSION),
        ("Take Name", take_name or str(demo.meta.get("take_name") or p.stem)),
        ("Take Notes", ""),
        ("Capture Frame Rate", rate_s),
        ("Export Frame Rate", rate_s),
        ("Capture Start Time", str(demo.meta.get("capture_start_time", ""))),
        ("Capture Start Frame", str(int(frames[0]))),
        ("Total Frames in Take", str(demo.n_frames)),
        ("Total Exported Frames", str(demo.n_frames)),
        ("Rotation Type", "Quaternion"),
        ("Length Units", "Meters"),
        ("Coordinate Space", "Global"),
        ("Up Axis", up),
    ]
    types, names, ids, comps, axes = (
        ["", "Type"],
        ["", "Name"],
        ["", "ID"],
        ["", ""],
        ["Frame", "Time (Seconds)"],
    )
    arrays: dict[str, Any] = {
        "f": pa.array(frames, pa.int64()),
        "t": pa.array(demo.t, pa.float64()),
    }
    for k, info in enumerate(demo.bodies, start=1):
        tr = demo.track(info.name)
        mask = ~tr.valid
        layout = [("Position", tr.pos, "XYZ")]
        if info.oriented:
            layout.insert(0, ("Rotation", tr.quat, "XYZW"))
        asset = "Rigid Body" if info.oriented else "Marker"
        for comp, arr, letters in layout:
            for j, a in enumerate(letters):
                types.append(asset)
                names.append(info.name)
                ids.append(str(k))
                comps.append(comp)
                axes.append(a)
                col = np.ascontiguousarray(arr[:, j])
                arrays[f"b{k}{comp[0]}{a}"] = pa.array(col, pa.float64(), mask=mask)
    lines = [",".join(f"{k},{v}" for k, v in [(_q(a), _q(b)) for a, b in first]), ""]
    lines += [",".join(_q(c) for c in row) for row in (types, names, ids, comps, axes)]
    table = pa.table(arrays)
    tmp = p.with_name(f".{p.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "wb") as fh:
            fh.write(("\n".join(lines) + "\n").encode("utf-8"))
            pacsv.write_csv(
                table,
                fh,
                write_options=pacsv.WriteOptions(include_header=False, quoting_style="none"),
            )
        os.replace(tmp, p)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def _q(cell: str) -> str:
    """One CSV cell, quoted when it holds a comma, quote or line break."""
    if any(c in cell for c in ',"\r\n'):
        return '"' + cell.replace('"', '""') + '"'
    return cell


__all__ = ["ASSET_TYPES", "LENGTH_UNITS", "read", "sniff", "write"]
