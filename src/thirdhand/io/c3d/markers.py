"""Loading a C3D file's marker trajectories, labels and thirdhand document."""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from thirdhand.arrays import FloatArray
from thirdhand.errors import FormatError
from thirdhand.io.c3d.constants import FORMAT_VERSION, GROUP, MIN_CLUSTER, UNIT_SCALES
from thirdhand.io.c3d.structure import _check_structure
from thirdhand.readlimits import check_json_depth


@dataclass
class _Markers:
    """Marker data of one file, in metres."""

    labels: list[str]
    xyz: FloatArray  # (n_frames, n_markers, 3), NaN where missing
    rate: float
    first_frame: int
    units: str
    doc: dict[str, Any] | None
    truncated: str | None = None


def _oriented(entry: Mapping[str, Any]) -> bool:
    return bool(entry.get("oriented", True))


def _load_markers(p: Path, units: str | None, *, allow_truncated: bool = False) -> _Markers:
    """Validate the file's structure, read it with ezc3d and convert to metres."""
    import ezc3d

    truncated = _check_structure(p, allow_truncated=allow_truncated)
    try:
        c = ezc3d.c3d(str(p))
    except (OSError, RuntimeError, ValueError) as exc:
        raise FormatError(p, f"not a readable C3D file: {exc}") from None
    params = c["parameters"]
    header = c["header"]["points"]
    points = np.asarray(c["data"]["points"], dtype=np.float64)
    if points.ndim != 3 or points.shape[0] < 3:
        raise FormatError(p, f"point data of shape {points.shape}, expected (4, markers, frames)")
    n_frames = points.shape[2]
    announced = int(header["last_frame"]) - int(header["first_frame"]) + 1
    if n_frames < announced and not truncated:
        raise FormatError(
            p,
            f"truncated: the header announces {announced} frames, the file holds {n_frames}",
            where=f"frame {n_frames}",
        )
    if n_frames == 0:
        raise FormatError(p, "the file holds no frame of marker data")
    labels = _point_labels(params)
    if len(labels) != points.shape[1]:
        raise FormatError(
            p,
            f"{len(labels)} point labels for {points.shape[1]} markers",
            where="POINT:LABELS",
        )
    unit = units if units is not None else _param_str(params, "POINT", "UNITS") or "mm"
    scale = UNIT_SCALES.get(unit.strip().lower())
    if scale is None:
        raise FormatError(
            p,
            f"cannot interpret length unit {unit!r}; expected one of "
            f"{', '.join(sorted(UNIT_SCALES))}",
            where="POINT:UNITS",
        )
    rate = float(header["frame_rate"])
    rate_param = params.get("POINT", {}).get("RATE")
    if rate_param is not None and np.size(rate_param["value"]):
        rate = float(np.ravel(rate_param["value"])[0])
    if not np.isfinite(rate) or rate <= 0:
        raise FormatError(
            p, f"point rate must be positive and finite, got {rate}", where="POINT:RATE"
        )
    residuals = np.asarray(c["data"]["meta_points"]["residuals"], dtype=np.float64)
    xyz = points[:3].transpose(2, 1, 0) * scale
    missing = ~np.all(np.isfinite(xyz), axis=2) | np.all(xyz == 0.0, axis=2)
    if residuals.shape == (1, points.shape[1], n_frames):
        missing |= ~(residuals[0].T >= 0.0)
    xyz[missing] = np.nan
    return _Markers(
        labels=labels,
        xyz=xyz,
        rate=rate,
        first_frame=int(header["first_frame"]),
        units=unit.strip(),
        doc=_read_doc(p, params, labels, None if truncated else n_frames),
        truncated=truncated,
    )


def _point_labels(params: Mapping[str, Any]) -> list[str]:
    """``POINT:LABELS`` (and ``LABELS2``...), made unique.

    Unlabelled markers are often stored with blank or repeated labels: a blank
    label becomes ``marker<k>`` (k its 1-based column), the n-th repeat of a
    label ``<label>#<n>``.
    """
    point = params.get("POINT", {})
    raw: list[str] = []
    key, i = "LABELS", 1
    while key in point:
        raw.extend(str(s).strip() for s in point[key]["value"])
        i += 1
        key = f"LABELS{i}"
    labels: list[str] = []
    taken: set[str] = set()
    seen: Counter[str] = Counter()
    for k, lab in enumerate(raw):
        name = lab or f"marker{k + 1}"
        seen[name] += 1
        if name in taken:
            name = f"{name}#{seen[name]}"
        while name in taken:
            name += "'"
        taken.add(name)
        labels.append(name)
    return labels


def _param_str(params: Mapping[str, Any], group: str, name: str) -> str | None:
    entry = params.get(group, {}).get(name)
    if entry is None or not isinstance(entry.get("value"), list) or not entry["value"]:
        return None
    return str(entry["value"][0])


def _read_doc(
    p: Path, params: Mapping[str, Any], labels: Sequence[str], n_frames: int | None
) -> dict[str, Any] | None:
    """The JSON description of a ``THIRDHAND`` group, checked against the file.

    ``n_frames`` None skips the frame count check (a truncated file read on purpose).
    """
    group = params.get(GROUP)
    if group is None:
        return None
    parts: list[str] = []
    key, i = "DOC", 1
    while key in group:
        parts.extend(str(s) for s in group[key]["value"])
        i += 1
        key = f"DOC{i}"
    where = f"{GROUP}:DOC"
    try:
        text = "".join(parts)
        check_json_depth(text, error=lambda m: FormatError(p, m, where=where))
        doc = json.loads(text)
        if doc.get("format") != FORMAT_VERSION:
            raise FormatError(
                p,
                f"unsupported format {doc.get('format')!r}, expected {FORMAT_VERSION!r}",
                where=where,
            )
        known = set(labels)
        for b in doc["bodies"]:
            if not isinstance(b["name"], str) or not all(isinstance(m, str) for m in b["markers"]):
                raise TypeError(f"body entry {b!r} needs a string name and string markers")
            missing = [m for m in b["markers"] if m not in known]
            if missing:
                raise FormatError(
                    p,
                    f"marker(s) {', '.join(missing)} not in POINT:LABELS",
                    where=f"body {b['name']}",
                )
            if _oriented(b):
                off = np.asarray(b["offsets"], dtype=np.float64)
                if off.shape != (len(b["markers"]), 3) or len(b["markers"]) < MIN_CLUSTER:
                    raise FormatError(
                        p,
                        f"expected >= {MIN_CLUSTER} markers with one offset (x y z) each, got "
                        f"{len(b['markers'])} markers and offsets of shape {off.shape}",
                        where=f"body {b['name']}",
                    )
            elif len(b["markers"]) != 1:
                raise FormatError(
                    p, "a position-only body has one marker", where=f"body {b['name']}"
                )
        if n_frames is not None and int(doc["n_frames"]) != n_frames:
            raise FormatError(
                p,
                f"{GROUP} describes {doc['n_frames']} frames, the file holds {n_frames}",
                where=where,
            )
        if not (np.isfinite(float(doc["rate"])) and float(doc["rate"]) > 0):
            raise FormatError(p, f"rate must be positive, got {doc['rate']}", where=where)
        float(doc["t0"])
    except FormatError:
        raise
    except (json.JSONDecodeError, KeyError, TypeError, ValueError, AttributeError) as exc:
        raise FormatError(
            p, f"malformed {GROUP} description: {type(exc).__name__}: {exc}", where=where
        ) from None
    out: dict[str, Any] = doc
    return out
