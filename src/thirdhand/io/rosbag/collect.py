"""Decoding a bag's messages into raw pose tracks, tf edges and thirdhand metadata."""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from thirdhand.errors import FormatError
from thirdhand.io.rosbag.classify import _classify, _Spec
from thirdhand.io.rosbag.constants import _NS, FORMAT_VERSION
from thirdhand.readlimits import loads_json

if TYPE_CHECKING:
    from rosbags.highlevel import AnyReader
    from rosbags.interfaces import Connection


@dataclass
class _Track:
    """Raw observations of one pose stream, in bag order."""

    topic: str
    frame: str = ""
    stamps: list[int] = field(default_factory=list)
    values: list[tuple[float, ...]] = field(default_factory=list)
    visible: list[bool] = field(default_factory=list)
    index: list[int] = field(default_factory=list)

    def add(self, stamp: int, values: tuple[float, ...], visible: bool, index: int) -> None:
        self.stamps.append(stamp)
        self.values.append(values)
        self.visible.append(visible)
        self.index.append(index)


@dataclass
class _Edge:
    """One tf edge ``parent -> child``: its non-static and static samples."""

    parent: str
    dynamic: _Track
    static: _Track


@dataclass
class _Raw:
    """Everything decoded from a bag, before the time axis is built."""

    ros_version: int
    tracks: dict[tuple[str, int | None], _Track]
    edges: dict[str, _Edge]
    own: dict[str, Any] | None
    used: dict[str, str]
    unused: dict[str, str]


def _stamp_of(obj: Any) -> int:
    """``obj.header.stamp`` in nanoseconds; 0 when absent or unset."""
    header = getattr(obj, "header", None)
    stamp = getattr(header, "stamp", None)
    if stamp is None:
        return 0
    return int(stamp.sec) * _NS + int(stamp.nanosec)


def _header_frame(obj: Any) -> str:
    """``obj.header.frame_id`` without a leading slash; empty when absent."""
    return _frame_id(str(getattr(getattr(obj, "header", None), "frame_id", "")))


def _attr(obj: Any, path: Sequence[str]) -> Any:
    for name in path:
        obj = getattr(obj, name)
    return obj


def _pose_values(pose: Any) -> tuple[float, ...]:
    p, o = pose.position, pose.orientation
    return (p.x, p.y, p.z, o.x, o.y, o.z, o.w)


def _frame_id(name: str) -> str:
    """tf frame ids with and without the leading slash of tf1 are the same frame."""
    return name.lstrip("/")


def _collect(
    reader: AnyReader,
    src: Path,
    topics: Sequence[str] | None,
) -> _Raw:
    from rosbags.highlevel import AnyReaderError

    store = reader.typestore
    by_topic: dict[str, list[Connection]] = defaultdict(list)
    for conn in reader.connections:
        by_topic[conn.topic].append(conn)
    specs: dict[str, _Spec] = {}
    unused: dict[str, str] = {}
    for topic, conns in sorted(by_topic.items()):
        spec = _classify(store, topic, conns[0].msgtype)
        if spec is None:
            unused[topic] = conns[0].msgtype
        else:
            specs[topic] = spec
    listing = ", ".join(f"{t} ({c[0].msgtype})" for t, c in sorted(by_topic.items())) or "none"
    if topics is not None:
        for t in topics:
            if t not in by_topic:
                raise FormatError(
                    src,
                    f"requested topic is not in the bag; its topics are {listing}",
                    where=f"topic {t}",
                )
            if t not in specs or specs[t].kind == "meta":
                raise FormatError(
                    src,
                    f"requested topic has type {by_topic[t][0].msgtype}, which carries no pose",
                    where=f"topic {t}",
                )
        wanted = set(topics)
        if "/tf" in wanted:
            wanted.add("/tf_static")
        for t in list(specs):
            if t not in wanted and specs[t].kind != "meta":
                unused[t] = by_topic[t][0].msgtype
                del specs[t]
    if not any(s.kind != "meta" for s in specs.values()):
        raise FormatError(
            src,
            "no pose topic (PoseStamped, tf, or an array of objects with id and pose); "
            f"topics are {listing}",
        )
    raw = _Raw(
        ros_version=2 if reader.is2 else 1,
        tracks={},
        edges={},
        own=None,
        used={t: s.kind for t, s in specs.items()},
        unused=dict(sorted(unused.items())),
    )
    counts: dict[str, int] = defaultdict(int)
    conns = [c for t in specs for c in by_topic[t]]
    for conn, received, data in reader.messages(connections=conns):
        topic = conn.topic
        k = counts[topic]
        counts[topic] += 1
        try:
            msg = reader.deserialize(data, conn.msgtype)
        except AnyReaderError as exc:
            raise FormatError(
                src,
                f"message cannot be decoded: {_one_line(exc)}",
                where=f"topic {topic} message {k}",
            ) from None
        _extract(raw, specs[topic], topic, k, int(received), msg, src)
    return raw


def _extract(
    raw: _Raw, spec: _Spec, topic: str, k: int, received: int, msg: Any, src: Path
) -> None:
    """Add the poses of one decoded message to ``raw``."""
    if spec.kind == "pose":
        track = raw.tracks.setdefault((topic, None), _Track(topic, _header_frame(msg)))
        track.add(_stamp_of(msg) or received, _pose_values(_attr(msg, spec.pose_path)), True, k)
    elif spec.kind == "world":
        top = _stamp_of(msg)
        for obj in getattr(msg, spec.array):
            holder = getattr(obj, spec.holder)
            stamp = _stamp_of(holder) or _stamp_of(obj) or top or received
            visible = True if spec.visible is None else bool(getattr(obj, spec.visible))
            key = (topic, int(obj.id))
            track = raw.tracks.setdefault(key, _Track(topic, _header_frame(holder)))
            track.add(stamp, _pose_values(_attr(holder, spec.pose_path)), visible, k)
    elif spec.kind in ("tf", "transform"):
        static = topic.rstrip("/").endswith("tf_static")
        for tr in msg.transforms if spec.kind == "tf" else (msg,):
            parent, child = _frame_id(tr.header.frame_id), _frame_id(tr.child_frame_id)
            edge = raw.edges.setdefault(child, _Edge(parent, _Track(topic), _Track(topic)))
            if edge.parent != parent:
                raise FormatError(
                    src,
                    f"tf frame {child!r} has two parents, {edge.parent!r} and {parent!r}",
                    where=f"topic {topic} message {k}",
                )
            t, r = tr.transform.translation, tr.transform.rotation
            values = (t.x, t.y, t.z, r.x, r.y, r.z, r.w)
            (edge.static if static else edge.dynamic).add(
                _stamp_of(tr) or received, values, True, k
            )
    elif raw.own is None:
        raw.own = _parse_own(msg.data, src, topic, k)


def _parse_own(text: str, src: Path, topic: str, k: int) -> dict[str, Any]:
    where = f"topic {topic} message {k}"
    own = loads_json(
        text, error=lambda m: FormatError(src, f"thirdhand metadata: {m}", where=where)
    )
    if not isinstance(own, dict) or own.get("format") != FORMAT_VERSION:
        found = own.get("format") if isinstance(own, dict) else type(own).__name__
        raise FormatError(
            src,
            f"unsupported thirdhand metadata {found!r}, expected {FORMAT_VERSION!r}",
            where=where,
        )
    if not isinstance(own.get("origin_ns"), int) or not isinstance(own.get("bodies"), list):
        raise FormatError(
            src, "thirdhand metadata lacks an integer origin_ns or a bodies list", where=where
        )
    return own


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())
