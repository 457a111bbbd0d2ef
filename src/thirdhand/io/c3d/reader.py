"""Reading a C3D file into rigid bodies (see :mod:`thirdhand.io.c3d`)."""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.demonstration import (
    BodyInfo,
    Demonstration,
    Labels,
    body_info_from_dict,
    labels_from_dict,
)
from thirdhand.errors import FormatError, ThirdhandError
from thirdhand.io.c3d.clusters import fit_cluster, group_by_prefix, reference_cluster
from thirdhand.io.c3d.constants import GROUP, MIN_CLUSTER
from thirdhand.io.c3d.markers import _load_markers, _oriented


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
