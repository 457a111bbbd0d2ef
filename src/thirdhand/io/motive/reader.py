"""Reading a Motive CSV export (see :mod:`thirdhand.io.motive`)."""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from thirdhand.arrays import FloatArray
from thirdhand.demonstration import (
    BODY_KINDS,
    MAX_PLAUSIBLE_POSITION_M,
    MAX_QUAT_NORM_ERROR,
    BodyInfo,
    BodyKind,
    Demonstration,
    Labels,
    body_info_from_dict,
    labels_from_dict,
)
from thirdhand.errors import FormatError, ThirdhandError
from thirdhand.io.motive.block import _as_float, _first_null, _read_block, _time_axis
from thirdhand.io.motive.columns import _BodySpec, _find_bodies
from thirdhand.io.motive.constants import _MAGIC, EXTRA_FORMAT, EXTRA_KEY
from thirdhand.io.motive.header import _Header, _rate, _read_header, _units_per_metre
from thirdhand.readlimits import loads_json, read_text_input

#: Smallest plausible extent of a capture, metres: every position of every body closer
#: to the origin than this means metres were exported under a mm/cm label.
_MIN_PLAUSIBLE_EXTENT_M = 0.005


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
    t = _time_axis(p, header, frame, _as_float(block[1]), rates, full_precision=EXTRA_KEY in keys)

    stated, labels, carried = _extra(p, keys, specs)
    bodies, pos, quat, valid = [], {}, {}, {}
    extent = 0.0
    for s in specs:
        pr, qr, v, reach = _body_arrays(p, header, s, block, scale)
        extent = max(extent, reach)
        if s.name in kinds or s.name not in stated:
            kind = cast(BodyKind, kinds.get(s.name, default_kind))
            bodies.append(BodyInfo(s.name, kind, oriented=s.quat is not None))
        else:
            bodies.append(stated[s.name])
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
        "motive_header": {k: v for k, v in keys.items() if k != EXTRA_KEY},
    }
    if "Capture Start Time" in keys:
        meta["capture_start_time"] = keys["Capture Start Time"]
    meta.update(carried)  # the meta of the recording thirdhand wrote, as it was
    try:
        return Demonstration(t, bodies, pos, quat, valid, labels=labels, meta=meta)
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
    where = f"body {spec.name!r}"
    # Blank cells (NaN) mean "not tracked"; an infinite cell is corrupt, as in every reader.
    for j, c in zip((*spec.pos, *(spec.quat or [])), (*pcols, *qcols), strict=True):
        inf = np.flatnonzero(np.isinf(c))
        if inf.size:
            i = int(inf[0])
            raise FormatError(
                path,
                f"cell is not finite: {float(c[i])!r} (a blank cell marks an untracked frame)",
                line=header.data_line + i,
                where=f"{where}, column {j + 1}",
            )
    valid = np.isfinite(pcols[0])
    for c in (*pcols[1:], *qcols):
        valid &= np.isfinite(c)
    if qcols:
        with np.errstate(over="ignore", invalid="ignore"):  # a huge cell is reported below
            sq = qcols[0] * qcols[0] + qcols[1] * qcols[1] + qcols[2] * qcols[2]
            sq += qcols[3] * qcols[3]
        zero = np.flatnonzero(valid & (sq < 1e-18))
        if zero.size:
            i = int(zero[0])
            found = tuple(float(c[i]) for c in qcols)
            raise FormatError(
                path, f"zero-norm quaternion {found}", line=header.data_line + i, where=where
            )
        with np.errstate(invalid="ignore", over="ignore"):
            off = np.flatnonzero(valid & ~(np.abs(np.sqrt(sq) - 1.0) <= MAX_QUAT_NORM_ERROR))
        if off.size:
            i = int(off[0])
            found = tuple(float(c[i]) for c in qcols)
            raise FormatError(
                path,
                f"quaternion {found} has norm {float(np.sqrt(sq[i])):.6g}; expected a unit "
                f"quaternion (norm within {MAX_QUAT_NORM_ERROR:g} of 1)",
                line=header.data_line + i,
                where=where,
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


def sidecar_path(path: Path) -> Path:
    """``rec.csv`` -> ``rec.thirdhand.json``: body kinds (and labels) of a real Motive export.

    The document is the one thirdhand writes in the first line's ``thirdhand`` key::

        {"format": "thirdhand.motive-extra/1",
         "bodies": [{"name": "rh_index", "kind": "finger", "hand": "right"}]}
    """
    return path.with_name(path.stem + ".thirdhand.json")


def _extra(
    path: Path, keys: Mapping[str, str], specs: Sequence[Any]
) -> tuple[dict[str, BodyInfo], Labels, dict[str, Any]]:
    """Body metadata, labels and meta stated in the first line's ``thirdhand`` key, or a sidecar.

    A real Motive export states no body kinds; the same JSON document in a file
    ``<stem>.thirdhand.json`` beside the CSV (:func:`sidecar_path`) states them.
    The key wins over the sidecar.
    """
    raw = keys.get(EXTRA_KEY)
    source: Path = path
    line: int | None = 1
    if raw is None:
        side = sidecar_path(path)
        if not side.is_file():
            return {}, Labels(), {}
        source, line = side, None
        raw = read_text_input(side, what="body-kinds sidecar")

    def error(message: str) -> FormatError:
        where = f"{EXTRA_KEY!r} key" if source == path else None
        return FormatError(source, message, line=line, where=where)

    doc = loads_json(raw, error=error)
    if not isinstance(doc, dict) or doc.get("format") != EXTRA_FORMAT:
        raise error(f"expected a JSON object of format {EXTRA_FORMAT!r}")
    oriented = {s.name: s.quat is not None for s in specs}
    stated: dict[str, BodyInfo] = {}
    try:
        for d in doc.get("bodies", []):
            info = body_info_from_dict(d)
            if info.name not in oriented:
                raise error(f"names body {info.name!r}, which the file does not hold")
            if info.oriented != oriented[info.name]:
                raise error(f"body {info.name!r}: orientation stated and columns disagree")
            stated[info.name] = info
        labels = labels_from_dict(doc.get("labels", {}))
    except ThirdhandError as exc:
        if isinstance(exc, FormatError):
            raise
        raise error(str(exc)) from None
    carried = doc.get("meta", {})
    if not isinstance(carried, dict):
        raise error("'meta': expected a JSON object")
    return stated, labels, carried
