"""ROS 1 and ROS 2 bags: poses from pose topics, the tf tree and world-model messages.

Reading (through the pure-Python ``rosbags`` package; no ROS installation needed)
-------------------------------------------------------------------------------
Sources: a ROS 1 ``.bag`` file (or a list of them, e.g. one recording split in
parts), a ROS 2 bag folder (``metadata.yaml`` plus ``.db3`` or ``.mcap`` files),
or a lone ``.mcap`` / ``.db3`` file. Message definitions embedded in the bag
(ROS 1 connections always carry them) are registered, so custom types decode.

Every topic is classified by the *structure* of its message type, not its name:

- **pose** topics: a ``geometry_msgs/Pose`` at ``msg``, ``msg.pose`` or
  ``msg.pose.pose`` (``PoseStamped``, ``PoseWithCovarianceStamped``,
  ``Odometry``...). One body per topic, named after the topic without its
  leading slash. When the header's frame belongs to the tf tree of
  ``root_frame``, the pose is moved into ``root_frame`` (tf looked up at the
  message's stamp); otherwise it stays in its header frame.
- **tf**: ``tf2_msgs/TFMessage`` (``/tf``; ``/tf_static`` for static transforms)
  and ``TransformStamped`` topics. Every ``child_frame_id`` becomes a body whose
  pose is expressed in ``root_frame`` (default: the root of the largest tree),
  composed along the tree. A body is observed at the stamps of the deepest
  non-static transform on its path; the other non-static transforms are
  interpolated there (linear / slerp, no extrapolation, as tf2 does); static
  transforms take the latest value published at or before that time (the
  first one before it was published).
- **world model**: a message holding an array of objects, each with an integer
  ``id``, a pose (``PoseStamped`` or ``Pose``) and optionally a boolean field
  whose name contains ``visible``. One body per id, named ``<object_prefix><id>``
  (``ar_0``, ``ar_13`` for AR tags); a frame where the object is not visible is
  invalid.

Topics of other types (joint states, controller states...) are listed in
``meta["unused_topics"]``.

Time stamps come from the message's ``header.stamp`` (for world-model objects:
the pose's, else the object's, else the message's header), falling back to
the bag's receive time when the stamp is zero (unset).

Time axis: the union of all observation stamps, merged so that bodies
published together share a frame: a frame opens at the earliest stamp not yet
placed and takes every later stamp within ``merge_tolerance`` of it, at most one
per body (stream); its time is that earliest stamp. A body is invalid at the
frames where it was not observed. ``t`` is in seconds from the first frame;
``meta["start_time_unix"]`` (float seconds) and ``meta["start_time_ns"]`` (int)
give the absolute time of ``t = 0``.

Writing
-------
ROS 1 ``.bag``, ROS 2 folder (mcap or sqlite3 storage) or a lone ``.mcap`` /
``.db3`` file, with one ``geometry_msgs/PoseStamped`` topic per body
(``/thirdhand/<name>/pose``) or the bodies as ``/tf`` frames under
``root_frame``. Invalid frames are not published. A ``/thirdhand/meta``
``std_msgs/String`` message holds JSON with the body metadata, labels, the
demonstration's ``meta`` and the time origin, so that a bag written here reads
back with the same time axis (to the nanosecond), poses, bodies and labels.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import os
import re
import shutil
import sqlite3
import struct
from collections import defaultdict
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numba
import numpy as np
from numpy.typing import NDArray

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

if TYPE_CHECKING:
    from rosbags.highlevel import AnyReader
    from rosbags.interfaces import Connection
    from rosbags.typesys.store import Typestore

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]
PathLike = str | os.PathLike[str]

FORMAT_VERSION = "thirdhand.rosbag/1"
#: Topic of the JSON message that makes a bag written by :func:`write` round-trip.
META_TOPIC = "/thirdhand/meta"
#: Default largest spread of stamps merged into one frame, seconds.
DEFAULT_MERGE_TOLERANCE = 1e-3

_NS = 1_000_000_000
_ROS2_SUFFIXES = (".mcap", ".db3")
_INT_TYPES = frozenset({"int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64"})
_TFMESSAGE = "tf2_msgs/msg/TFMessage"
_POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
_STRING = "std_msgs/msg/String"


# =================================================================== sniffing
def sniff(path: Path) -> bool:
    """A ``.bag``, ``.mcap`` or ``.db3`` file, or a folder with ``metadata.yaml`` and such files."""
    p = Path(path)
    if p.is_dir():
        return (p / "metadata.yaml").is_file() and any(
            any(s.lower() in _ROS2_SUFFIXES for s in f.suffixes) for f in p.iterdir()
        )
    return p.is_file() and p.suffix.lower() in (".bag", *_ROS2_SUFFIXES)


# ============================================================ classification
@dataclass(frozen=True)
class _Spec:
    """How to pull poses out of one topic's messages.

    ``pose_path`` leads from the message (pose topics) or from the object's
    ``holder`` field (world-model topics) to a ``geometry_msgs/Pose``.
    """

    kind: Literal["pose", "tf", "transform", "world", "meta"]
    pose_path: tuple[str, ...] = ()
    array: str = ""
    holder: str = ""
    visible: str | None = None


def _fields(store: Typestore, typ: str | None) -> dict[str, Any]:
    if typ is None or typ not in store.fielddefs:
        return {}
    return dict(store.fielddefs[typ][1])


def _name_of(desc: Any) -> str | None:
    """The message type of a field holding one message, else None."""
    from rosbags.interfaces import Nodetype

    return str(desc[1]) if desc is not None and desc[0] == Nodetype.NAME else None


def _element_of(desc: Any) -> str | None:
    """The message type of the elements of an array field, else None."""
    from rosbags.interfaces import Nodetype

    if desc is None or desc[0] not in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        return None
    return _name_of(desc[1][0])


def _base_of(desc: Any) -> str | None:
    """The primitive type of a scalar field (``uint32``, ``bool``...), else None."""
    from rosbags.interfaces import Nodetype

    return str(desc[1][0]) if desc is not None and desc[0] == Nodetype.BASE else None


def _has(store: Typestore, typ: str | None, names: Sequence[str]) -> bool:
    f = _fields(store, typ)
    return bool(f) and all(n in f for n in names)


def _pose_path(store: Typestore, typ: str, depth: int = 2) -> tuple[str, ...] | None:
    """Attributes leading from a message of type ``typ`` to a Pose, or None."""
    f = _fields(store, typ)
    if _has(store, _name_of(f.get("position")), "xyz") and _has(
        store, _name_of(f.get("orientation")), "xyzw"
    ):
        return ()
    sub = _name_of(f.get("pose"))
    if depth == 0 or sub is None:
        return None
    rest = _pose_path(store, sub, depth - 1)
    return None if rest is None else ("pose", *rest)


def _is_transform_stamped(store: Typestore, typ: str | None) -> bool:
    f = _fields(store, typ)
    return (
        _base_of(f.get("child_frame_id")) == "string"
        and "header" in f
        and _has(store, _name_of(f.get("transform")), ("translation", "rotation"))
    )


def _classify(store: Typestore, topic: str, typ: str) -> _Spec | None:
    """What a topic of message type ``typ`` carries, judged by the type's fields."""
    f = _fields(store, typ)
    if topic == META_TOPIC and _base_of(f.get("data")) == "string":
        return _Spec("meta")
    if _is_transform_stamped(store, typ):
        return _Spec("transform")
    if _is_transform_stamped(store, _element_of(f.get("transforms"))):
        return _Spec("tf")
    path = _pose_path(store, typ)
    if path is not None:
        return _Spec("pose", pose_path=path)
    for array, desc in f.items():
        ef = _fields(store, _element_of(desc))
        if _base_of(ef.get("id")) not in _INT_TYPES:
            continue
        for holder, hdesc in ef.items():
            sub = _name_of(hdesc)
            hpath = None if sub is None else _pose_path(store, sub, 1)
            if hpath is None:
                continue
            visible = next(
                (n for n, d in ef.items() if _base_of(d) == "bool" and "visible" in n.lower()),
                None,
            )
            return _Spec("world", pose_path=hpath, array=array, holder=holder, visible=visible)
    return None


# ================================================================ collection
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
    try:
        own = json.loads(text)
    except json.JSONDecodeError as exc:
        raise FormatError(
            src, f"thirdhand metadata is not valid JSON: {exc}", where=where
        ) from None
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


# ================================================================== series
@dataclass
class _Series:
    """Observations of one stream sorted by stamp, duplicates removed.

    Attributes
    ----------
    stamps : ndarray of int64, shape (n,), nanoseconds since the Unix epoch
    pose : ndarray, shape (n, 7), x y z (metres) then qx qy qz qw, parent frame
    visible : ndarray of bool, shape (n,)
    frame : str
        The parent frame (``header.frame_id`` of the first message), may be empty.
    """

    stamps: IntArray
    pose: FloatArray
    visible: BoolArray
    frame: str = ""


def _fmt_stamp(ns: int) -> str:
    return f"{ns // _NS}.{ns % _NS:09d} s"


def _series(track: _Track, src: Path, what: str) -> _Series:
    """Sort by stamp, drop exact repeats, reject conflicting repeats and zero quaternions."""
    stamps = np.asarray(track.stamps, dtype=np.int64)
    pose = np.asarray(track.values, dtype=np.float64).reshape(-1, 7)
    visible = np.asarray(track.visible, dtype=bool)
    index = np.asarray(track.index, dtype=np.int64)
    order = np.argsort(stamps, kind="stable")
    stamps, pose, visible, index = stamps[order], pose[order], visible[order], index[order]
    same = np.flatnonzero(np.diff(stamps) == 0)
    if same.size:
        a, b = pose[same], pose[same + 1]
        differ = ~np.all((a == b) | (np.isnan(a) & np.isnan(b)), axis=1)
        differ |= visible[same] != visible[same + 1]
        if np.any(differ):
            i = int(same[differ][0])
            raise FormatError(
                src,
                f"{what}: two different poses with the same stamp {_fmt_stamp(int(stamps[i]))}",
                where=f"topic {track.topic} messages {index[i]} and {index[i + 1]}",
            )
        keep = np.ones(stamps.size, dtype=bool)
        keep[same + 1] = False
        stamps, pose, visible, index = stamps[keep], pose[keep], visible[keep], index[keep]
    finite = np.all(np.isfinite(pose), axis=1)
    zero = np.flatnonzero(visible & finite & (np.linalg.norm(pose[:, 3:], axis=1) < 1e-12))
    if zero.size:
        i = int(zero[0])
        raise FormatError(
            src,
            f"{what}: zero-norm quaternion at stamp {_fmt_stamp(int(stamps[i]))}",
            where=f"topic {track.topic} message {index[i]}",
        )
    return _Series(stamps, pose, visible & finite, track.frame)


@numba.njit(cache=True, nogil=True)
def _greedy_frames(stamps: IntArray, owner: IntArray, n_owners: int, tol_ns: int) -> IntArray:
    """Frame of each sorted stamp: a frame opens at the first stamp not yet placed
    and takes the following stamps within ``tol_ns`` of it, one per owner."""
    frame = np.empty(stamps.size, dtype=np.int64)
    last = np.full(n_owners, -1, dtype=np.int64)
    f = -1
    anchor = 0
    for i in range(stamps.size):
        if f < 0 or stamps[i] - anchor > tol_ns or last[owner[i]] == f:
            f += 1
            anchor = stamps[i]
        frame[i] = f
        last[owner[i]] = f
    return frame


def _frame_axis(streams: Sequence[IntArray], tol_ns: int) -> tuple[IntArray, list[IntArray]]:
    """Merge the stamps of several streams into one frame axis.

    Parameters
    ----------
    streams : sequence of int64 arrays, each shape (n_i,), sorted, unique, nanoseconds
    tol_ns : int
        Largest spread of stamps merged into one frame, nanoseconds.

    Returns
    -------
    frames : ndarray of int64, shape (n_frames,), nanoseconds, strictly increasing
        The earliest stamp of each frame.
    index : list of int64 arrays, shape (n_i,)
        Frame of each stamp of each stream.
    """
    if not streams:
        return np.zeros(0, np.int64), []
    stamps = np.concatenate(streams).astype(np.int64)
    owner = np.repeat(np.arange(len(streams), dtype=np.int64), [s.size for s in streams])
    order = np.argsort(stamps, kind="stable")
    sorted_stamps = stamps[order]
    frame = _greedy_frames(sorted_stamps, owner[order], len(streams), int(tol_ns))
    first = np.flatnonzero(np.diff(frame, prepend=-1))
    idx = np.empty(stamps.size, dtype=np.int64)
    idx[order] = frame
    bounds = np.cumsum([0] + [x.size for x in streams])
    return sorted_stamps[first], [idx[a:b] for a, b in itertools.pairwise(bounds)]


# ====================================================================== tf
@dataclass
class _Tree:
    """The tf tree: per child frame its parent and sample series."""

    parent: dict[str, str]
    dynamic: dict[str, _Series]
    static: dict[str, _Series]

    def path(self, frame: str) -> list[str]:
        """Child frames from the tree's root down to ``frame`` (empty for the root)."""
        out: list[str] = []
        while frame in self.parent:
            out.append(frame)
            frame = self.parent[frame]
        return out[::-1]

    def root(self, frame: str) -> str:
        while frame in self.parent:
            frame = self.parent[frame]
        return frame

    def edge_at(self, child: str, t_ns: IntArray) -> tuple[FloatArray, FloatArray, BoolArray]:
        """Pose of ``child`` in its parent at times ``t_ns``, shapes (n, 3), (n, 4), (n,)."""
        if child in self.dynamic:
            return _interpolate(self.dynamic[child], t_ns)
        st = self.static[child]
        i = np.clip(np.searchsorted(st.stamps, t_ns, side="right") - 1, 0, None)
        return st.pose[i, :3], st.pose[i, 3:], st.visible[i]

    def lookup(
        self, frame: str, t_ns: IntArray, *, base: str | None = None
    ) -> tuple[FloatArray, FloatArray, BoolArray]:
        """Pose of ``frame`` in its ancestor ``base`` (default the tree's root) at times ``t_ns``.

        Returns positions (n, 3), quaternions (n, 4) and ``ok`` (n,), False where a
        transform on the path is unknown at that time.
        """
        path = self.path(frame)
        if base is not None:
            path = path[len(self.path(base)) :]
        n = t_ns.size
        p, q, ok = np.zeros((n, 3)), se3.quat_identity((n,)), np.ones(n, dtype=bool)
        for i, child in enumerate(path):
            ep, eq, eok = self.edge_at(child, t_ns)
            p, q = (ep, eq) if i == 0 else se3.pose_compose(p, q, ep, eq)
            ok = ok & eok
        return p, q, ok


def _interpolate(series: _Series, t_ns: IntArray) -> tuple[FloatArray, FloatArray, BoolArray]:
    """Linear / slerp interpolation of a sample series, no extrapolation; exact at samples."""
    s = series.stamps
    n = s.size
    hi = np.searchsorted(s, t_ns, side="left")
    hic = np.minimum(hi, n - 1)
    lo = np.maximum(hi - 1, 0)
    exact = (hi < n) & (s[hic] == t_ns)
    inside = (hi > 0) & (hi < n)
    span = (s[hic] - s[lo]).astype(np.float64)
    w = np.where(inside, (t_ns - s[lo]) / np.where(span > 0, span, 1.0), 0.0)
    p0, p1 = series.pose[lo, :3], series.pose[hic, :3]
    p = p0 + w[:, None] * (p1 - p0)
    q0 = series.pose[lo, 3:] / np.linalg.norm(series.pose[lo, 3:], axis=1, keepdims=True)
    q1 = series.pose[hic, 3:] / np.linalg.norm(series.pose[hic, 3:], axis=1, keepdims=True)
    q = se3.quat_slerp(q0, q1, w)
    p[exact] = series.pose[hic[exact], :3]
    q[exact] = series.pose[hic[exact], 3:]
    ok = np.where(exact, series.visible[hic], inside & series.visible[lo] & series.visible[hic])
    return p, q, ok


def _build_tree(raw: _Raw, src: Path) -> _Tree:
    tree = _Tree(parent={}, dynamic={}, static={})
    for child, edge in raw.edges.items():
        tree.parent[child] = edge.parent
        what = f"tf frame {child!r}"
        if edge.dynamic.stamps:
            tree.dynamic[child] = _series(edge.dynamic, src, what)
        else:
            tree.static[child] = _series(edge.static, src, what)
    for child in tree.parent:
        seen = {child}
        frame = child
        while frame in tree.parent:
            frame = tree.parent[frame]
            if frame in seen:
                raise FormatError(src, f"tf frames form a cycle through {frame!r}", where="tf")
            seen.add(frame)
    return tree


def _choose_root(tree: _Tree, src: Path, root_frame: str | None) -> str:
    frames = set(tree.parent) | set(tree.parent.values())
    if root_frame is not None:
        r = _frame_id(root_frame)
        if r not in frames:
            raise FormatError(
                src,
                f"root_frame {root_frame!r} is not a tf frame; frames are "
                f"{', '.join(sorted(frames))}",
                where="tf",
            )
        return r
    size: dict[str, int] = defaultdict(int)
    for child in tree.parent:
        size[tree.root(child)] += 1
    return min(size, key=lambda r: (-size[r], r))


# ================================================================= reading
def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())


def _as_paths(path: PathLike | Sequence[PathLike]) -> list[Path]:
    if isinstance(path, str | os.PathLike):
        return [Path(path)]
    paths = [Path(p) for p in path]
    if not paths:
        raise FormatError("<no path>", "no bag given")
    return paths


def _reader_errors() -> tuple[type[BaseException], ...]:
    from rosbags.highlevel import AnyReaderError
    from rosbags.rosbag1 import ReaderError as ReaderError1
    from rosbags.rosbag2 import ReaderError as ReaderError2
    from rosbags.serde import SerdeError
    from rosbags.typesys import TypesysError

    return (
        AnyReaderError,
        ReaderError1,
        ReaderError2,
        SerdeError,
        TypesysError,
        struct.error,
        EOFError,
        sqlite3.Error,
        UnicodeDecodeError,
        KeyError,
        IndexError,
        ValueError,
    )


def read(
    path: PathLike | Sequence[PathLike],
    *,
    topics: Sequence[str] | None = None,
    root_frame: str | None = None,
    names: Mapping[str, str] | None = None,
    merge_tolerance: float = DEFAULT_MERGE_TOLERANCE,
    object_prefix: str = "ar_",
) -> Demonstration:
    """Read the poses in a ROS 1 or ROS 2 bag.

    Parameters
    ----------
    path : path-like or sequence of path-like
        A ROS 1 ``.bag`` file (or several, read as one recording), a ROS 2 bag
        folder, or a lone ``.mcap`` / ``.db3`` file.
    topics : sequence of str, optional
        Read only these topics; ``/tf`` brings ``/tf_static`` with it. Default:
        every topic that carries poses.
    root_frame : str, optional
        tf frame the tf bodies are expressed in; default the root of the largest
        tf tree. Pose topics whose header frame is in that tree are moved into it.
    names : mapping str -> str, optional
        Body names to use instead of the default ones; keys are topics, tf frame
        ids or default names (``"ar_13"``).
    merge_tolerance : float
        Largest spread of stamps merged into one frame, seconds (see the module
        documentation). Bags written by :func:`write` are read exactly.
    object_prefix : str
        Prefix of the names of world-model objects, followed by their id.

    Returns
    -------
    Demonstration
        ``t`` in seconds from the first frame; poses in metres, x y z w
        quaternions; ``meta`` with ``source``, ``ros_version``,
        ``start_time_unix`` / ``start_time_ns`` (absolute time of ``t = 0``),
        ``topics`` (topic -> what it carried) and ``unused_topics`` (topic ->
        message type).

    Raises
    ------
    FormatError
        Naming the file and the topic / message index (counted from 0 within
        the topic): an empty, damaged or truncated bag, no pose topic, an
        unknown requested topic, a zero-norm quaternion (with its stamp), two
        different poses of one body with the same stamp, a tf frame with two
        parents (a tf tree that changes over time is not supported).
    """
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    paths = _as_paths(path)
    src = paths[0]
    if not np.isfinite(merge_tolerance) or merge_tolerance < 0:
        raise FormatError(src, f"merge_tolerance must be >= 0 s, got {merge_tolerance}")
    for p in paths:
        if not p.exists():
            raise FormatError(p, "no such file or directory")
        if p.is_file() and p.stat().st_size == 0:
            raise FormatError(p, "empty file, expected a ROS bag")
        if p.is_dir() and not (p / "metadata.yaml").is_file():
            raise FormatError(p, "a ROS 2 bag folder needs a metadata.yaml")
    if len(paths) > 1 and any(p.suffix != ".bag" for p in paths):
        raise FormatError(src, "several paths must all be ROS 1 .bag files")
    is2 = src.suffix != ".bag"
    default = get_typestore(Stores.LATEST if is2 else Stores.ROS1_NOETIC)
    try:
        with AnyReader(paths, default_typestore=default) as reader:
            raw = _collect(reader, src, topics)
    except FormatError:
        raise
    except _reader_errors() as exc:
        raise FormatError(src, f"damaged or unreadable bag: {_one_line(exc)}") from None
    return _assemble(
        raw,
        src,
        root_frame=root_frame,
        names=dict(names or {}),
        topics=topics,
        tol_ns=0 if raw.own is not None else round(merge_tolerance * _NS),
        object_prefix=object_prefix,
        sources=paths,
    )


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


def _tf_arrays(
    tree: _Tree, root: str, frame: str, t_ns: IntArray
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """Pose of ``frame`` in ``root`` at times ``t_ns``: positions, quaternions, ok.

    Composed from their lowest common ancestor, so that a frame below ``root``
    gets exactly the composition of the transforms between them.
    """
    above = [*tree.path(root)]
    below = tree.path(frame)
    common = 0
    while common < min(len(above), len(below)) and above[common] == below[common]:
        common += 1
    base = below[common - 1] if common else None
    p, q, ok = tree.lookup(frame, t_ns, base=base)
    if len(above) > common:
        rp, rq, rok = tree.lookup(root, t_ns, base=base)
        p, q = se3.relative_pose(rp, rq, p, q)
        ok = ok & rok
    return p, q, ok


def _in_root(
    series: _Series, tree: _Tree | None, root: str | None
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """Poses of a pose topic, moved into the tf root frame when their frame is in its tree."""
    p, q, ok = series.pose[:, :3], series.pose[:, 3:], series.visible
    frame = series.frame
    if tree is None or root is None or frame == root or tree.root(frame) != tree.root(root):
        return p, q, ok
    fp, fq, fok = _tf_arrays(tree, root, frame, series.stamps)
    p, q = se3.pose_compose(fp, fq, p, q)
    return p, q, ok & fok


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


# ================================================================= writing
def _ros_names(names: Sequence[str]) -> list[str]:
    """Valid, unique ROS name tokens (``a/b_c``) for body names."""
    out: list[str] = []
    used: set[str] = set()
    for name in names:
        tokens = [re.sub(r"\W", "_", tok, flags=re.ASCII) for tok in name.split("/") if tok]
        base = "/".join(f"_{t}" if t[0].isdigit() else t for t in tokens) or "body"
        cand, k = base, 2
        while cand in used:
            cand, k = f"{base}_{k}", k + 1
        used.add(cand)
        out.append(cand)
    return out


def _target(
    p: Path, version: int | None, storage: str | None
) -> tuple[int, Literal["mcap", "sqlite3"], bool]:
    """ROS version, ROS 2 storage, and whether the bag is a single file."""
    suffix = p.suffix.lower()
    if suffix == ".bag":
        if version not in (None, 1) or storage is not None:
            raise FormatError(
                p, f"a .bag file is a ROS 1 bag, got version={version} storage={storage}"
            )
        return 1, "mcap", True
    if version == 1:
        raise FormatError(p, "a ROS 1 bag must end in .bag")
    if version not in (None, 2):
        raise FormatError(p, f"version must be 1 or 2, got {version!r}")
    want = {".mcap": "mcap", ".db3": "sqlite3"}.get(suffix)
    if storage not in (None, "mcap", "sqlite3") or (want and storage not in (None, want)):
        raise FormatError(
            p, f"storage must be 'mcap' or 'sqlite3' matching the suffix, got {storage!r}"
        )
    chosen = want or storage or "mcap"
    return 2, "sqlite3" if chosen == "sqlite3" else "mcap", want is not None


def _stamps(demo: Demonstration, p: Path, version: int) -> tuple[int, IntArray]:
    """Time origin and per-frame stamps, nanoseconds since the Unix epoch."""
    meta = demo.meta
    offsets = np.round(demo.t * _NS).astype(np.int64)
    if isinstance(meta.get("start_time_ns"), int | np.integer):
        origin = int(meta["start_time_ns"])
    elif isinstance(meta.get("start_time_unix"), int | float):
        origin = round(float(meta["start_time_unix"]) * _NS)
    else:
        origin = _NS - min(0, int(offsets[0]))
    stamps = origin + offsets
    limit = (2**32 if version == 1 else 2**31) * _NS
    if stamps[0] <= 0 or stamps[-1] >= limit:
        raise FormatError(
            p,
            f"time stamps from {_fmt_stamp(max(int(stamps[0]), 0))} to "
            f"{_fmt_stamp(int(stamps[-1]))} do not fit a ROS time",
        )
    close = np.flatnonzero(np.diff(stamps) <= 0)
    if close.size:
        raise FormatError(
            p, f"frames {close[0]} and {close[0] + 1} are less than 1 ns apart", where="t"
        )
    return origin, stamps


def _typestore(version: int) -> Typestore:
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    if version == 2:
        return get_typestore(Stores.LATEST)
    store = get_typestore(Stores.ROS1_NOETIC)
    store.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", _TFMESSAGE))
    return store


def _messages(
    demo: Demonstration,
    store: Typestore,
    stamps: IntArray,
    *,
    topic_of: Sequence[str] | None,
    frame_of: Sequence[str],
    root_frame: str,
) -> Iterator[tuple[str, int, Any]]:
    """``(topic, stamp_ns, message)`` in time order; pose topics if ``topic_of`` else /tf."""
    types = store.types
    time_t, header_t = types["builtin_interfaces/msg/Time"], types["std_msgs/msg/Header"]
    point_t, quat_t = types["geometry_msgs/msg/Point"], types["geometry_msgs/msg/Quaternion"]
    has_seq = "seq" in _fields(store, "std_msgs/msg/Header")
    pos, quat, valid = demo.stacked()
    seq = [0] * len(demo)

    def header(b: int, stamp: int, frame: str) -> Any:
        t = time_t(sec=stamp // _NS, nanosec=stamp % _NS)
        seq[b] += 1
        return header_t(seq=seq[b], stamp=t, frame_id=frame) if has_seq else header_t(t, frame)

    for i in range(demo.n_frames):
        ids = np.flatnonzero(valid[:, i]).tolist()
        stamp = int(stamps[i])
        if topic_of is not None:
            pose_t, stamped_t = types["geometry_msgs/msg/Pose"], types[_POSE_STAMPED]
            for b in ids:
                x, y, z = pos[b, i].tolist()
                qx, qy, qz, qw = quat[b, i].tolist()
                pose = pose_t(
                    position=point_t(x=x, y=y, z=z), orientation=quat_t(x=qx, y=qy, z=qz, w=qw)
                )
                yield topic_of[b], stamp, stamped_t(header=header(b, stamp, root_frame), pose=pose)
        elif ids:
            vec_t, tr_t = types["geometry_msgs/msg/Vector3"], types["geometry_msgs/msg/Transform"]
            ts_t = types["geometry_msgs/msg/TransformStamped"]
            transforms = []
            for b in ids:
                x, y, z = pos[b, i].tolist()
                qx, qy, qz, qw = quat[b, i].tolist()
                tr = tr_t(translation=vec_t(x=x, y=y, z=z), rotation=quat_t(x=qx, y=qy, z=qz, w=qw))
                transforms.append(
                    ts_t(
                        header=header(b, stamp, root_frame),
                        child_frame_id=frame_of[b],
                        transform=tr,
                    )
                )
            yield "/tf", stamp, types[_TFMESSAGE](transforms=transforms)


def write(
    demo: Demonstration,
    path: PathLike,
    *,
    version: Literal[1, 2] | None = None,
    storage: Literal["mcap", "sqlite3"] | None = None,
    mode: Literal["pose", "tf"] = "pose",
    root_frame: str = "world",
    overwrite: bool = False,
) -> None:
    """Write a demonstration as a ROS bag (atomically: temporary path, then rename).

    Parameters
    ----------
    demo : Demonstration
    path : path-like
        ``*.bag`` writes ROS 1; ``*.mcap`` / ``*.db3`` a lone ROS 2 storage file;
        any other path a ROS 2 bag folder.
    version : {1, 2}, optional
        ROS version; default from the path.
    storage : {"mcap", "sqlite3"}, optional
        ROS 2 storage of a bag folder; default ``"mcap"``.
    mode : {"pose", "tf"}
        ``"pose"``: one ``geometry_msgs/PoseStamped`` topic ``/thirdhand/<name>/pose``
        per body; ``"tf"``: one ``tf2_msgs/TFMessage`` on ``/tf`` per frame, a
        transform ``root_frame -> <name>`` per valid body.
    root_frame : str
        ``header.frame_id`` of every pose (the demonstration's world frame).
    overwrite : bool
        Replace an existing bag; the old one is removed only once the new one
        is complete.

    Time stamps are ``meta["start_time_ns"]`` (or ``start_time_unix``) plus
    ``t``, rounded to nanoseconds; without a start time ``t = 0`` is written as
    1 s after the Unix epoch.

    Raises
    ------
    FormatError
        The path exists and ``overwrite`` is False, the path and options
        disagree, or the times do not fit ROS time stamps.
    """
    p = Path(path)
    ver, plugin, single = _target(p, version, storage)
    if mode not in ("pose", "tf"):
        raise FormatError(p, f"mode must be 'pose' or 'tf', got {mode!r}")
    if p.exists() and not overwrite:
        raise FormatError(p, "already exists; pass overwrite=True to replace it")
    if not root_frame or _frame_id(root_frame) != root_frame:
        raise FormatError(
            p, f"root_frame must be a tf frame id without leading slash, got {root_frame!r}"
        )
    origin, stamps = _stamps(demo, p, ver)
    ros = _ros_names(demo.body_names)
    topic_of = [f"/thirdhand/{r}/pose" for r in ros] if mode == "pose" else None
    _, _, valid = demo.stacked()
    entries = [
        {
            "info": body_info_to_dict(info),
            **({"topic": topic_of[k]} if topic_of else {"frame": ros[k]}),
        }
        for k, info in enumerate(demo.bodies)
    ]
    header = {
        "format": FORMAT_VERSION,
        "mode": mode,
        "root_frame": root_frame,
        "origin_ns": origin,
        "extra_frames_ns": stamps[~np.any(valid, axis=0)].tolist(),
        "bodies": entries,
        "labels": labels_to_dict(demo.labels),
        "meta": demo.meta,
    }
    store = _typestore(ver)
    messages = _messages(
        demo, store, stamps, topic_of=topic_of, frame_of=ros, root_frame=root_frame
    )
    try:
        meta_msg = store.types[_STRING](data=json.dumps(header))
    except TypeError as exc:
        raise FormatError(p, f"demonstration meta is not JSON-able: {exc}") from None
    types = {t: _POSE_STAMPED for t in topic_of or []} or {"/tf": _TFMESSAGE}
    tmp = p.parent / f".{p.name}.{os.getpid()}.tmp"
    tmp.mkdir(parents=True)
    try:
        if ver == 1:
            built = tmp / p.name
            _write_ros1(built, store, types, meta_msg, int(stamps[0]), messages)
        else:
            built = tmp / (p.stem if single else p.name)
            _write_ros2(built, store, plugin, types, meta_msg, int(stamps[0]), messages)
            if single:
                built = built / f"{built.name}{p.suffix}"
        _replace(built, p)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _write_ros1(
    p: Path,
    store: Typestore,
    types: Mapping[str, str],
    meta_msg: Any,
    first: int,
    messages: Iterator[tuple[str, int, Any]],
) -> None:
    from rosbags.rosbag1 import Writer

    with Writer(p) as w:
        conns = {t: w.add_connection(t, typ, typestore=store) for t, typ in types.items()}
        meta_conn = w.add_connection(META_TOPIC, _STRING, typestore=store)
        w.write(meta_conn, first, store.serialize_ros1(meta_msg, _STRING))
        for topic, stamp, msg in messages:
            w.write(conns[topic], stamp, store.serialize_ros1(msg, types[topic]))


def _write_ros2(
    p: Path,
    store: Typestore,
    plugin: Literal["mcap", "sqlite3"],
    types: Mapping[str, str],
    meta_msg: Any,
    first: int,
    messages: Iterator[tuple[str, int, Any]],
) -> None:
    from rosbags.rosbag2 import StoragePlugin, Writer

    storage = StoragePlugin.MCAP if plugin == "mcap" else StoragePlugin.SQLITE3
    with Writer(p, version=Writer.VERSION_LATEST, storage_plugin=storage) as w:
        conns = {t: w.add_connection(t, typ, typestore=store) for t, typ in types.items()}
        meta_conn = w.add_connection(META_TOPIC, _STRING, typestore=store)
        w.write(meta_conn, first, store.serialize_cdr(meta_msg, _STRING))
        for topic, stamp, msg in messages:
            w.write(conns[topic], stamp, store.serialize_cdr(msg, types[topic]))


def _replace(built: Path, p: Path) -> None:
    """Move a complete new bag to ``p``; an old bag there is removed only afterwards."""
    if p.exists() and (p.is_dir() or built.is_dir()):
        old = p.parent / f".{p.name}.{os.getpid()}.old"
        os.replace(p, old)
        os.replace(built, p)
        if old.is_dir():
            shutil.rmtree(old)
        else:
            old.unlink()
    else:
        os.replace(built, p)
