"""Raw bag contents to a :class:`~thirdhand.demonstration.Demonstration`: bodies, frames, meta."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from thirdhand.arrays import BoolArray, FloatArray, IntArray
from thirdhand.demonstration import (
    BodyInfo,
    Demonstration,
    Labels,
    body_info_from_dict,
    labels_from_dict,
)
from thirdhand.errors import FormatError, ThirdhandError
from thirdhand.io.rosbag.collect import _Raw
from thirdhand.io.rosbag.constants import _NS, META_TOPIC
from thirdhand.io.rosbag.timeline import _frame_axis, _Series, _series
from thirdhand.io.rosbag.tree import _build_tree, _choose_root, _in_root, _tf_arrays, _Tree


@dataclass
class _Body:
    """One body being assembled: its default name and where its poses come from."""

    default: str
    key: str
    series: _Series | None = None
    frame: str | None = None


def _own_names(own: Mapping[str, Any], src: Path) -> dict[tuple[str, str], str]:
    """("topic" | "frame", source) -> body name, from a thirdhand metadata message."""
    out: dict[tuple[str, str], str] = {}
    try:
        for b in own["bodies"]:
            for kind in ("topic", "frame"):
                if kind in b:
                    out[kind, str(b[kind])] = str(b["info"]["name"])
    except (KeyError, TypeError) as exc:
        raise FormatError(src, f"malformed thirdhand metadata: {exc!r}", where=META_TOPIC) from None
    return out


def _direct_bodies(
    raw: _Raw, src: Path, own_names: Mapping[tuple[str, str], str], object_prefix: str
) -> list[_Body]:
    """Bodies of pose and world-model topics, sorted by topic then object id."""
    world_topics = {topic for topic, oid in raw.tracks if oid is not None}
    out = []
    for (topic, oid), track in sorted(raw.tracks.items(), key=lambda kv: (kv[0][0], kv[0][1] or 0)):
        if oid is None:
            default, key = own_names.get(("topic", topic), topic.lstrip("/")), topic
        else:
            default, key = f"{object_prefix}{oid}", f"{topic}/{oid}"
            if len(world_topics) > 1:
                default = f"{topic.lstrip('/')}/{default}"
        out.append(_Body(default, key, _series(track, src, f"body {default!r}")))
    return out


def _tf_bodies(
    raw: _Raw, src: Path, root_frame: str | None, own_names: Mapping[tuple[str, str], str]
) -> tuple[_Tree | None, str | None, list[_Body]]:
    """The tf tree, the frame poses are expressed in, and one body per other frame of its tree."""
    if not raw.edges:
        if root_frame is not None and raw.own is None:
            raise FormatError(
                src, f"root_frame {root_frame!r} given but the bag has no tf", where="tf"
            )
        return None, None, []
    tree = _build_tree(raw, src)
    root = _choose_root(tree, src, root_frame)
    top = tree.root(root)
    bodies = [
        _Body(own_names.get(("frame", c), c), c, frame=c)
        for c in sorted(tree.parent)
        if c != root and tree.root(c) == top
    ]
    return tree, root, bodies


def _assemble(
    raw: _Raw,
    src: Path,
    *,
    root_frame: str | None,
    names: Mapping[str, str],
    topics: Sequence[str] | None,
    tol_ns: int,
    object_prefix: str,
    sources: Sequence[Path],
) -> Demonstration:
    own = raw.own
    own_names = {} if own is None else _own_names(own, src)
    if own is not None and root_frame is None:
        root_frame = own.get("root_frame") if raw.edges else None
    bodies = _direct_bodies(raw, src, own_names, object_prefix)
    tree, root, tf_bodies = _tf_bodies(raw, src, root_frame, own_names)
    bodies += tf_bodies

    streams: list[IntArray] = [b.series.stamps for b in bodies if b.series is not None]
    deepest: dict[str, str | None] = {}
    edge_stream: dict[str, int] = {}
    if tree is not None:
        for frame in (b.frame for b in tf_bodies if b.frame is not None):
            dyn = [c for c in tree.path(frame) if c in tree.dynamic]
            d = deepest[frame] = dyn[-1] if dyn else None
            if d is not None and d not in edge_stream:
                edge_stream[d] = len(streams)
                streams.append(tree.dynamic[d].stamps)
        if not streams and tree.static:
            streams.append(np.unique(np.concatenate([s.stamps for s in tree.static.values()])))
    if own is not None:
        streams.append(np.unique(np.asarray(own.get("extra_frames_ns", []), dtype=np.int64)))
    frames, frame_index = _frame_axis(streams, tol_ns)
    if frames.size == 0:
        raise FormatError(src, "the pose topics hold no message")
    n = frames.size

    pos: dict[str, FloatArray] = {}
    quat: dict[str, FloatArray] = {}
    valid: dict[str, BoolArray] = {}
    final: dict[str, _Body] = {}
    for i, b in enumerate(bodies):
        name = names.get(b.key, names.get(b.default, b.default))
        if name in final:
            raise FormatError(
                src,
                f"two sources give body {name!r} ({final[name].key} and {b.key}); "
                "rename one with names=",
            )
        final[name] = b
        p, q, v = np.full((n, 3), np.nan), np.full((n, 4), np.nan), np.zeros(n, dtype=bool)
        if b.series is not None:
            idx = frame_index[i]
            p[idx], q[idx], v[idx] = _in_root(b.series, tree, root)
        elif tree is not None and root is not None and b.frame is not None:
            d = deepest[b.frame]
            if d is None:
                t_eval, idx = frames, np.arange(n)
            else:
                t_eval, idx = tree.dynamic[d].stamps, frame_index[edge_stream[d]]
            p[idx], q[idx], v[idx] = _tf_arrays(tree, root, b.frame, t_eval)
        v &= np.all(np.isfinite(p), axis=1) & np.all(np.isfinite(q), axis=1)
        pos[name], quat[name], valid[name] = p, q, v

    origin = int(frames[0])
    if own is None:
        infos = [BodyInfo(name) for name in final]
        labels = Labels()
        meta: dict[str, Any] = {
            "format": "rosbag",
            "topics": raw.used,
            "unused_topics": raw.unused,
            "merge_tolerance_s": tol_ns / _NS,
        }
        if root is not None:
            meta["tf_root_frame"] = root
    else:
        origin = int(own["origin_ns"])
        infos, labels, meta = _own_metadata(own, src, final, names, topics)
        for info in infos:
            if info.name not in pos:
                pos[info.name] = np.full((n, 3), np.nan)
                quat[info.name] = np.full((n, 4), np.nan)
                valid[info.name] = np.zeros(n, dtype=bool)
    meta.update(
        source=str(src) if len(sources) == 1 else [str(s) for s in sources],
        ros_version=raw.ros_version,
        start_time_unix=origin / _NS,
        start_time_ns=origin,
    )
    try:
        return Demonstration(
            (frames - origin) / _NS, infos, pos, quat, valid, labels=labels, meta=meta
        )
    except ThirdhandError as exc:
        raise FormatError(src, str(exc)) from None


def _own_metadata(
    own: Mapping[str, Any],
    src: Path,
    final: Mapping[str, _Body],
    names: Mapping[str, str],
    topics: Sequence[str] | None,
) -> tuple[list[BodyInfo], Labels, dict[str, Any]]:
    """Bodies, labels and meta of a bag written by :func:`write`, renamed by ``names``."""
    rename: dict[str, str] = {}
    infos: list[BodyInfo] = []
    try:
        for b in own["bodies"]:
            info = body_info_from_dict(b["info"])
            source = b.get("topic", "/tf")
            if topics is not None and source not in topics:
                continue
            new = names.get(b.get("topic", b.get("frame", "")), names.get(info.name, info.name))
            rename[info.name] = new
            infos.append(dataclasses.replace(info, name=new))
        labels = labels_from_dict(own.get("labels", {}))
        meta = dict(own.get("meta", {}))
    except (KeyError, TypeError, AttributeError, ThirdhandError) as exc:
        raise FormatError(src, f"malformed thirdhand metadata: {exc}", where=META_TOPIC) from None
    known = {i.name for i in infos}
    infos += [BodyInfo(name) for name in final if name not in known]
    return infos, _rename_labels(labels, rename), meta


def _rename_labels(labels: Labels, rename: Mapping[str, str]) -> Labels:
    """Labels with bodies renamed; labels about bodies not in ``rename`` are dropped."""

    def ok(*bodies: str) -> bool:
        return all(b in rename for b in bodies)

    return Labels(
        interactions=tuple(
            dataclasses.replace(i, a=rename[i.a], b=rename[i.b])
            for i in labels.interactions
            if ok(i.a, i.b)
        ),
        constraints=tuple(
            dataclasses.replace(c, parent=rename[c.parent], child=rename[c.child])
            for c in labels.constraints
            if ok(c.parent, c.child)
        ),
        plan=tuple(
            dataclasses.replace(s, parent=rename[s.parent], child=rename[s.child])
            for s in labels.plan
            if ok(s.parent, s.child)
        ),
    )
