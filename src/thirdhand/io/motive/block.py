"""The numeric block of a Motive export: parsing, diagnosing bad rows, the time axis."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from thirdhand.arrays import FloatArray
from thirdhand.errors import FormatError
from thirdhand.io.motive.header import _cells, _decode, _Header


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
    _check_complete(path, header, table.num_rows, end)
    return {j: table.column(names[j]) for j in columns}


def _check_complete(path: Path, header: _Header, n_rows: int, end: int) -> None:
    """Refuse a file cut short: no final line break, or fewer rows than the header states.

    A cut inside the last cell would otherwise load a shortened number.
    """
    with open(path, "rb") as fh:
        fh.seek(max(end, 0))
        tail = fh.read(2)
    if not tail.startswith((b"\n", b"\r")):
        raise FormatError(
            path,
            "the file ends inside a line (no final line break): it looks cut short, "
            "and the last row may hold a shortened number",
            line=header.data_line + n_rows - 1,
        )
    stated = header.keys.get("Total Exported Frames", "").strip()
    if stated.isdigit() and int(stated) > 0 and int(stated) != n_rows:
        raise FormatError(
            path,
            f"the header states {int(stated)} exported frames (Total Exported Frames), "
            f"the data block holds {n_rows} rows",
            line=header.data_line + min(n_rows, int(stated)),
        )


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
            row = _cells(_decode(raw).rstrip("\r\n"), path, lineno)
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
    *,
    full_precision: bool = False,
) -> FloatArray:
    """Time stamps from the frame numbers and the frame rate, cross-checked with Time.

    ``full_precision``: the file states it was written by thirdhand (its
    ``thirdhand`` key), whose Time column holds every time stamp exactly; it is
    taken as is once it agrees with the frame numbers.

    Frame numbers count at the export rate (``rates[0]``); the other rates (the
    capture rate) are tried when the Time column contradicts it, as frames of a
    down-sampled export may keep their capture numbers. The Time column of a Motive
    export is rounded to microseconds, so the axis is ``frame / rate``; when the
    Time column agrees with it to within 10 ns it was written at full precision (by
    :func:`write`; a clock of whole nanoseconds, as MCAP's, stays within that) and is
    taken as is.
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
    steps = np.diff(frame)
    uneven = np.flatnonzero(steps != steps[0]) if steps.size else steps
    if uneven.size:
        # Motive numbers every exported frame (every k-th when down-sampled): a
        # changing step is a row lost or pasted in, which would load as a gap.
        i = int(uneven[0]) + 1
        raise FormatError(
            path,
            f"frame numbers step by {steps[0]} up to frame {frame[i - 1]}, then by "
            f"{steps[i - 1]} to frame {frame[i]}: a row is missing or extra",
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
            # Full precision (written by :func:`write`) on the grid, or on the grid
            # started at the first time stamp (a recording whose clock is not a
            # whole number of frames from zero).
            shifted = (frame - frame[0]) / rate + time[0]
            if (
                full_precision
                or float(dev.max()) <= 1e-8
                or float(np.abs(time - shifted).max()) <= 1e-8
            ):
                return time
            return t_frame
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
