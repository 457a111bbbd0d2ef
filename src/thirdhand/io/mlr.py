"""The 3rdHand / MLR recording folder: ``poses.dat``, ``poses.dat.times``, ``meta.kvg``.

Layout of a folder (Polhemus G4 recordings of the MLR group, TU Berlin):

- ``poses.dat``: one ``[ ... ]`` block per frame, one line per sensor row, seven
  numbers per row: position ``x y z`` (metres) then a unit quaternion **w x y z**.
  A row of zeros is a sensor that was not seen in that frame. So is a row whose
  position lies within :data:`SOURCE_CLEARANCE_M` of the origin: the G4 reports a
  sensor it has not yet acquired at its source (``toolbox_coop_4``: 329 rows in
  frames 153–221, 0.2 mm from the origin, quaternion → (0.5, 0.5, 0.5, 0.5), a
  60-cm jump from the neighbouring frames), and a sensor cannot sit inside the
  source's housing; every other row of the shared recordings is ≥ 8 cm away.
  The samples next to such reports and those before a frame reset are dropped
  too (:func:`acquisition_validity`; counts and reset times in ``meta["mlr"]``).
  These repair rules apply to the G4's own files only: a ``meta.kvg`` that
  starts with thirdhand's mark ``writer = "thirdhand"`` (every folder
  :func:`write` makes) is read as written, so a Motive recording converted to
  this format keeps a body that passes the origin.
- ``poses.dat.times``: ``frame_number timestamp_s`` per line, one line per block
  (frame numbers count from 1; timestamps are seconds on the recorder's clock).
- ``meta.kvg``: sections (``agents``, ``objects``) mapping body names to their
  sensor row: ``/human/rh/thumb = { type = digit, rn = 0, hid = 0, sid = 0 }``.
  ``hid``/``sid`` (G4 hub and sensor) are kept in ``meta`` and written back.
- optional labels: ``ann_kvg.kvg`` (frames; see :mod:`thirdhand.io.kvg`) or, when
  there is none, ``elan.eaf`` (media time; see :mod:`thirdhand.io.elan`).

Body kinds come from the name and ``type``: ``type = digit`` under
``/human/<x>h/`` is a finger of hand ``/human/<x>h`` (``lh`` left, ``rh`` right,
any other, e.g. the cooperating person's ``th``, ``"other"``); ``/human/<x>h``
itself or ``type = hand`` a hand; ``head`` a head; ``screwdriver``, ``tool``,
``hammer``, ... or a ``/tool(s)/`` path a tool; any other entry of ``objects`` a
part, of ``agents`` ``"other"``. Sensor rows that no body names are skipped. An
entry may state ``kind``, ``hand``, ``hand_body``, ``person`` or ``oriented``
explicitly; thirdhand writes these keys only where the rules above would not
recover the body's metadata, so files of the original shape stay so.

Hand labels (``TS /human/rh ...``) name no tracked body: they stand for every
tracked finger of that hand (one interval per finger), unless a body of that very
name exists; a label naming neither raises :class:`~thirdhand.errors.FormatError`.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from thirdhand.demonstration import (
    MAX_PLAUSIBLE_POSITION_M,
    MAX_QUAT_NORM_ERROR,
    BodyInfo,
    Demonstration,
    HandSide,
    Labels,
    labels_from_dict,
    labels_to_dict,
)
from thirdhand.errors import FormatError, ThirdhandError
from thirdhand.fileops import atomic_output
from thirdhand.io import elan, kvg
from thirdhand.readlimits import MAX_RECORDING_BYTES, read_input

POSES = "poses.dat"
TIMES = "poses.dat.times"
META = "meta.kvg"
ANNOTATIONS = "ann_kvg.kvg"
#: What the 3rdHand files cannot state, as thirdhand wrote it: the recording's meta
#: and its labels at their exact times (``ann_kvg.kvg`` holds them on frames).
EXTRA = "thirdhand.json"
EXTRA_FORMAT = "thirdhand.mlr-extra/1"
#: Meta keys :func:`read` sets to describe the folder read (the tracker's repair of it).
_FOLDER_KEYS = frozenset({"format", "source", "labels_source", "mlr"})
ELAN = "elan.eaf"

#: The top-level ``meta.kvg`` entry thirdhand writes (``writer = "thirdhand"``).
#: A folder without it is a Polhemus G4 recording of the MLR group, the only
#: source of this format, and gets the G4 repair (:func:`acquisition_validity`);
#: a folder with it holds data thirdhand wrote (already repaired, or from another
#: tracker) and is read as written.
WRITER_KEY = "writer"
WRITER_MARK = "thirdhand"
#: A seen row closer than this to the tracker origin (metres) is a sensor the G4
#: has not acquired (it reports the source's own position), not a measurement.
SOURCE_CLEARANCE_M = 0.01
#: Samples of a sensor this close in time (s) to its report at the source are the
#: G4's filter moving between the source and the true pose (``toolbox_coop_4``:
#: 48 → 59 → 62 → 63 cm over 46 ms after acquisition, 7.7 cm from the source
#: 8 ms before a dropout), not measurements.
SETTLE_S = 0.1
#: Reports at the source closer than this (s) belong to one acquisition episode.
EPISODE_GAP_S = 1.0
#: Median jump (m) of the sensors' positions across an episode in which most of
#: them were at the source, above which the tracker's frame changed there.
FRAME_CHANGE_M = 0.05


def acquisition_validity(
    t: NDArray[np.float64], pos: NDArray[np.float64], seen: NDArray[np.bool_]
) -> tuple[NDArray[np.bool_], list[float]]:
    """Which samples of a G4 recording are measurements, and where its frame was reset.

    Parameters
    ----------
    t : ndarray, shape (n_frames,), seconds
    pos : ndarray, shape (n_frames, n_sensors, 3), metres, tracker frame
    seen : ndarray of bool, shape (n_frames, n_sensors)
        Rows that are not all zero.

    Returns
    -------
    valid : ndarray of bool, shape (n_frames, n_sensors)
        ``seen`` without the reports at the source (:data:`SOURCE_CLEARANCE_M`),
        the samples within :data:`SETTLE_S` of them, and every sample before a
        frame reset.
    resets : list of float
        Times (s) after which the tracker's frame differs from the one before: an
        acquisition episode in which at least half of the sensors were reported at
        the source and across which their positions jump by a median of more than
        :data:`FRAME_CHANGE_M` (``toolbox_coop_4``: at 1.6–2.2 s every sensor went
        to the source and came back 33–69 cm away, mirrored; the first 1.6 s are in
        another frame than the remaining 62 s).
    """
    near = seen & (np.linalg.norm(pos, axis=2) < SOURCE_CLEARANCE_M)
    valid = seen & ~near
    if not near.any():
        return valid, []
    n_sensors = seen.shape[1]
    for k in range(n_sensors):
        # Time to the nearest report at the source (infinite when there is none).
        tn = np.concatenate(([-np.inf], t[near[:, k]], [np.inf]))
        i = np.searchsorted(tn, t)
        valid[:, k] &= np.minimum(t - tn[i - 1], tn[i] - t) > SETTLE_S
    frames = np.flatnonzero(near.any(axis=1))
    cuts = np.flatnonzero(np.diff(t[frames]) > EPISODE_GAP_S) + 1
    resets: list[float] = []
    for episode in np.split(frames, cuts):
        lo, hi = int(episode[0]), int(episode[-1])
        if 2 * int(near[lo : hi + 1].any(axis=0).sum()) < n_sensors:
            continue
        jumps = []
        for k in range(n_sensors):
            before = np.flatnonzero(valid[:lo, k])
            after = np.flatnonzero(valid[hi + 1 :, k])
            if before.size and after.size:
                jumps.append(np.linalg.norm(pos[hi + 1 + after[0], k] - pos[before[-1], k]))
        if jumps and float(np.median(jumps)) > FRAME_CHANGE_M:
            resets.append(float(t[hi]) + SETTLE_S)
    if resets:
        valid[t <= resets[-1]] = False
    return valid, resets


_TOOL_WORDS = frozenset(
    {"tool", "screwdriver", "hammer", "wrench", "spanner", "drill", "pliers", "allen_key"}
)
_HAND = re.compile(r"^/human/([a-z]*h)$")
_EXPLICIT = ("kind", "hand", "hand_body", "person", "oriented")
_NONE = "none"  # an explicit key's value for None (a finger-like name with no hand)
_SPACE = np.zeros(256, dtype=bool)
_SPACE[[9, 10, 11, 12, 13, 32]] = True
_BRACKETS_TO_SPACE = bytes.maketrans(b"[]", b"  ")


# ------------------------------------------------------------ numeric text
@dataclass(frozen=True)
class NumericRows:
    """Rows of numbers parsed from text.

    Attributes
    ----------
    values : ndarray, shape (n_rows, n_cols)
    lines : ndarray of int, shape (n_rows,)
        1-based line of each row.
    block : ndarray of int, shape (n_rows,)
        0-based ``[ ... ]`` block of each row (all 0 without blocks).
    block_lines : ndarray of int, shape (n_blocks,)
        Line of each block's ``[``.
    """

    values: NDArray[np.float64]
    lines: NDArray[np.int64]
    block: NDArray[np.int64]
    block_lines: NDArray[np.int64]


def parse_numeric_rows(
    raw: bytes, path: Path, *, n_cols: Sequence[int], blocks: bool = False
) -> NumericRows:
    """Parse whitespace-separated numbers, one row per line (vectorised).

    With ``blocks``, rows are grouped in ``[ ... ]`` blocks (brackets also end a row)
    and every block must hold the same number of rows.

    Parameters
    ----------
    raw : bytes
        The file's content.
    path : Path
        Named in errors.
    n_cols : sequence of int
        Allowed numbers per row; every row must have as many as the first.
    blocks : bool

    Raises
    ------
    FormatError
        Empty file, unbalanced or nested brackets, numbers outside a block, a row
        with another number of cells, a block with another number of rows, a cell
        that is not a number. Naming the line.
    """
    buf = np.frombuffer(raw, dtype=np.uint8)
    newlines = np.flatnonzero(buf == 10)
    space = _SPACE[buf]
    if blocks:
        opens, closes = np.flatnonzero(buf == 91), np.flatnonzero(buf == 93)
        space |= (buf == 91) | (buf == 93)
        seps = np.sort(np.concatenate((newlines, opens, closes)))
    else:
        opens = closes = np.zeros(0, dtype=np.intp)
        seps = newlines
    starts = np.flatnonzero(~space & np.concatenate(([True], space[:-1])))

    def line_at(pos: NDArray[np.intp]) -> NDArray[np.int64]:
        return (np.searchsorted(newlines, pos, side="right") + 1).astype(np.int64)

    if starts.size == 0:
        raise FormatError(path, "empty file: expected rows of numbers")
    block_lines = line_at(opens)
    if blocks:
        _check_brackets(opens, closes, starts, line_at, path)
    tseg = np.searchsorted(seps, starts)
    first_tok = np.flatnonzero(np.concatenate(([True], tseg[1:] != tseg[:-1])))
    counts = np.diff(np.append(first_tok, starts.size))
    lines = line_at(starts[first_tok])
    width = int(counts[0])
    if width not in n_cols:
        want = " or ".join(str(c) for c in n_cols)
        raise FormatError(path, f"expected {want} numbers per row, got {width}", line=int(lines[0]))
    bad = np.flatnonzero(counts != width)
    if bad.size:
        raise FormatError(
            path,
            f"expected {width} numbers per row (as on line {lines[0]}), got {counts[bad[0]]}",
            line=int(lines[bad[0]]),
        )
    if blocks:
        block = (np.searchsorted(opens, starts[first_tok]) - 1).astype(np.int64)
        per_block = np.bincount(block, minlength=opens.size)
        off = np.flatnonzero(per_block != per_block[0])
        if off.size:
            k = int(off[0])
            raise FormatError(
                path,
                f"expected {per_block[0]} sensor rows per block (as in frame 0), got "
                f"{per_block[k]}",
                line=int(block_lines[k]),
                where=f"frame {k}",
            )
    else:
        block = np.zeros_like(lines)
    tokens = (raw.translate(_BRACKETS_TO_SPACE) if blocks else raw).split()
    values = _to_floats(tokens, line_at(starts), path)
    return NumericRows(values.reshape(-1, width), lines, block, block_lines)


def _check_brackets(
    opens: NDArray[np.intp],
    closes: NDArray[np.intp],
    starts: NDArray[np.intp],
    line_at: Callable[[NDArray[np.intp]], NDArray[np.int64]],
    path: Path,
) -> None:
    """Blocks must alternate ``[`` ``]`` and hold every number."""
    pos = np.concatenate((opens, closes))
    order = np.argsort(pos, kind="stable")
    depth = np.cumsum(np.concatenate((np.ones(opens.size), -np.ones(closes.size)))[order])
    if depth.size:
        neg = np.flatnonzero(depth < 0)
        if neg.size:
            at = pos[order[neg[:1]]]
            raise FormatError(path, "']' without a matching '['", line=int(line_at(at)[0]))
        nested = np.flatnonzero(depth > 1)
        if nested.size:
            at = pos[order[nested[:1]]]
            raise FormatError(
                path, "'[' inside an unclosed block: a ']' is missing", line=int(line_at(at)[0])
            )
        if depth[-1] != 0:
            raise FormatError(
                path,
                f"block of frame {opens.size - 1} opened here is never closed (truncated file?)",
                line=int(line_at(opens[-1:])[0]),
            )
    blk = np.searchsorted(opens, starts) - 1
    if closes.size:
        outside = (blk < 0) | (closes[np.maximum(blk, 0)] < starts)
    else:
        outside = np.ones(starts.size, dtype=bool)
    hit = np.flatnonzero(outside)
    if hit.size:
        raise FormatError(
            path, "numbers outside a '[ ... ]' block", line=int(line_at(starts[hit[:1]])[0])
        )


def _to_floats(tokens: list[bytes], lines: NDArray[np.int64], path: Path) -> NDArray[np.float64]:
    try:
        return np.array(tokens).astype(np.float64)
    except ValueError:
        for k, tok in enumerate(tokens):
            try:
                float(tok)
            except ValueError:
                raise FormatError(
                    path,
                    f"cell {tok.decode(errors='replace')!r} is not a number",
                    line=int(lines[k]),
                ) from None
        raise


# ---------------------------------------------------------------- meta.kvg
@dataclass(frozen=True)
class Sensor:
    """One body entry of ``meta.kvg``."""

    name: str
    section: str
    row: int
    fields: dict[str, Any]
    line: int


def _read_meta(path: Path) -> tuple[list[Sensor], bool]:
    """The sensor entries, and whether thirdhand wrote the file (its ``writer`` mark)."""
    graph = kvg.read(path)
    mark = graph.find(WRITER_KEY)
    ours = mark is not None and mark.value == WRITER_MARK
    sensors: list[Sensor] = []
    for section in graph:
        if not isinstance(section.value, kvg.Graph) or len(section.keys) != 1:
            continue
        for entry in section.value:
            if len(entry.keys) != 1 or not isinstance(entry.value, kvg.Graph):
                raise FormatError(
                    path,
                    f"expected '<body name> = {{ type = ..., rn = <row> }}', got "
                    f"{' '.join(entry.keys) or repr(entry.value)}",
                    line=entry.line,
                )
            fields = entry.value.to_dict()
            row = fields.pop("rn", None)
            if not isinstance(row, int) or isinstance(row, bool) or row < 0:
                raise FormatError(
                    path,
                    f"body {entry.keys[0]!r}: expected a sensor row rn = <integer >= 0>, "
                    f"got {row!r}",
                    line=entry.line,
                )
            sensors.append(Sensor(entry.keys[0], section.keys[0], row, fields, entry.line))
    if not sensors:
        raise FormatError(path, "no body entry: expected sections like 'objects { ... }'")
    seen: dict[object, Sensor] = {}
    for s in sensors:
        for key in (("name", s.name), ("row", s.row)):
            if key in seen:
                raise FormatError(
                    path,
                    f"{key[0]} {key[1]!r} appears twice (also on line {seen[key].line})",
                    line=s.line,
                )
            seen[key] = s
    return sensors, ours


def derive_body(name: str, section: str, type_: str) -> BodyInfo:
    """Body metadata implied by a ``meta.kvg`` entry's name, section and ``type``."""
    parts = [p for p in name.split("/") if p]
    last = parts[-1].lower() if parts else name.lower()
    t = type_.lower()
    hand_body = name.rsplit("/", 1)[0] if "/" in name else ""
    hand_m = _HAND.match(hand_body)
    if t in ("digit", "finger") or (hand_m is not None and section == "agents"):
        side = _side(hand_m.group(1) if hand_m else "")
        return BodyInfo(name, "finger", side, hand_body or None)
    own = _HAND.match(name)
    if t == "hand" or own is not None:
        return BodyInfo(name, "hand", _side(own.group(1) if own else ""))
    if "head" in (t, last):
        return BodyInfo(name, "head")
    if t in _TOOL_WORDS or last in _TOOL_WORDS or (parts and parts[0] in ("tool", "tools")):
        return BodyInfo(name, "tool")
    return BodyInfo(name, "other" if section == "agents" else "part")


def _side(token: str) -> HandSide:
    return "left" if token == "lh" else "right" if token == "rh" else "other"


def _body_info(s: Sensor, path: Path) -> BodyInfo:
    base = derive_body(s.name, s.section, str(s.fields.get("type", "")))
    explicit = {k: s.fields[k] for k in _EXPLICIT if k in s.fields}
    if not explicit:
        return base

    def text(key: str) -> Any:
        v = explicit.get(key, getattr(base, key))
        return None if v is None or v == _NONE else str(v)

    try:
        return BodyInfo(
            name=s.name,
            kind=text("kind"),
            hand=text("hand"),
            hand_body=text("hand_body"),
            person=text("person"),
            oriented=explicit.get("oriented", base.oriented) is not False,
        )
    except ThirdhandError as exc:
        raise FormatError(path, str(exc), line=s.line) from None


# -------------------------------------------------------------------- read
def sniff(path: Path) -> bool:
    """A folder holding ``poses.dat``, or a file named ``poses.dat``."""
    if path.is_dir():
        return (path / POSES).is_file()
    return path.name == POSES and path.is_file()


def _read_bytes(path: Path) -> bytes:
    if not os.path.lexists(path):
        raise FormatError(path, f"missing: an MLR recording folder needs {path.name}")
    return read_input(path, what=f"{path.name} file", limit=MAX_RECORDING_BYTES)


def _read_times(path: Path, n_frames: int) -> tuple[NDArray[np.float64], int]:
    rows = parse_numeric_rows(_read_bytes(path), path, n_cols=(2,))
    if rows.values.shape[0] != n_frames:
        raise FormatError(
            path,
            f"{rows.values.shape[0]} time stamps for the {n_frames} frames of {POSES}",
            line=int(rows.lines[-1]),
        )
    t = rows.values[:, 1]
    bad = np.flatnonzero(~np.isfinite(rows.values).all(axis=1))
    if bad.size:
        raise FormatError(path, "time stamp is not finite", line=int(rows.lines[bad[0]]))
    dec = np.flatnonzero(np.diff(t) <= 0)
    if dec.size:
        i = int(dec[0]) + 1
        raise FormatError(
            path,
            f"time stamps must increase: {t[i]:.17g} s after {t[i - 1]:.17g} s",
            line=int(rows.lines[i]),
        )
    return t, int(rows.values[0, 0])


def _check_rows(
    vals: NDArray[np.float64], rows: NumericRows, sensors: Sequence[Sensor], path: Path
) -> None:
    """Value checks on the rows of named sensors; ``vals`` has shape (n_frames, n_rows, 7)."""
    n_rows = vals.shape[1]
    used = np.array([s.row for s in sensors])
    sub = vals[:, used]
    seen = np.any(sub != 0, axis=2)

    def fail(mask: Any, message: str) -> None:
        hit = np.argwhere(mask)
        if hit.size:
            f, k = (int(x) for x in hit[0])
            line = int(rows.lines[f * n_rows + used[k]])
            raise FormatError(
                path,
                message.format(v=sub[f, k]),
                line=line,
                where=f"frame {f}, sensor row {used[k]} = {sensors[k].name}",
            )

    fail(~np.isfinite(sub).all(axis=2), "cell is not finite: {v}")
    with np.errstate(over="ignore", invalid="ignore"):  # a huge cell fails the check below
        norm = np.linalg.norm(sub[..., 3:], axis=2)
    fail(seen & (norm < 1e-9), "zero-norm quaternion in a seen sensor row: {v}")
    fail(
        seen & ~(np.abs(norm - 1.0) <= MAX_QUAT_NORM_ERROR),
        f"quaternion norm is not within {MAX_QUAT_NORM_ERROR:g} of 1 in a seen sensor row "
        "(w x y z expected a unit quaternion): {v}",
    )
    fail(
        seen & (np.abs(sub[..., :3]).max(axis=2) > MAX_PLAUSIBLE_POSITION_M),
        f"position beyond {MAX_PLAUSIBLE_POSITION_M:g} m from the origin ({{v}}): expected "
        "metres, are these millimetres?",
    )


def read(
    path: str | os.PathLike[str], *, labels: bool = True, elan_offset: float | None = None
) -> Demonstration:
    """Read an MLR recording folder.

    Parameters
    ----------
    path : path-like
        The folder (or its ``poses.dat``).
    labels : bool
        Attach ``ann_kvg.kvg`` (or, failing it, ``elan.eaf``) when present.
    elan_offset : float, optional
        Recording time of ELAN's media time 0, seconds; defaults to the first frame's
        time stamp (the video is assumed to start with the motion capture).

    Returns
    -------
    Demonstration
        Time stamps of ``poses.dat.times``; per named sensor row, positions (metres,
        tracker frame), quaternions x y z w, validity (rows not all zero, and not
        dropped by :func:`acquisition_validity`). ``meta``
        holds ``format``, ``source``, ``labels_source`` and, under ``"mlr"``, the
        sensor entries (section, row, ``type``, ``hid``, ``sid`` ...) for :func:`write`.

    Raises
    ------
    FormatError
        Naming the file and the line (frame, sensor) of the problem.
    """
    folder = Path(path)
    if folder.name == POSES and folder.is_file():
        folder = folder.parent
    if not folder.is_dir():
        raise FormatError(folder, f"no such folder (expected a folder holding {POSES})")
    if not (folder / META).is_file():
        raise FormatError(folder / META, "missing: it maps sensor rows to body names")
    sensors, ours = _read_meta(folder / META)
    poses_path = folder / POSES
    rows = parse_numeric_rows(_read_bytes(poses_path), poses_path, n_cols=(7,), blocks=True)
    n_frames = rows.block_lines.size
    vals = rows.values.reshape(n_frames, -1, 7)
    n_rows = vals.shape[1]
    for s in sensors:
        if s.row >= n_rows:
            raise FormatError(
                folder / META,
                f"body {s.name!r}: rn = {s.row} but {POSES} has {n_rows} sensor rows "
                f"(0..{n_rows - 1})",
                line=s.line,
            )
    _check_rows(vals, rows, sensors, poses_path)
    t, first_number = _read_times(folder / TIMES, n_frames)
    bodies = [_body_info(s, folder / META) for s in sensors]
    pos, quat, valid = {}, {}, {}
    used = vals[:, [s.row for s in sensors]]
    seen = np.any(used != 0, axis=2)
    # The G4's artefacts are repaired in the G4's own files only: a folder thirdhand
    # wrote holds data already repaired, or another tracker's (a body may pass
    # within a centimetre of a Motive origin).
    ok, resets = (seen, []) if ours else acquisition_validity(t, used[..., :3], seen)
    for k, (s, b) in enumerate(zip(sensors, bodies, strict=True)):
        block = vals[:, s.row]
        pos[b.name] = block[:, :3]
        quat[b.name] = block[:, [4, 5, 6, 3]]
        valid[b.name] = ok[:, k]
    lab, source = _read_labels(folder, t, bodies, elan_offset) if labels else (Labels(), None)
    lab, carried = _read_extra(folder, lab, source)
    meta = {
        "format": "mlr",
        "source": str(folder),
        "labels_source": source,
        "mlr": {
            "n_rows": n_rows,
            "first_frame_number": first_number,
            "polhemus_repair": not ours,
            "dropped_samples": int(np.count_nonzero(seen & ~ok)),
            "frame_resets_s": resets,
            "sensors": {
                s.name: {"section": s.section, "rn": s.row, **_jsonable(s.fields)} for s in sensors
            },
        },
    }
    meta.update(carried)  # the meta of the recording thirdhand wrote, as it was
    try:
        return Demonstration(t, bodies, pos, quat, valid, labels=lab, meta=meta)
    except ThirdhandError as exc:
        raise FormatError(folder, str(exc)) from None


def _sha256(text: str) -> str:
    import hashlib

    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _extra_text(demo: Demonstration, annotations: str | None) -> str | None:
    """:data:`EXTRA`: the meta (when it is JSON) and exact labels, tied to ``ann_kvg.kvg``."""
    import json

    doc: dict[str, Any] = {"format": EXTRA_FORMAT}
    # The keys the reader sets to describe the folder it reads are not carried.
    meta = {k: v for k, v in (demo.meta or {}).items() if k not in _FOLDER_KEYS}
    try:
        text = json.dumps(meta, allow_nan=False)
        if meta and json.loads(text) == meta:
            doc["meta"] = meta
    except (TypeError, ValueError):
        pass
    if annotations is not None:
        doc["labels"] = labels_to_dict(demo.labels)
        doc["annotations_sha256"] = _sha256(annotations)
    if len(doc) == 1:
        return None
    return json.dumps(doc, indent=1, allow_nan=False) + "\n"


def _read_extra(folder: Path, labels: Labels, source: str | None) -> tuple[Labels, dict[str, Any]]:
    """The exact labels and the meta of :data:`EXTRA`, when present.

    Its labels replace those of ``ann_kvg.kvg`` only while that file is the one
    thirdhand wrote beside them (same SHA-256): labels edited by hand win.
    """
    path = folder / EXTRA
    if not os.path.lexists(path):
        return labels, {}
    from thirdhand.readlimits import MAX_DOCUMENT_BYTES, loads_json

    def error(message: str) -> FormatError:
        return FormatError(path, message)

    doc = loads_json(
        read_input(path, what="thirdhand MLR extra", limit=MAX_DOCUMENT_BYTES, error=error),
        error=error,
    )
    if not isinstance(doc, dict) or doc.get("format") != EXTRA_FORMAT:
        raise error(f"expected a JSON object of format {EXTRA_FORMAT!r}")
    meta = doc.get("meta", {})
    if not isinstance(meta, dict):
        raise error("'meta': expected a JSON object")
    if "labels" in doc and source == ANNOTATIONS:
        written = _read_bytes(folder / ANNOTATIONS).decode("utf-8", "replace")
        if _sha256(written) == doc.get("annotations_sha256"):
            try:
                labels = labels_from_dict(doc["labels"])
            except ThirdhandError as exc:
                raise error(f"'labels': {exc}") from None
    return labels, meta


def _jsonable(fields: Mapping[str, Any]) -> dict[str, Any]:
    return {
        k: list(v) if isinstance(v, tuple) else _jsonable(v) if isinstance(v, dict) else v
        for k, v in fields.items()
    }


def _read_labels(
    folder: Path, t: NDArray[np.float64], bodies: Sequence[BodyInfo], elan_offset: float | None
) -> tuple[Labels, str | None]:
    if (folder / ANNOTATIONS).is_file():
        lab = kvg.read_annotations(folder / ANNOTATIONS, frame_times=t, bodies=bodies)
        return lab, ANNOTATIONS
    if (folder / ELAN).is_file():
        offset = float(t[0]) if elan_offset is None else float(elan_offset)
        return elan.read_eaf(folder / ELAN, offset=offset, bodies=bodies), ELAN
    return Labels(), None


# ------------------------------------------------------------------- write
def _default_type(kind: str) -> str:
    return {"finger": "digit"}.get(kind, kind)


def _sensor_entries(
    demo: Demonstration,
) -> tuple[list[tuple[BodyInfo, str, int, dict[str, Any]]], int]:
    """Per body: info, section, row, fields to write; and the number of sensor rows."""
    stored = demo.meta.get("mlr", {}) if isinstance(demo.meta.get("mlr"), dict) else {}
    known = stored.get("sensors", {}) if isinstance(stored.get("sensors"), dict) else {}
    rows = [known.get(b.name, {}).get("rn") for b in demo.bodies]
    keep_rows = all(isinstance(r, int) and r >= 0 for r in rows) and len(set(rows)) == len(rows)
    if not keep_rows:
        rows = list(range(len(demo)))
    n_rows = max(rows, default=-1) + 1
    if keep_rows and isinstance(stored.get("n_rows"), int):
        n_rows = max(n_rows, stored["n_rows"])
    out = []
    for b, row in zip(demo.bodies, rows, strict=True):
        entry = dict(known.get(b.name, {}))
        section = str(
            entry.pop("section", "agents" if b.kind in ("finger", "hand", "head") else "objects")
        )
        entry.pop("rn", None)
        for k in _EXPLICIT:
            entry.pop(k, None)
        entry.setdefault("type", _default_type(b.kind))
        derived = derive_body(b.name, section, str(entry["type"]))
        for k in _EXPLICIT:
            if getattr(b, k) != getattr(derived, k):
                entry[k] = _NONE if getattr(b, k) is None else getattr(b, k)
        out.append((b, section, int(row), entry))
    return out, n_rows


def _format_fields(fields: Mapping[str, Any]) -> str:
    parts = []
    for k, v in fields.items():
        if isinstance(v, dict):
            text = "{ " + _format_fields(v) + " }"
        else:
            text = kvg.format_value(tuple(v) if isinstance(v, list) else v)
        parts.append(f"{k} = {text}")
    return ", ".join(parts)


def _meta_text(entries: Sequence[tuple[BodyInfo, str, int, dict[str, Any]]]) -> str:
    """Sections in body order; a section recurs when the bodies interleave sections."""
    runs: list[tuple[str, list[str]]] = []
    width = max(len(kvg.format_value(b.name)) for b, *_ in entries)
    for b, section, row, fields in entries:
        items = {"type": fields["type"], "rn": row}
        items.update((k, v) for k, v in fields.items() if k != "type")
        line = f"  {kvg.format_value(b.name):<{width}} = {{ {_format_fields(items)} }}"
        if not runs or runs[-1][0] != section:
            runs.append((section, []))
        runs[-1][1].append(line)
    mark = f"{WRITER_KEY} = {kvg.format_value(WRITER_MARK)}\n\n"
    return mark + "\n".join(
        f"{kvg.format_value(name)} {{\n" + "\n".join(lines) + "\n}\n" for name, lines in runs
    )


def _poses_text(
    demo: Demonstration, entries: Sequence[tuple[BodyInfo, str, int, dict[str, Any]]], n_rows: int
) -> str:
    vals = np.zeros((demo.n_frames, n_rows, 7))
    for b, _, row, _ in entries:
        tr = demo.track(b.name)
        v = tr.valid
        vals[v, row, :3] = tr.pos[v]
        vals[v, row, 3:] = tr.quat[v][:, [3, 0, 1, 2]]
    row_fmt = " ".join(["%.17g"] * 7)
    block = "[ " + "\n  ".join([row_fmt] * n_rows) + " ]\n"
    return (block * demo.n_frames) % tuple(vals.ravel().tolist())


def _times_text(t: NDArray[np.float64], first: int) -> str:
    numbers = np.arange(first, first + t.size)
    flat = np.empty(2 * t.size, dtype=object)
    flat[0::2] = numbers.tolist()
    flat[1::2] = t.tolist()
    return ("%6d %.17g\n" * t.size) % tuple(flat)


def write(demo: Demonstration, path: str | os.PathLike[str], *, overwrite: bool = False) -> None:
    """Write ``demo`` as an MLR recording folder, atomically.

    Files are written into a temporary sibling folder, then renamed into place.
    Numbers use ``%.17g``, so :func:`read` gives back the same arrays exactly.

    Parameters
    ----------
    demo : Demonstration
    path : path-like
        The folder to create.
    overwrite : bool
        Replace an existing folder; the old one is kept as the next numbered
        backup (``<folder>.bak``, ``<folder>.bak.1``, …; no backup is deleted).

    Raises
    ------
    FormatError
        The folder exists and ``overwrite`` is False, or labels cannot be written.
    """
    target = Path(path)
    if target.exists() and not overwrite:
        raise FormatError(
            target, "already exists (the command's --force replaces it, keeping a backup)"
        )
    if target.exists() and not target.is_dir():
        raise FormatError(target, "exists and is not a folder")
    if len(demo) == 0:
        raise FormatError(target, "a demonstration without bodies cannot be written")
    entries, n_rows = _sensor_entries(demo)
    mlr_meta = demo.meta.get("mlr", {})
    first = mlr_meta.get("first_frame_number", 1) if isinstance(mlr_meta, dict) else 1
    files = {
        META: _meta_text(entries),
        POSES: _poses_text(demo, entries, n_rows),
        TIMES: _times_text(demo.t, int(first)),
    }
    if demo.labels:
        files[ANNOTATIONS] = kvg.format_annotations(
            demo.labels, frame_times=demo.t, bodies=demo.bodies, path=target / ANNOTATIONS
        )
    extra = _extra_text(demo, files.get(ANNOTATIONS))
    if extra is not None:
        files[EXTRA] = extra
    with atomic_output(target) as tmp:
        tmp.mkdir()
        for name, text in files.items():
            with open(tmp / name, "w", encoding="utf-8", newline="\n") as fh:
                fh.write(text)


__all__ = [
    "NumericRows",
    "derive_body",
    "parse_numeric_rows",
    "read",
    "sniff",
    "write",
]
