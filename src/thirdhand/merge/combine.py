"""Several recordings of one session as one :class:`~thirdhand.demonstration.Demonstration`.

The first recording is the reference: every other one is aligned to it
(:func:`~thirdhand.merge.align.align`), its times mapped onto the reference
clock and its poses into the reference world frame. All bodies are then
resampled onto one regular axis at the highest input rate (or a given one),
interpolating only between samples at most ``max_gap`` apart: a gap in a
recording stays a gap. A body tracked by several systems is one body: the
reference's samples, with its gaps filled by the others' where they have one.
The axis starts at the earliest sample of any recording (``t = 0``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from thirdhand.demonstration import (
    BodyInfo,
    BodyTrack,
    Demonstration,
    Labels,
    _interpolate_track,
)
from thirdhand.merge.align import Alignment, MergeError, align

#: Default longest interval interpolated across when resampling, seconds.
DEFAULT_MAX_GAP_S = 0.1
#: Most frames a merged recording may have (a typo in --rate must not fill the memory).
MAX_FRAMES = 50_000_000


def rename(demo: Demonstration, mapping: Mapping[str, str]) -> Demonstration:
    """``demo`` with bodies renamed ``old -> new`` (labels follow)."""
    if not mapping:
        return demo
    for old in mapping:
        demo.track(old)
    names = [mapping.get(n, n) for n in demo.body_names]
    if len(set(names)) != len(names):
        raise MergeError(f"renaming {dict(mapping)} gives two bodies the same name")

    def nm(n: str) -> str:
        return mapping.get(n, n)

    bodies = [dataclasses.replace(b, name=nm(b.name)) for b in demo.bodies]
    tracks = {nm(n): (demo.pos(n), demo.quat(n), demo.valid(n)) for n in demo.body_names}
    lab = demo.labels
    labels = Labels(
        interactions=tuple(dataclasses.replace(i, a=nm(i.a), b=nm(i.b)) for i in lab.interactions),
        constraints=tuple(
            dataclasses.replace(c, parent=nm(c.parent), child=nm(c.child)) for c in lab.constraints
        ),
        plan=tuple(
            dataclasses.replace(s, parent=nm(s.parent), child=nm(s.child)) for s in lab.plan
        ),
    )
    return demo.replace(bodies=bodies, tracks=tracks, labels=labels)


def _shift_labels(labels: Labels, a: float, b: float) -> Labels:
    """Labels with every time ``t`` replaced by ``a * t + b``."""
    return Labels(
        interactions=tuple(
            dataclasses.replace(i, start=a * i.start + b, end=a * i.end + b)
            for i in labels.interactions
        ),
        constraints=tuple(dataclasses.replace(c, time=a * c.time + b) for c in labels.constraints),
        plan=tuple(
            dataclasses.replace(s, time=None if s.time is None else a * s.time + b)
            for s in labels.plan
        ),
    )


def combine(
    recordings: Sequence[Demonstration],
    alignments: Sequence[Alignment],
    *,
    rate: float | None = None,
    max_gap: float = DEFAULT_MAX_GAP_S,
    sources: Sequence[str] | None = None,
) -> Demonstration:
    """Resample aligned recordings onto one axis (see the module documentation).

    Parameters
    ----------
    recordings : sequence of Demonstration
        The reference first.
    alignments : sequence of Alignment
        One per recording after the first.
    rate : float, optional
        Output rate, Hz; default the highest input rate.
    max_gap : float
        Longest interval between two samples interpolated across, seconds.
    sources : sequence of str, optional
        Names of the recordings, for the metadata.
    """
    if len(alignments) != len(recordings) - 1:
        raise MergeError(f"{len(recordings)} recordings need {len(recordings) - 1} alignments")
    identity = Alignment(0.0, 0.0, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0), time_source="reference")
    maps = [identity, *alignments]
    if rate is None:
        rate = (
            max(d.rate for d in recordings if d.n_frames > 1)
            if any(d.n_frames > 1 for d in recordings)
            else 1.0
        )
    starts = [float(m.map_time(d.t[:1])[0]) for d, m in zip(recordings, maps, strict=True)]
    ends = [float(m.map_time(d.t[-1:])[0]) for d, m in zip(recordings, maps, strict=True)]
    t0, t1 = min(starts), max(ends)
    n = int(np.floor((t1 - t0) * rate + 1e-9)) + 1
    if n > MAX_FRAMES:
        raise MergeError(f"the merged axis would hold {n} frames at {rate:g} Hz; lower --rate")
    new_t = t0 + np.arange(n) / rate
    tracks: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
    infos: dict[str, BodyInfo] = {}
    filled: dict[str, int] = {}
    labels: list[Labels] = []
    for demo, m in zip(recordings, maps, strict=True):
        t_mapped = m.map_time(demo.t)
        if not np.all(np.diff(t_mapped) > 0):
            raise MergeError("the clock mapping is not increasing (a drift <= -1?)")
        for name in demo.body_names:
            tr = demo.track(name)
            p, q = m.map_pose(tr.pos, tr.quat)
            moved = BodyTrack(tr.info, p, q, tr.valid)
            pos, quat, valid = _interpolate_track(t_mapped, moved, new_t, max_gap)
            if name not in tracks:
                tracks[name] = (pos, quat, valid)
                infos[name] = tr.info
                continue
            op, oq, ov = tracks[name]
            fill = valid & ~ov
            op, oq, ov = op.copy(), oq.copy(), ov.copy()
            op[fill], oq[fill], ov[fill] = pos[fill], quat[fill], True
            tracks[name] = (op, oq, ov)
            filled[name] = filled.get(name, 0) + int(fill.sum())
            if infos[name].oriented != tr.info.oriented:
                infos[name] = dataclasses.replace(infos[name], oriented=True)
        labels.append(_shift_labels(demo.labels, 1.0 + m.drift, m.offset_s - t0))
    merged_labels = Labels(
        interactions=tuple(i for lab in labels for i in lab.interactions),
        constraints=tuple(c for lab in labels for c in lab.constraints),
        plan=tuple(s for lab in labels for s in lab.plan),
    )
    names = sources or [
        str(d.meta.get("source", f"recording {i}")) for i, d in enumerate(recordings)
    ]
    meta: dict[str, Any] = dict(recordings[0].meta)
    if isinstance(meta.get("start_time_ns"), int):
        meta["start_time_ns"] = int(meta["start_time_ns"] + round(t0 * 1e9))
        meta["start_time_unix"] = meta["start_time_ns"] / 1e9
    meta["merge"] = {
        "sources": list(names),
        "rate_hz": rate,
        "max_gap_s": max_gap,
        "reference_time_of_t0_s": t0,
        "alignments": [alignment_dict(a) for a in alignments],
        "frames_filled_from_other_recordings": filled,
    }
    return Demonstration(
        new_t - t0,
        list(infos.values()),
        {k: v[0] for k, v in tracks.items()},
        {k: v[1] for k, v in tracks.items()},
        {k: v[2] for k, v in tracks.items()},
        labels=merged_labels,
        meta=meta,
    )


def alignment_dict(a: Alignment) -> dict[str, Any]:
    """JSON-able form of an alignment (what the merge report and the metadata hold)."""
    d = dataclasses.asdict(a)
    d["drift_ppm"] = a.drift * 1e6
    d["rotation_deg"] = a.rotation_deg
    return d


#: Median position residual (m) of a shared body above which two recordings are
#: not of one session: sensor noise is millimetres, and a shared body tracked at
#: points a few centimetres apart in the two systems (docs/how-to/merge.md) stays below.
MAX_SESSION_RESIDUAL_M = 0.05


def check_same_session(al: Alignment, what: str) -> None:
    """Refuse an alignment that matched unrelated motion (two different sessions).

    Raises
    ------
    MergeError
        Naming the residuals and the limit they exceed. (A large fitted drift
        alone is no evidence: small residuals show the fit found the motion.)
    """
    bad = [r for r in al.residuals if r.median_m > MAX_SESSION_RESIDUAL_M]
    if bad:
        worst = max(bad, key=lambda r: r.median_m)
        ang = (
            ""
            if worst.angle_median_deg is None
            else f", orientation median {worst.angle_median_deg:.0f}°"
        )
        raise MergeError(
            f"{what}: not one session: the shared body {worst.body!r} has residuals of "
            f"{1000 * worst.median_m:.0f} mm median{ang} after the best alignment, far above "
            f"sensor noise (limit {1000 * MAX_SESSION_RESIDUAL_M:.0f} mm); merge recordings "
            "of the same take, or name the shared bodies with --via/--same"
        )


def shared_bodies(ref: Demonstration, other: Demonstration) -> list[str]:
    """Bodies tracked in both recordings (by name), in the reference's order."""
    return [n for n in ref.body_names if n in other]


def merge(
    recordings: Sequence[Demonstration],
    *,
    via: Sequence[str] | None = None,
    offsets: Sequence[float | None] | None = None,
    transforms: Sequence[tuple[Sequence[float], Sequence[float]] | None] | None = None,
    fit_drift: bool = True,
    smooth: bool = False,
    rate: float | None = None,
    max_gap: float = DEFAULT_MAX_GAP_S,
    sources: Sequence[str] | None = None,
) -> tuple[Demonstration, list[Alignment]]:
    """Align every recording to the first and combine them.

    Parameters
    ----------
    recordings : sequence of Demonstration
        Two or more, the reference first; a body of the same name in two of
        them is the same physical body.
    via : sequence of str, optional
        Align by these shared bodies only (default: every shared body).
    offsets, transforms : sequence, optional
        Per recording after the first: a known clock offset (s) / world transform
        ``(p, q)``, or None to estimate it.
    fit_drift, smooth, rate, max_gap, sources
        See :func:`~thirdhand.merge.align.align` and :func:`combine`.

    Raises
    ------
    MergeError
        A recording shares no body with the reference and no transform was given.
    """
    if len(recordings) < 2:
        raise MergeError("merge needs at least two recordings")
    k = len(recordings) - 1
    offsets = list(offsets) if offsets is not None else [None] * k
    transforms = list(transforms) if transforms is not None else [None] * k
    names = list(sources) if sources is not None else [f"recording {i}" for i in range(k + 1)]
    ref = recordings[0]
    alignments = []
    for i, other in enumerate(recordings[1:]):
        shared = shared_bodies(ref, other)
        if via:
            missing = [b for b in via if b not in shared]
            if missing:
                listing = ", ".join(shared) or "none"
                raise MergeError(
                    f"{names[i + 1]}: --via {', '.join(missing)} is not tracked by both "
                    f"{names[0]} and {names[i + 1]}; shared bodies are {listing}"
                )
            shared = list(via)
        if not shared and transforms[i] is None:
            raise MergeError(
                f"{names[0]} and {names[i + 1]} share no tracked body "
                f"({names[0]}: {', '.join(ref.body_names)}; "
                f"{names[i + 1]}: {', '.join(other.body_names)}) and no --transform was given: "
                "rename a body tracked by both with --same REF=OTHER, or give --transform "
                "and --offset"
            )
        offset = offsets[i]
        if not shared and offset is None:
            a0, b0 = ref.meta.get("start_time_ns"), other.meta.get("start_time_ns")
            if isinstance(a0, int) and isinstance(b0, int):
                offset = (b0 - a0) / 1e9
            else:
                raise MergeError(
                    f"{names[0]} and {names[i + 1]} share no tracked body and neither gives "
                    "its absolute start time: give --offset"
                )
        try:
            al = align(
                ref,
                other,
                shared,
                offset=offset,
                transform=transforms[i],
                fit_drift=fit_drift,
                smooth=smooth,
            )
        except MergeError as exc:
            raise MergeError(f"{names[0]} + {names[i + 1]}: {exc}") from None
        if not shared and offsets[i] is None:
            al = dataclasses.replace(al, time_source="start times")
        check_same_session(al, f"{names[0]} + {names[i + 1]}")
        alignments.append(al)
    return combine(recordings, alignments, rate=rate, max_gap=max_gap, sources=names), alignments
