"""Articulated-object tracks of Sturm, Stachniss & Burgard (``tum-vision/articulation``).

One pose per line: ``x y z`` (metres), optionally a quaternion ``qx qy qz qw``,
optionally the tracked rectangle's ``width height`` (metres)::

    -0.243697 0.170726 1.951928 0.948742 -0.009130 0.138290 -0.284045 0.500000 0.560000

Every line of a file has the same number of columns (3, 7 or 9); blank lines are
skipped. A file holds a single body, named after the file stem; a position-only
file gives a ``BodyInfo(oriented=False)`` body. ``width``/``height`` go to
``meta["width"]``/``meta["height"]`` (one value per frame).

The files carry no time: sample ``i`` is at ``i / rate`` seconds. The original
tools replay them at an arbitrary pace, so without ``rate`` the reader assumes
:data:`DEFAULT_RATE_HZ` (10 Hz: the PR2 logs ``cabinet_one``/``drawer_one`` then
move the handle at 5-8 cm/s, a plausible slow opening) and records it in
``meta["rate_hz"]`` with ``meta["rate_assumed"] = True``.

Frames where the body was not tracked are written as ``nan`` rows and read back
as invalid.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from thirdhand.demonstration import (
    MAX_PLAUSIBLE_POSITION_M,
    MAX_QUAT_NORM_ERROR,
    BodyInfo,
    Demonstration,
)
from thirdhand.errors import FormatError, ThirdhandError
from thirdhand.fileops import write_text
from thirdhand.io.mlr import parse_numeric_rows
from thirdhand.readlimits import MAX_RECORDING_BYTES, read_input

#: Sampling rate assumed when the caller gives none, Hz.
DEFAULT_RATE_HZ = 10.0
COLUMNS = (3, 7, 9)
_SUFFIXES = (".txt", ".log")


def sniff(path: Path) -> bool:
    """A ``.txt``/``.log`` file whose first non-blank line holds 3, 7 or 9 numbers."""
    if not path.is_file() or path.suffix.lower() not in _SUFFIXES:
        return False
    from thirdhand.readlimits import sniff_bytes

    head = sniff_bytes(path, 4096)
    for line in head.splitlines():
        cells = line.split()
        if not cells:
            continue
        try:
            [float(c) for c in cells]
        except ValueError:
            return False
        return len(cells) in COLUMNS
    return False


def read(path: str | os.PathLike[str], *, rate: float | None = None) -> Demonstration:
    """Read an articulation track file.

    Parameters
    ----------
    path : path-like
    rate : float, optional
        Sampling rate, Hz; defaults to :data:`DEFAULT_RATE_HZ` (noted in ``meta``).

    Returns
    -------
    Demonstration
        One body named after the file stem: positions (metres, camera frame),
        quaternions x y z w (identity for a position-only file), valid where the row
        is finite. ``meta``: ``format``, ``source``, ``rate_hz``, ``rate_assumed``,
        and ``width``/``height`` lists (metres) for 9-column files.

    Raises
    ------
    FormatError
        Empty file, a non-numeric cell, a line with another number of columns, a
        zero-norm quaternion, positions that look like millimetres. Naming the line.
    """
    p = Path(path)
    hz = DEFAULT_RATE_HZ if rate is None else float(rate)
    if not np.isfinite(hz) or hz <= 0:
        raise FormatError(p, f"rate must be a positive number of Hz, got {rate}")
    raw = read_input(p, what="articulation track", limit=MAX_RECORDING_BYTES)
    rows = parse_numeric_rows(raw, p, n_cols=COLUMNS)
    vals = rows.values
    valid: np.ndarray = np.asarray(np.isfinite(vals[:, :3]).all(axis=1))
    _check(vals, valid, rows.lines, p)
    n = vals.shape[0]
    oriented = vals.shape[1] >= 7
    quat = vals[:, 3:7] if oriented else np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
    body = BodyInfo(p.stem, "part", oriented=oriented)
    meta: dict[str, object] = {
        "format": "articulation",
        "source": str(p),
        "rate_hz": hz,
        "rate_assumed": rate is None,
    }
    if vals.shape[1] == 9:
        meta["width"] = vals[:, 7].tolist()
        meta["height"] = vals[:, 8].tolist()
    try:
        return Demonstration(
            np.arange(n) / hz,
            [body],
            {body.name: vals[:, :3]},
            {body.name: quat},
            {body.name: valid},
            meta=meta,
        )
    except ThirdhandError as exc:
        raise FormatError(p, str(exc)) from None


def _check_carried(demo: Demonstration, p: Path) -> None:
    """Refuse what an articulation file would not give back (time, name, kind, labels)."""
    lost = "; choose a format that keeps it (.parquet, .csv)"
    info = demo.bodies[0]
    if info.name != p.stem:
        raise FormatError(
            p, f"stores no body name: body {info.name!r} would read back as {p.stem!r}" + lost
        )
    if info != BodyInfo(p.stem, "part", oriented=info.oriented):
        raise FormatError(
            p, f"stores no body kind: {info.name!r} ({info.kind}) would read back as a part" + lost
        )
    expected = np.arange(demo.n_frames) / DEFAULT_RATE_HZ
    if not np.allclose(demo.t, expected, rtol=0, atol=1e-9):
        raise FormatError(
            p,
            f"stores no time: it reads back at {DEFAULT_RATE_HZ:g} Hz from 0 s, the recording "
            f"runs at {demo.rate:.6g} Hz from {demo.t[0]:.6g} s" + lost,
        )
    if demo.labels:
        raise FormatError(p, "stores no labels" + lost)


def _check(vals: np.ndarray, valid: np.ndarray, lines: np.ndarray, path: Path) -> None:
    def fail(mask: np.ndarray, message: str) -> None:
        hit = np.flatnonzero(mask)
        if hit.size:
            raise FormatError(path, message, line=int(lines[hit[0]]), where=f"frame {hit[0]}")

    n_pose = 7 if vals.shape[1] >= 7 else 3
    finite = np.isfinite(vals[:, :n_pose])
    fail(valid & ~finite.all(axis=1), "position is finite but orientation is not")
    fail(~valid & finite.any(axis=1), "a row must be all numbers or all nan (not tracked)")
    if n_pose == 7:
        with np.errstate(over="ignore", invalid="ignore"):  # a huge cell fails below
            norm = np.linalg.norm(np.nan_to_num(vals[:, 3:7]), axis=1)
        fail(valid & (norm < 1e-9), "zero-norm quaternion")
        fail(
            valid & ~(np.abs(norm - 1.0) <= MAX_QUAT_NORM_ERROR),
            f"quaternion norm is not within {MAX_QUAT_NORM_ERROR:g} of 1 (not a unit quaternion)",
        )
    far = np.abs(np.nan_to_num(vals[:, :3])).max(axis=1) > MAX_PLAUSIBLE_POSITION_M
    fail(
        far,
        f"position beyond {MAX_PLAUSIBLE_POSITION_M:g} m from the origin: expected metres, "
        "are these millimetres?",
    )


def write(demo: Demonstration, path: str | os.PathLike[str]) -> None:
    """Write a single-body demonstration as an articulation track file (atomically).

    Columns: ``x y z`` for a position-only body, else ``x y z qx qy qz qw``, plus
    ``width height`` when ``meta`` holds one value of each per frame. Numbers use
    ``%.17g`` so that :func:`read` gives them back exactly; invalid frames are
    ``nan`` rows. The time axis is not stored: :func:`read` gives ``i / rate``.

    The format stores neither time, body name, kind nor labels, so a recording is
    written only when :func:`read` gives it back as it is: one body named like
    the file's stem, of kind ``part``, sampled at :data:`DEFAULT_RATE_HZ` from
    0 s, without labels. Anything else is refused (one line saying what would be
    lost), never written with it dropped.

    Raises
    ------
    FormatError
        The demonstration does not hold exactly one body, or holds what the format
        cannot carry.
    """
    p = Path(path)
    if len(demo) != 1:
        raise FormatError(
            p,
            f"an articulation file holds one body, the demonstration has {len(demo)}: "
            "select one with demo.select([...])",
        )
    _check_carried(demo, p)
    tr = demo.track(demo.body_names[0])
    cols = [tr.pos] if not tr.info.oriented else [tr.pos, tr.quat]
    width, height = demo.meta.get("width"), demo.meta.get("height")
    if (
        tr.info.oriented
        and isinstance(width, list | tuple)
        and isinstance(height, list | tuple)
        and len(width) == len(height) == demo.n_frames
    ):
        cols.append(np.column_stack([width, height]).astype(np.float64))
    table = np.column_stack(cols)
    table[~tr.valid, : 7 if tr.info.oriented else 3] = np.nan
    row = " ".join(["%.17g"] * table.shape[1]) + "\n"
    text = (row * table.shape[0]) % tuple(table.ravel().tolist())
    write_text(p, text)


__all__ = ["COLUMNS", "DEFAULT_RATE_HZ", "read", "sniff", "write"]
