"""C3D motion-capture files (through ``ezc3d``): markers in, rigid bodies out, and back.

Reading
-------
A C3D file holds marker trajectories (``POINT`` data): per frame and marker a
position and a residual. A marker is *missing* in a frame when its residual is
negative, a coordinate is NaN, or all three coordinates are exactly zero.
Positions are converted from ``POINT:UNITS`` (``mm``, ``cm``, ``m``, ``in``;
absent means millimetres, the C3D default) to metres. The time axis is
``t_i = (first_frame + i) / rate`` seconds, with ``first_frame`` the header's
0-based first frame and ``rate`` the point rate (``POINT:RATE``).

Rigid bodies are fitted to clusters of at least 3 markers by a weighted
least-squares (Kabsch) fit per frame, missing markers weighted 0; a frame with
fewer than 3 seen markers is invalid. The clusters come from, in order:

1. the ``bodies`` option ``{body: [marker labels]}``;
2. a ``THIRDHAND`` parameter group written by :func:`write`;
3. the labels' prefixes: ``Seat:M1`` (everything before the first ``:``), else
   ``chair/seat/M1`` (before the last ``/``), else ``Seat_M1`` (before the last
   ``_``); a prefix shared by at least 3 markers makes a body of that name,
   unless the group is not rigid (median fit residual above ``max_rms``, 5 mm
   by default: a person's skin markers, a Vicon subject's skeleton).

Body frame convention
---------------------
When the file carries a ``THIRDHAND`` group, each cluster's marker coordinates
in the body frame are read from it, so the bodies written by :func:`write` come
back with their original poses. Otherwise the body frame is built from the data:

1. the first frame where every marker of the cluster is seen (else the first
   frame seeing the most markers, at least 3) gives a provisional cluster;
2. the well-seen frames (those seeing every marker, when there are at least
   10 of them; else every frame seeing 3 markers of the provisional cluster) are
   fitted to it, each seen marker is expressed in the provisional body frame,
   and the per-coordinate median over frames gives the cluster's geometry
   (robust to noise and occasional mislabelled frames);
3. the body frame of that median cluster has its origin at the centroid of the
   markers and its axes along the cluster's principal axes, x the direction of
   largest spread, then y, and z = x × y (right-handed). The sign of x and y is
   chosen so that the first marker (in label order) whose coordinate along that
   axis exceeds 10 % of the largest one has a positive coordinate.

Such a frame is arbitrary but fixed for a recording: relative motions (the pose
of one body in another, rotation angles) are exact, absolute orientations are
not those of any CAD model. A collinear cluster leaves the rotation about its
line undetermined.

Writing
-------
:func:`write` turns each oriented body into a cluster of markers (by default 4
non-coplanar markers 3 to 6 cm from the body origin, the same for a given body
name), each position-only body into one marker, and writes them in millimetres
as float32 with residual 0 (seen) or -1 and NaN (missing). A ``THIRDHAND``
parameter group holds, as JSON, the body metadata, marker labels, cluster
offsets (float64), exact time axis, labels and ``meta``, so ``read(write(demo))``
returns the demonstration up to float32 storage of the markers (positions to
well under 1e-5 m, orientations to under 1e-4 rad for clusters of a few cm).
The time axis must be regular, and ``ezc3d`` stores at most 65535 frames.

Markers that belong to no body are dropped, or with ``markers_as_bodies=True``
kept as position-only bodies (:attr:`BodyInfo.oriented` False) named by their label.

Damaged files
-------------
ezc3d trusts the sizes written in a file, and crashes the interpreter on some
damaged parameter sections; it also reads a truncated file silently. The header
and every parameter record are therefore checked first, and a file shorter than
the frames it announces raises :class:`FormatError` (or, with
``allow_truncated=True``, yields its complete frames).
"""

from __future__ import annotations

import json
import os
import struct
import warnings
import zlib
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from thirdhand import se3
from thirdhand.demonstration import (
    BodyInfo,
    Demonstration,
    Labels,
    body_info_from_dict,
    body_info_to_dict,
    labels_from_dict,
    labels_to_dict,
)
from thirdhand.errors import FormatError, ThirdhandError

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

FORMAT_VERSION = "thirdhand.c3d/1"
#: Parameter group holding the JSON description written by :func:`write`.
GROUP = "THIRDHAND"
#: Most frames ``ezc3d`` reads back (the C3D header's 16-bit frame numbers).
MAX_FRAMES = 65535
#: Length unit names of ``POINT:UNITS`` -> metres per unit.
UNIT_SCALES: dict[str, float] = {
    "mm": 1e-3,
    "millimeter": 1e-3,
    "millimeters": 1e-3,
    "millimetre": 1e-3,
    "millimetres": 1e-3,
    "cm": 1e-2,
    "m": 1.0,
    "meter": 1.0,
    "meters": 1.0,
    "metre": 1.0,
    "metres": 1.0,
    "in": 0.0254,
    "inch": 0.0254,
    "inches": 0.0254,
}
MIN_CLUSTER = 3
_CHUNK = 200  # characters per string of the JSON document (C3D strings hold <= 255)
_CHUNKS_PER_PARAM = 120  # keeps every parameter record well under 32 kB
_MAX_MEDIAN_FRAMES = 4000
_MIN_WELL_SEEN = 10  # complete frames needed to take the median geometry from them alone
_MAGIC = 0x50
_PROCESSORS = {84: "<", 85: "<", 86: ">"}  # Intel, DEC, MIPS


# ------------------------------------------------------------------ detection
def sniff(path: Path) -> bool:
    """A file ending in ``.c3d``, or whose header and parameter section look like C3D's."""
    if not path.is_file():
        return False
    if path.suffix.lower() == ".c3d":
        return True
    try:
        with open(path, "rb") as fh:
            head = fh.read(2)
            if len(head) < 2 or head[1] != _MAGIC or head[0] < 2:
                return False
            fh.seek((head[0] - 1) * 512 + 3)
            proc = fh.read(1)
    except OSError:
        return False
    return len(proc) == 1 and proc[0] in _PROCESSORS


# ------------------------------------------------------------------- reading
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


def read(
    path: str | os.PathLike[str],
    *,
    bodies: Mapping[str, Sequence[str]] | None = None,
    markers_as_bodies: bool = False,
    units: str | None = None,
    stored_clusters: bool = True,
    allow_truncated: bool = False,
    max_rms: float = 0.005,
) -> Demonstration:
    """Read a C3D file into a :class:`Demonstration` of rigid bodies.

    Parameters
    ----------
    path : path-like
        The ``.c3d`` file.
    bodies : mapping body name -> sequence of marker labels, optional
        Which markers form each rigid body (at least 3 each). Default: the
        ``THIRDHAND`` group when present, else grouping by label prefix.
    markers_as_bodies : bool
        Keep markers that belong to no body as position-only bodies named by
        their label (default: drop them).
    units : str, optional
        Override ``POINT:UNITS`` (one of :data:`UNIT_SCALES`).
    stored_clusters : bool
        Use the cluster geometry stored in a ``THIRDHAND`` group (the default);
        False builds every body frame from the data as a foreign file would.
    allow_truncated : bool
        Read the complete frames of a file shorter than it announces (and say so
        in ``meta["c3d_truncated"]``) instead of raising.
    max_rms : float
        Metres. A body guessed from label prefixes whose median fit residual
        exceeds this is not rigid (a person's skin markers, a whole subject):
        it is not made a body, and its markers count as belonging to none
        (``meta["c3d_nonrigid_groups"]`` lists such groups). Bodies named by
        ``bodies`` or stored by :func:`write` are always kept.

    Returns
    -------
    Demonstration
        Bodies in the order of ``bodies``, else of first appearance; ``meta`` holds
        the source file, units, rate, the markers of each body and the median fit
        residual per body (``c3d_fit_rms_m``, metres).

    Raises
    ------
    FormatError
        Naming the file and the frame, marker, body or parameter at fault.
    """
    p = Path(path)
    mk = _load_markers(p, units, allow_truncated=allow_truncated)
    doc = mk.doc if stored_clusters else None
    stored = {b["name"]: b for b in doc["bodies"]} if doc is not None else {}
    specs, inferred = _body_specs(p, mk.labels, bodies, doc)
    index = {lab: i for i, lab in enumerate(mk.labels)}
    tracks: dict[str, tuple[BodyInfo, FloatArray, FloatArray]] = {}
    rms_med: dict[str, float] = {}
    nonrigid: dict[str, float] = {}
    for name, members, oriented in specs:
        entry = stored.get(name)
        xyz = mk.xyz[:, [index[m] for m in members]]
        if not oriented:
            tracks[name] = (_info(p, entry, name, oriented=False), *_point_track(xyz[:, 0]))
            continue
        if entry is not None and _oriented(entry) and list(entry["markers"]) == members:
            ref = np.asarray(entry["offsets"], dtype=np.float64)
        else:
            ref = reference_cluster(xyz)
        p_b, q_b, rms = fit_cluster(ref, xyz)
        med = float(np.nanmedian(rms)) if np.any(np.isfinite(rms)) else float("nan")
        if inferred and not med <= max_rms:
            nonrigid[name] = med
            continue
        rms_med[name] = med
        tracks[name] = (_info(p, entry, name, oriented=True), p_b, q_b)
    clusters = {name: members for name, members, _ in specs if name not in nonrigid}
    if markers_as_bodies:
        used = {m for members in clusters.values() for m in members}
        single = {b["markers"][0]: b for b in stored.values() if not _oriented(b)}
        for lab in mk.labels:
            if lab in used:
                continue
            entry = single.get(lab)
            name = lab if entry is None else entry["name"]
            if name in tracks:
                raise FormatError(p, "marker named as a body", where=f"marker {lab}")
            info = _info(p, entry, name, oriented=False)
            tracks[name] = (info, *_point_track(mk.xyz[:, index[lab]]))
    n = mk.xyz.shape[0]
    labels = None
    if doc is not None:
        t = float(doc["t0"]) + np.arange(n) / float(doc["rate"])
        meta = dict(doc.get("meta", {}))
        try:
            labels = _labels_within(labels_from_dict(doc.get("labels", {})), set(tracks))
        except ThirdhandError as exc:
            raise FormatError(p, str(exc), where=f"{GROUP}:DOC") from None
    else:
        t = (mk.first_frame + np.arange(n)) / mk.rate
        meta = {
            "source": str(p),
            "format": "c3d",
            "units": mk.units,
            "rate_hz": mk.rate,
            "markers": clusters,
            "c3d_fit_rms_m": rms_med,
        }
        if nonrigid:
            meta["c3d_nonrigid_groups"] = nonrigid
        if mk.truncated:
            meta["c3d_truncated"] = mk.truncated
    try:
        return Demonstration(
            t,
            [info for info, _, _ in tracks.values()],
            {name: tr[1] for name, tr in tracks.items()},
            {name: tr[2] for name, tr in tracks.items()},
            labels=labels,
            meta=meta,
        )
    except ThirdhandError as exc:
        raise FormatError(p, str(exc)) from None


def _point_track(xyz: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Position and identity orientation (NaN where missing) of a single marker."""
    return xyz, np.where(np.isfinite(xyz[:, :1]), se3.quat_identity((1,)), np.nan)


def _body_specs(
    p: Path,
    labels: Sequence[str],
    bodies: Mapping[str, Sequence[str]] | None,
    doc: Mapping[str, Any] | None,
) -> tuple[list[tuple[str, list[str], bool]], bool]:
    """``(body name, marker labels, oriented)`` per body to build, and whether guessed."""
    if bodies is not None:
        specs = [(n, m, True) for n, m in _check_body_option(p, bodies, labels).items()]
        return specs, False
    if doc is not None:
        specs = [(b["name"], list(b["markers"]), _oriented(b)) for b in doc["bodies"]]
        names = [s[0] for s in specs]
        if len(set(names)) != len(names):
            raise FormatError(p, "a body is described twice", where=f"{GROUP}:DOC")
        return specs, False
    return [(n, m, True) for n, m in group_by_prefix(labels).items()], True


def _labels_within(labels: Labels, names: set[str]) -> Labels:
    """The labels that only name bodies in ``names``."""
    return Labels(
        interactions=tuple(i for i in labels.interactions if {i.a, i.b} <= names),
        constraints=tuple(c for c in labels.constraints if {c.parent, c.child} <= names),
        plan=tuple(s for s in labels.plan if {s.parent, s.child} <= names),
    )


def _oriented(entry: Mapping[str, Any]) -> bool:
    return bool(entry.get("oriented", True))


def _info(p: Path, entry: Mapping[str, Any] | None, name: str, *, oriented: bool) -> BodyInfo:
    if entry is None:
        return BodyInfo(name=name, oriented=oriented)
    fields = {k: v for k, v in entry.items() if k not in ("markers", "offsets")}
    fields["oriented"] = oriented
    try:
        info = body_info_from_dict(fields)
    except ThirdhandError as exc:
        raise FormatError(p, str(exc), where=f"{GROUP}:DOC body {name}") from None
    return info


def _check_body_option(
    p: Path, bodies: Mapping[str, Sequence[str]], labels: Sequence[str]
) -> dict[str, list[str]]:
    known = set(labels)
    out: dict[str, list[str]] = {}
    for name, members in bodies.items():
        if isinstance(members, str):
            raise FormatError(p, "expected a list of marker labels, got a string", where=name)
        members = list(members)
        missing = [m for m in members if m not in known]
        if missing:
            raise FormatError(
                p,
                f"unknown marker(s) {', '.join(map(repr, missing))}; the file's markers are "
                f"{', '.join(labels)}",
                where=f"body {name}",
            )
        if len(set(members)) < MIN_CLUSTER:
            raise FormatError(
                p,
                f"a rigid body needs at least {MIN_CLUSTER} distinct markers, "
                f"got {len(set(members))}",
                where=f"body {name}",
            )
        out[str(name)] = list(dict.fromkeys(members))
    return out


def group_by_prefix(labels: Sequence[str]) -> dict[str, list[str]]:
    """Group marker labels into bodies by prefix.

    The prefix is what precedes the first ``:``, else the last ``/``, else the
    last ``_``; prefixes shared by at least 3 markers become bodies.

    Parameters
    ----------
    labels : sequence of str
        Marker labels, in file order.

    Returns
    -------
    dict body name -> list of labels
        In order of first appearance.
    """
    groups: dict[str, list[str]] = {}
    for lab in labels:
        prefix = label_prefix(lab)
        if prefix:
            groups.setdefault(prefix, []).append(lab)
    return {k: v for k, v in groups.items() if len(v) >= MIN_CLUSTER}


def label_prefix(label: str) -> str | None:
    """Body prefix of a marker label (see :func:`group_by_prefix`), None if it has none."""
    if ":" in label:
        head = label.split(":", 1)[0]
    elif "/" in label.strip("/"):
        head = label.rstrip("/").rsplit("/", 1)[0]
    elif "_" in label:
        head = label.rsplit("_", 1)[0]
    else:
        return None
    return head or None


def reference_cluster(xyz: ArrayLike) -> FloatArray:
    """A cluster's marker coordinates in a body frame built from the data.

    See the module docstring for the convention (first well-seen frame, median
    geometry, centroid origin, principal axes).

    Parameters
    ----------
    xyz : array_like, shape (n_frames, m, 3), metres, world frame
        The cluster's markers over time; NaN where missing.

    Returns
    -------
    ndarray, shape (m, 3), metres, body frame
        NaN rows for markers never seen in a frame that could be fitted; all NaN
        when no frame sees 3 markers.
    """
    obs = np.asarray(xyz, dtype=np.float64)
    m = obs.shape[1]
    seen = np.all(np.isfinite(obs), axis=2)
    counts = seen.sum(axis=1)
    if counts.size == 0 or counts.max() < MIN_CLUSTER:
        return np.full((m, 3), np.nan)
    first = int(np.argmax(counts == counts.max()))
    ref0 = canonical_cluster(obs[first])
    use = np.all(np.isfinite(ref0), axis=1)
    idx = np.flatnonzero(counts == m)
    if idx.size < _MIN_WELL_SEEN:  # too few complete frames: any frame that can be fitted
        idx = np.flatnonzero(seen[:, use].sum(axis=1) >= MIN_CLUSTER)
    if idx.size > _MAX_MEDIAN_FRAMES:  # evenly spread frames are plenty for a median
        idx = idx[np.linspace(0, idx.size - 1, _MAX_MEDIAN_FRAMES).round().astype(int)]
    p, q, _ = se3.kabsch(ref0[use], obs[idx][:, use])
    local = se3.quat_rotate(se3.quat_conjugate(q)[:, None], obs[idx] - p[:, None])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN marker: stays NaN
        median = np.nanmedian(local, axis=0)
    return canonical_cluster(median)


def canonical_cluster(points: ArrayLike) -> FloatArray:
    """Express a marker cluster in its centroid / principal-axes frame.

    Parameters
    ----------
    points : array_like, shape (m, 3), metres
        Marker positions in any frame; NaN rows (unseen markers) are ignored
        and stay NaN.

    Returns
    -------
    ndarray, shape (m, 3), metres, body frame
        Origin at the centroid of the finite rows; x, y, z along the principal
        axes by decreasing spread, right-handed, signs as in the module docstring.
    """
    pts = np.asarray(points, dtype=np.float64)
    ok = np.all(np.isfinite(pts), axis=1)
    centred = pts - pts[ok].mean(axis=0)
    _, vecs = np.linalg.eigh(centred[ok].T @ centred[ok])
    axes = vecs[:, ::-1].copy()
    for j in (0, 1):
        proj = centred[ok] @ axes[:, j]
        big = np.flatnonzero(np.abs(proj) > 0.1 * np.abs(proj).max())
        if big.size and proj[big[0]] < 0:
            axes[:, j] *= -1.0
    axes[:, 2] = np.cross(axes[:, 0], axes[:, 1])
    out: FloatArray = centred @ axes
    return out


def fit_cluster(reference: ArrayLike, xyz: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Body poses from its markers by a per-frame Kabsch fit.

    Parameters
    ----------
    reference : array_like, shape (m, 3), metres, body frame
        Marker coordinates in the body frame; NaN rows are left out of the fit.
    xyz : array_like, shape (n_frames, m, 3), metres, world frame
        Observed markers; NaN where missing (weight 0).

    Returns
    -------
    pos : ndarray, shape (n_frames, 3), metres, world frame
    quat : ndarray, shape (n_frames, 4), x y z w, sign-continuous
    rms : ndarray, shape (n_frames,), metres
        NaN where fewer than 3 markers were seen.
    """
    ref = np.asarray(reference, dtype=np.float64)
    obs = np.asarray(xyz, dtype=np.float64)
    use = np.all(np.isfinite(ref), axis=1)
    n = obs.shape[0]
    if use.sum() < MIN_CLUSTER:
        return np.full((n, 3), np.nan), np.full((n, 4), np.nan), np.full(n, np.nan)
    p, q, rms = se3.kabsch(ref[use], obs[:, use])
    return p, se3.quat_make_continuous(q), rms


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
        doc = json.loads("".join(parts))
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
        with open(p, "rb") as fh:
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


# ------------------------------------------------------------------- writing
def default_cluster(name: str) -> FloatArray:
    """The marker cluster :func:`write` gives a body by default.

    Four non-coplanar markers 3 to 6 cm from the body origin in an irregular
    tetrahedron, turned by a rotation seeded from the body name: the same for a
    given name in every run, different between bodies.

    Returns
    -------
    ndarray, shape (4, 3), metres, body frame
    """
    rng = np.random.default_rng(zlib.crc32(name.encode("utf-8")))
    base = np.array(
        [[0.05, 0.0, 0.0], [0.0, 0.04, 0.0], [0.0, 0.0, 0.035], [-0.03, -0.035, -0.025]]
    )
    base *= rng.uniform(0.85, 1.15, size=(4, 1))
    rot = se3.matrix_from_quat(se3.random_quat(rng))
    out: FloatArray = base @ rot.T
    return out


def markers_from_demonstration(
    demo: Demonstration, clusters: Mapping[str, ArrayLike] | None = None
) -> tuple[list[str], FloatArray]:
    """Marker trajectories of a demonstration's bodies (the marker-level view of a scene).

    Parameters
    ----------
    demo : Demonstration
    clusters : mapping body name -> array_like, shape (m, 3), metres, body frame, optional
        Marker offsets of oriented bodies (m >= 3, not collinear); others get
        :func:`default_cluster`.

    Returns
    -------
    labels : list of str
        ``"<body>:M<k>"`` (k from 1) for oriented bodies, the body name for
        position-only bodies.
    positions : ndarray, shape (n_frames, n_markers, 3), metres, world frame
        NaN where the body is not tracked.

    Raises
    ------
    ThirdhandError
        For a cluster of an unknown or position-only body, of fewer than 3
        markers, collinear or not finite, or duplicate labels.
    """
    labels, offsets = _layout(demo, clusters)
    cols: list[FloatArray] = []
    for name in demo.body_names:
        tr = demo.track(name)
        off = offsets.get(name)
        if off is None:
            cols.append(tr.pos[:, None])
        else:
            cols.append(tr.pos[:, None] + se3.quat_rotate(tr.quat[:, None], off[None]))
    if not cols:
        return labels, np.zeros((demo.n_frames, 0, 3))
    return labels, np.concatenate(cols, axis=1)


def _layout(
    demo: Demonstration, clusters: Mapping[str, ArrayLike] | None
) -> tuple[list[str], dict[str, FloatArray]]:
    """Marker labels and offsets (oriented bodies only) in body order."""
    given = dict(clusters or {})
    unknown = sorted(set(given) - set(demo.body_names))
    if unknown:
        raise ThirdhandError(f"clusters given for unknown bod(ies) {', '.join(unknown)}")
    labels: list[str] = []
    offsets: dict[str, FloatArray] = {}
    for info in demo.bodies:
        # C3D readers strip the blanks around labels: the labels are made without them.
        stem = info.name.strip()
        if not stem:
            raise ThirdhandError(f"body {info.name!r}: a blank name makes no marker label")
        if not info.oriented:
            if info.name in given:
                raise ThirdhandError(f"body {info.name!r} is position-only: it takes no cluster")
            labels.append(stem)
            continue
        off = (
            _check_offsets(info.name, given[info.name])
            if info.name in given
            else default_cluster(info.name)
        )
        offsets[info.name] = off
        labels.extend(f"{stem}:M{k + 1}" for k in range(off.shape[0]))
    counts = Counter(labels)
    dup = sorted(lab for lab, k in counts.items() if k > 1)
    if dup:
        raise ThirdhandError(f"duplicate marker label(s) {', '.join(dup)}")
    long = [lab for lab in counts if len(lab.encode("utf-8")) > 255]
    if long:
        raise ThirdhandError(f"marker label {long[0]!r} is longer than C3D's 255 bytes")
    return labels, offsets


def _check_offsets(name: str, offsets: ArrayLike) -> FloatArray:
    off = np.asarray(offsets, dtype=np.float64)
    if off.ndim != 2 or off.shape[1] != 3 or off.shape[0] < MIN_CLUSTER:
        raise ThirdhandError(
            f"body {name!r}: a cluster needs shape (m >= {MIN_CLUSTER}, 3), got {off.shape}"
        )
    if not np.all(np.isfinite(off)):
        raise ThirdhandError(f"body {name!r}: cluster offsets must be finite")
    sv = np.linalg.svd(off - off.mean(axis=0), compute_uv=False)
    if sv[1] <= 1e-6:
        raise ThirdhandError(f"body {name!r}: cluster markers are collinear; orientation is lost")
    return off


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
    tmp = p.with_name(f".{p.name}.{os.getpid()}.tmp.c3d")
    try:
        c.write(str(tmp))
        os.replace(tmp, p)
    except (OSError, RuntimeError, ValueError, TypeError) as exc:
        raise FormatError(p, f"could not write: {exc}") from None
    finally:
        if tmp.exists():
            tmp.unlink()


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
    text = json.dumps(doc, ensure_ascii=True, separators=(",", ":"), default=_plain)
    text = text.replace(" ", "\\u0020")
    chunks = [text[i : i + _CHUNK] for i in range(0, len(text), _CHUNK)]
    out: dict[str, list[str]] = {}
    for j in range(0, len(chunks), _CHUNKS_PER_PARAM):
        key = "DOC" if j == 0 else f"DOC{j // _CHUNKS_PER_PARAM + 1}"
        out[key] = chunks[j : j + _CHUNKS_PER_PARAM]
    return out


__all__ = [
    "FORMAT_VERSION",
    "GROUP",
    "MAX_FRAMES",
    "UNIT_SCALES",
    "canonical_cluster",
    "default_cluster",
    "fit_cluster",
    "group_by_prefix",
    "label_prefix",
    "markers_from_demonstration",
    "read",
    "reference_cluster",
    "sniff",
    "write",
]
