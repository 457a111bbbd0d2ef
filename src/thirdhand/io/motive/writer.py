"""Writing a demonstration as a Motive 1.23-style CSV export (see :mod:`thirdhand.io.motive`)."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from thirdhand.arrays import FloatArray
from thirdhand.demonstration import BodyInfo, Demonstration, body_info_to_dict, labels_to_dict
from thirdhand.errors import FormatError
from thirdhand.fileops import atomic_output
from thirdhand.io.motive.constants import EXTRA_FORMAT, EXTRA_KEY

_WRITE_VERSION = "1.23"


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
    extra = extra_key(demo)
    if extra is not None:
        first.append((EXTRA_KEY, extra))
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
    with atomic_output(p) as tmp, open(tmp, "wb") as fh:
        fh.write(("\n".join(lines) + "\n").encode("utf-8"))
        pacsv.write_csv(
            table,
            fh,
            write_options=pacsv.WriteOptions(include_header=False, quoting_style="none"),
        )


def extra_key(demo: Demonstration) -> str | None:
    """JSON of what a Motive export cannot state (body kinds, labels, meta), or None if nothing.

    The recording's ``meta`` (part geometry, units, its source) is carried when it
    is JSON without NaN; otherwise it is left out (``convert`` then names it lost).

    Written as the value of the first line's :data:`EXTRA_KEY` key, which
    :func:`~thirdhand.io.motive.read` reads back; Motive and other CSV readers
    skip a key they do not know.
    """
    bodies = [
        body_info_to_dict(b) for b in demo.bodies if b != BodyInfo(b.name, oriented=b.oriented)
    ]
    meta = _json_meta(demo.meta)
    if not bodies and not demo.labels and not meta:
        return None
    doc: dict[str, Any] = {"format": EXTRA_FORMAT, "bodies": bodies}
    if demo.labels:
        doc["labels"] = labels_to_dict(demo.labels)
    if meta:
        doc["meta"] = meta
    return json.dumps(doc, separators=(",", ":"), allow_nan=False, ensure_ascii=True)


def _json_meta(meta: Any) -> dict[str, Any] | None:
    """``meta`` if it is a JSON object without NaN or infinity (it then reads back equal)."""
    if not isinstance(meta, dict) or not meta:
        return None
    try:
        text = json.dumps(meta, allow_nan=False)
    except (TypeError, ValueError):
        return None
    back: dict[str, Any] = json.loads(text)
    return back if back == meta else None


def _q(cell: str) -> str:
    """One CSV cell, quoted when it holds a comma, quote or line break."""
    if any(c in cell for c in ',"\r\n'):
        return '"' + cell.replace('"', '""') + '"'
    return cell
