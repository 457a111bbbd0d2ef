"""Byte-level checks of a C3D file's header, parameter records and data extent."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from thirdhand.errors import FormatError
from thirdhand.io.c3d.constants import _MAGIC, _PROCESSORS, MAX_FRAMES
from thirdhand.readlimits import open_input


def sniff(path: Path) -> bool:
    """A file ending in ``.c3d``, or whose header and parameter section look like C3D's."""
    if not path.is_file():
        return False
    if path.suffix.lower() == ".c3d":
        return True
    from thirdhand.readlimits import sniff_bytes

    head = sniff_bytes(path, 2)
    if len(head) < 2 or head[1] != _MAGIC or head[0] < 2:
        return False
    proc = sniff_bytes(path, 1, offset=(head[0] - 1) * 512 + 3)
    return len(proc) == 1 and proc[0] in _PROCESSORS


def _check_structure(p: Path, *, allow_truncated: bool = False) -> str | None:
    """Check the header and parameter section before handing the file to ezc3d.

    ezc3d trusts the sizes stored in the file; a damaged parameter record can
    make it read out of bounds, so every record's extent is checked here. A
    file shorter than its announced frames is reported as truncated (ezc3d would
    silently read the complete frames): raised, or with ``allow_truncated``
    returned as a message.
    """
    try:
        size = p.stat().st_size
        with open_input(p, what="C3D file") as fh:
            head = fh.read(512)
            if len(head) < 2 or head[1] != _MAGIC or head[0] < 2:
                raise FormatError(
                    p,
                    "empty file"
                    if not head
                    else "not a C3D file: no 0x50 key in byte 2 of the header",
                    where="header",
                )
            if len(head) < 512:
                raise FormatError(p, f"truncated: a C3D header has 512 bytes, the file {len(head)}")
            start = (head[0] - 1) * 512
            fh.seek(start)
            section = fh.read(255 * 512)
    except OSError as exc:
        raise FormatError(p, f"cannot read: {exc}") from None
    if len(section) < 4:
        raise FormatError(p, f"truncated: no parameter section at byte {start}", where="parameters")
    proc = section[3]
    if proc not in _PROCESSORS:
        raise FormatError(
            p, f"unknown processor type {proc}, expected 84, 85 or 86", where="parameters"
        )
    end = section[2] * 512
    if end == 0 or end > len(section):
        raise FormatError(
            p,
            f"truncated: a parameter section of {section[2]} blocks, "
            f"the file holds {len(section) // 512}",
            where="parameters",
        )
    point_frames = _check_parameter_records(p, section[:end], proc)
    try:
        _check_data_extent(p, head, proc, size, point_frames)
    except FormatError as exc:
        if allow_truncated and exc.message.startswith("truncated"):
            return exc.message
        raise
    return None


def _check_parameter_records(p: Path, sec: bytes, proc: int) -> int | None:
    """Walk the parameter records, checking every extent; return ``POINT:FRAMES`` if set."""
    endian = _PROCESSORS[proc]
    groups: dict[int, str] = {}
    frames: list[tuple[int, int, int]] = []  # (group id, type, byte of the value)
    pos, end = 4, len(sec)
    while True:
        if pos + 2 > end:
            raise FormatError(
                p, f"parameter record at byte {pos} runs past the section", where="parameters"
            )
        nlen, gid = struct.unpack_from("bb", sec, pos)
        if nlen == 0:
            break
        name_end = pos + 2 + abs(nlen)
        if name_end + 2 > end or gid == 0:
            raise FormatError(p, f"malformed parameter record at byte {pos}", where="parameters")
        name = sec[pos + 2 : name_end].decode("latin-1").upper()
        (offset,) = struct.unpack_from(endian + "H", sec, name_end)
        rec = name_end + 2
        if gid > 0:
            if rec + 2 > end:
                raise FormatError(
                    p, "parameter record runs past the section", where=f"parameter {name}"
                )
            ptype, ndim = struct.unpack_from("bB", sec, rec)
            if ptype not in (-1, 1, 2, 4) or ndim > 7 or rec + 2 + ndim > end:
                raise FormatError(
                    p, f"bad type {ptype} or dimension count {ndim}", where=f"parameter {name}"
                )
            dims = sec[rec + 2 : rec + 2 + ndim]
            if name == "FRAMES" and ptype > 0:
                frames.append((gid, ptype, rec + 2 + ndim))
            rec += 2 + ndim + abs(ptype) * int(np.prod(list(dims), dtype=np.int64))
        else:
            groups[-gid] = name
        where = f"{'parameter' if gid > 0 else 'group'} {name}"
        if rec >= end or rec + 1 + sec[rec] > end:
            raise FormatError(p, "record runs past the parameter section", where=where)
        if sec[rec] > 127:  # ezc3d reads this length as a signed byte and then crashes
            raise FormatError(p, f"description length {sec[rec]} > 127", where=where)
        if offset == 0:
            break
        nxt = name_end + offset
        if nxt <= pos or nxt > end:
            raise FormatError(p, f"record points to byte {nxt} outside the section", where=name)
        pos = nxt
    for gid, ptype, at in frames:
        if groups.get(gid) != "POINT" or (ptype == 4 and proc == 85):
            continue
        fmt = {1: "B", 2: "H", 4: "f"}[ptype]
        (value,) = struct.unpack_from(endian + fmt, sec, at)
        return int(value) if np.isfinite(value) and value > 0 else None
    return None


def _check_data_extent(
    p: Path, head: bytes, proc: int, size: int, point_frames: int | None
) -> None:
    """The file holds the frames announced (``POINT:FRAMES`` over the header, as ezc3d)."""
    endian = _PROCESSORS[proc]
    n_points, n_analog, first, last = struct.unpack_from(endian + "4H", head, 2)
    (data_start,) = struct.unpack_from(endian + "H", head, 16)
    if proc != 85:  # DEC floats: left to ezc3d
        (rate,) = struct.unpack_from(endian + "f", head, 20)
        if not np.isfinite(rate) or rate < 0:
            raise FormatError(
                p, f"frame rate must be positive and finite, got {rate}", where="header"
            )
    sign_byte = {84: 15, 85: 13, 86: 12}[proc]
    word = 4 if head[sign_byte] & 0x80 else 2  # negative scale factor: float data
    # ezc3d: a first frame of 0 means both numbers are 0-based, else both are 1-based.
    n_frames = point_frames or max(last + 1 if first == 0 else last - first + 1, 0)
    per_frame = word * (4 * n_points + n_analog)
    data_at = (max(data_start, 1) - 1) * 512
    if n_frames and per_frame and data_at + per_frame > size:
        raise FormatError(p, f"truncated: no data at byte {data_at}", where="frame 0")
    needed = data_at + n_frames * per_frame
    if size < needed:
        complete = max((size - data_at) // per_frame, 0) if per_frame else 0
        raise FormatError(
            p,
            f"truncated: the file announces {n_frames} frames ({needed} bytes), but has "
            f"{size} bytes",
            where=f"frame {complete}",
        )
    extra = (size - needed - 512) // per_frame if per_frame else 0
    if last >= MAX_FRAMES and extra > 0:
        raise FormatError(
            p,
            f"holds about {n_frames + extra} frames, more than the {MAX_FRAMES} a C3D header "
            "(and ezc3d) can index; split the recording",
            where=f"frame {MAX_FRAMES}",
        )
