"""Writing a demonstration as a C3D file (see :mod:`thirdhand.io.c3d`)."""

from __future__ import annotations

import errno
import os
import struct
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from thirdhand import jsontext
from thirdhand.arrays import FloatArray
from thirdhand.demonstration import Demonstration, body_info_to_dict, labels_to_dict
from thirdhand.errors import FormatError, ThirdhandError
from thirdhand.fileops import atomic_output
from thirdhand.io.c3d.clusters import _layout, markers_from_demonstration
from thirdhand.io.c3d.constants import FORMAT_VERSION, GROUP, MAX_FRAMES

_CHUNK = 200  # characters per string of the JSON document (C3D strings hold <= 255)
_CHUNKS_PER_PARAM = 120  # keeps every parameter record well under 32 kB


def write(
    demo: Demonstration,
    path: str | os.PathLike[str],
    *,
    clusters: Mapping[str, ArrayLike] | None = None,
    rate: float | None = None,
) -> None:
    """Write ``demo`` as a C3D file of marker clusters (atomically).

    Parameters
    ----------
    demo : Demonstration
        Its time axis must be regular (resample it first otherwise).
    path : path-like
    clusters : mapping body name -> array_like, shape (m, 3), metres, body frame, optional
        Marker offsets of oriented bodies; default :func:`default_cluster`.
    rate : float, optional
        Frame rate, Hz; default from the time axis (100 Hz for a single frame).

    Raises
    ------
    FormatError
        For an irregular time axis, too many frames, no body, or a bad cluster.
    """
    import ezc3d

    p = Path(path)
    n = demo.n_frames
    if n > MAX_FRAMES:
        raise FormatError(
            p, f"C3D (ezc3d) holds at most {MAX_FRAMES} frames, got {n}; split with demo.slice"
        )
    if not len(demo):
        raise FormatError(p, "the demonstration has no body to write")
    t0, hz = _regular_axis(p, demo.t, rate)
    try:
        labels, offsets = _layout(demo, clusters)
        _, xyz = markers_from_demonstration(demo, offsets)
    except ThirdhandError as exc:
        raise FormatError(p, str(exc)) from None
    m = len(labels)
    points = np.ones((4, m, n))
    points[:3] = xyz.transpose(2, 1, 0) * 1000.0
    seen = np.all(np.isfinite(xyz), axis=2).T
    residuals = np.where(seen, 0.0, -1.0)[None]
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = np.array([hz])
    c["parameters"]["POINT"]["LABELS"]["value"] = list(labels)
    c["header"]["points"]["first_frame"] = int(np.clip(round(t0 * hz), 0, MAX_FRAMES - n))
    c["data"]["points"] = points
    c["data"]["meta_points"] = {
        "residuals": residuals,
        "camera_masks": np.zeros((7, m, n), dtype=bool),
    }
    c.add_parameter("POINT", "UNITS", ["mm"])
    c.add_parameter(GROUP, "FORMAT", [FORMAT_VERSION])
    try:
        params = _doc_params(_document(demo, labels, offsets, t0, hz))
    except (TypeError, ValueError) as exc:
        raise FormatError(p, f"demo.meta cannot be stored as JSON: {exc}") from None
    for key, chunk in params.items():
        c.add_parameter(GROUP, key, chunk)
    with atomic_output(p, verify=lambda tmp: _check_written(tmp, m, n)) as tmp:
        try:
            c.write(str(tmp))
        except (RuntimeError, ValueError, TypeError) as exc:
            raise FormatError(p, f"could not write: {exc}") from None


def _check_written(tmp: Path, n_points: int, n_frames: int) -> None:
    """Check the written file holds every frame: ezc3d does not report a short write.

    The size the header implies, ``(DATA_START - 1) * 512`` bytes before the
    data plus ``frames * (4 * points + analog) * word`` bytes of data, must all
    be there. The header is parsed here, not by ezc3d, which crashes on a cut file.
    """
    size = tmp.stat().st_size
    with open(tmp, "rb") as fh:
        head = fh.read(24)
    if len(head) < 24:
        raise OSError(errno.EFBIG, f"only {size} bytes were written")
    points, analog, first, last = struct.unpack("<HHHH", head[2:10])
    (scale,) = struct.unpack("<f", head[12:16])
    (data_start,) = struct.unpack("<H", head[16:18])
    frames = last - first + 1
    word = 4 if scale < 0 else 2
    expected = (data_start - 1) * 512 + frames * (4 * points + analog) * word
    if points != n_points or frames != n_frames or size < expected:
        raise OSError(
            errno.EFBIG,
            f"the written file is short: {size} of {expected} bytes "
            f"({frames} frames of {points} markers, expected {n_frames} of {n_points})",
        )


def _regular_axis(p: Path, t: FloatArray, rate: float | None) -> tuple[float, float]:
    n = t.size
    if rate is not None:
        hz = float(rate)
    elif n > 1:
        hz = (n - 1) / float(t[-1] - t[0])
    else:
        hz = 100.0
    if not np.isfinite(hz) or hz <= 0:
        raise FormatError(p, f"frame rate must be positive and finite, got {hz}")
    t0 = float(t[0])
    dev = np.abs(t - (t0 + np.arange(n) / hz))
    worst = int(np.argmax(dev))
    if dev[worst] > 1e-3 / hz:
        raise FormatError(
            p,
            f"C3D needs a regular time axis: {t[worst]:.9g} s is {dev[worst]:.3g} s off the "
            f"{hz:.6g} Hz grid; resample the demonstration first",
            where=f"frame {worst}",
        )
    return t0, hz


def _document(
    demo: Demonstration,
    labels: Sequence[str],
    offsets: Mapping[str, FloatArray],
    t0: float,
    hz: float,
) -> dict[str, Any]:
    bodies = []
    k = 0
    for info in demo.bodies:
        entry = body_info_to_dict(info)
        off = offsets.get(info.name)
        m = 1 if off is None else off.shape[0]
        entry["markers"] = list(labels[k : k + m])
        if off is not None:
            entry["offsets"] = off.tolist()
        bodies.append(entry)
        k += m
    return {
        "format": FORMAT_VERSION,
        "t0": t0,
        "rate": hz,
        "n_frames": demo.n_frames,
        "bodies": bodies,
        "labels": labels_to_dict(demo.labels),
        "meta": demo.meta,
    }


def _plain(obj: Any) -> Any:
    """numpy scalars and arrays in ``meta`` as plain JSON values."""
    if isinstance(obj, np.generic | np.ndarray):
        return obj.tolist()
    raise TypeError(f"{type(obj).__name__} is not JSON serialisable")


def _doc_params(doc: Mapping[str, Any]) -> dict[str, list[str]]:
    """The JSON document as C3D string parameters ``DOC``, ``DOC2``...

    C3D strings are at most 255 characters and readers strip trailing blanks,
    so the compact ASCII JSON has its spaces (only ever inside strings) escaped.
    """
    text = jsontext.dumps(
        doc, what="the recording's header", ensure_ascii=True, separators=(",", ":"), default=_plain
    )
    text = text.replace(" ", "\\u0020")
    chunks = [text[i : i + _CHUNK] for i in range(0, len(text), _CHUNK)]
    out: dict[str, list[str]] = {}
    for j in range(0, len(chunks), _CHUNKS_PER_PARAM):
        key = "DOC" if j == 0 else f"DOC{j // _CHUNKS_PER_PARAM + 1}"
        out[key] = chunks[j : j + _CHUNKS_PER_PARAM]
    return out
