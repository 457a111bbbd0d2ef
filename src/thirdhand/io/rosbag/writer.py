"""Writing a demonstration as a ROS 1 or ROS 2 bag (see :mod:`thirdhand.io.rosbag`)."""

from __future__ import annotations

import os
import re
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from thirdhand import jsontext
from thirdhand.arrays import IntArray
from thirdhand.demonstration import Demonstration, body_info_to_dict, labels_to_dict
from thirdhand.errors import FormatError
from thirdhand.fileops import atomic_output
from thirdhand.io.rosbag.classify import _fields
from thirdhand.io.rosbag.collect import _frame_id
from thirdhand.io.rosbag.constants import (
    _NS,
    _POSE_STAMPED,
    _STRING,
    _TFMESSAGE,
    FORMAT_VERSION,
    META_TOPIC,
    PathLike,
)
from thirdhand.io.rosbag.timeline import _fmt_stamp

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore


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
        raise FormatError(p, "already exists (the command's --force replaces it, keeping a backup)")
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
        meta_msg = store.types[_STRING](data=jsontext.dumps(header, what="the recording's header"))
    except TypeError as exc:
        raise FormatError(p, f"demonstration meta is not JSON-able: {exc}") from None
    types = {t: _POSE_STAMPED for t in topic_of or []} or {"/tf": _TFMESSAGE}
    with atomic_output(p) as built:
        if ver == 1:
            _write_ros1(built, store, types, meta_msg, int(stamps[0]), messages)
        elif single:
            folder = built.parent / p.stem
            _write_ros2(folder, store, plugin, types, meta_msg, int(stamps[0]), messages)
            os.rename(folder / f"{p.stem}{p.suffix}", built)
        else:
            _write_ros2(built, store, plugin, types, meta_msg, int(stamps[0]), messages)


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
