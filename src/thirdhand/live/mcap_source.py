"""A live source reading a ROS 2 MCAP file while it is being written.

:class:`McapSource` follows an ``.mcap`` file as a recorder appends to it
(``ros2 bag record -s mcap``, or thirdhand's own writer) and yields a
:class:`~thirdhand.live.source.Frame` per sample, as :class:`~thirdhand.live.source.ReplaySource`
does for a finished recording. It reads the file with the ``mcap`` package's
:class:`~mcap.stream_reader.StreamReader` through a file object that waits for
more bytes at the end of the file instead of ending; it stops at the file's
footer (the recorder closed it) or after ``idle_s`` seconds without a new byte.
Messages become visible when the recorder finishes the chunk that holds them
(a recorder's chunk size sets the extra delay).

Messages: ``geometry_msgs/msg/PoseStamped`` on one topic per body, decoded with
``rosbags`` (CDR); other topics are skipped. The bodies and their topics are
given, or read from the ``/thirdhand/meta`` message thirdhand's writer puts
first (:mod:`thirdhand.io.rosbag`). A frame gathers the poses stamped within
``tolerance_s`` of its first one, at most one per body; its time is that
stamp minus the recording's origin (``origin_ns`` of the meta message, else
the first stamp), seconds, the clock the offline reader gives the same file. A
message stamped before the frame it would join is dropped and counted
(``late_messages``).

Needs the ``mcap`` package (``pip install 'thirdhand[live]'``).
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from thirdhand.demonstration import BodyInfo, body_info_from_dict
from thirdhand.errors import FormatError, ThirdhandError
from thirdhand.io.rosbag.constants import META_TOPIC
from thirdhand.live.source import Frame

#: The message type a body's topic carries.
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
#: The bytes an MCAP file starts and, once its writer closed it, ends with.
MAGIC = b"\x89MCAP0\r\n"


def being_written(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` is an MCAP file its writer has not closed yet (no closing magic).

    A file that does not start with the MCAP magic is not one (False).
    """
    p = Path(path)
    if p.suffix.lower() != ".mcap" or not p.is_file():
        return False
    with p.open("rb") as f:
        head = f.read(len(MAGIC))
        f.seek(0, os.SEEK_END)
        size = f.tell()
        if head != MAGIC:
            return False
        if size < 2 * len(MAGIC):
            return True
        f.seek(size - len(MAGIC))
        return f.read(len(MAGIC)) != MAGIC


class _Tail:
    """A read-only binary file that, at its end, waits for the writer to append.

    ``read(n)`` returns ``n`` bytes, polling every ``poll_s`` seconds; after
    ``idle_s`` seconds without growth it returns what it has (a short read ends
    the stream reader).
    """

    def __init__(self, path: Path, poll_s: float, idle_s: float) -> None:
        self._f = path.open("rb")
        self._poll, self._idle = poll_s, idle_s

    def read(self, n: int = -1) -> bytes:
        if n is None or n < 0:
            return self._f.read()
        out = bytearray()
        last = time.monotonic()
        while len(out) < n:
            got = self._f.read(n - len(out))
            if got:
                out += got
                last = time.monotonic()
            elif time.monotonic() - last > self._idle:
                break
            else:
                time.sleep(self._poll)
        return bytes(out)

    def close(self) -> None:
        self._f.close()


class McapSource:
    """Frames of an MCAP file as it is written (see the module docstring).

    Parameters
    ----------
    path : path-like
        The ``.mcap`` file (it may not exist yet: waits ``idle_s`` for it).
    bodies : sequence of BodyInfo, optional
        Rows of every frame; default: from the ``/thirdhand/meta`` message.
    topics : mapping of str to str, optional
        Body name per topic; default ``/thirdhand/<name>/pose`` (or the meta
        message's topics).
    meta : mapping, optional
        As a Demonstration's ``meta`` (geometry); default: the meta message's.
    tolerance_s : float
        Stamps within this of a frame's first one join it, seconds.
    poll_s, idle_s : float
        How often to look for new bytes, and how long without any ends the stream.

    Attributes
    ----------
    late_messages : int
        Messages dropped because their stamp was before the frame they would join.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        bodies: Sequence[BodyInfo] | None = None,
        *,
        topics: Mapping[str, str] | None = None,
        meta: Mapping[str, Any] | None = None,
        tolerance_s: float = 0.002,
        poll_s: float = 0.01,
        idle_s: float = 10.0,
    ) -> None:
        try:
            from mcap.stream_reader import StreamReader
        except ImportError:
            raise ThirdhandError(
                "reading an MCAP as it is written needs the mcap package: "
                "pip install 'thirdhand[live]'"
            ) from None
        from rosbags.typesys import Stores, get_typestore

        self.path = Path(path)
        waited = 0.0
        while not self.path.is_file():
            if waited > idle_s:
                raise ThirdhandError(f"{self.path}: no such file after waiting {idle_s:g} s")
            time.sleep(poll_s)
            waited += poll_s
        self._tail = _Tail(self.path, poll_s, idle_s)
        self._records = iter(StreamReader(self._tail).records)  # type: ignore[arg-type]
        self._store = get_typestore(Stores.ROS2_HUMBLE)
        self._schemas: dict[int, str] = {}
        self._channels: dict[int, tuple[str, str]] = {}
        self._tolerance = tolerance_s
        self._origin: int | None = None
        self._pending: list[tuple[str, int, bytes]] = []
        self.late_messages = 0
        #: Whether the stream ended without the file's closing record (the writer
        #: stopped mid-record, or never closed the file).
        self.unclosed = False
        doc = self._meta_message() if bodies is None or meta is None else None
        if bodies is None:
            if doc is None:
                raise FormatError(
                    self.path, "no /thirdhand/meta message first: give the bodies", where=META_TOPIC
                )
            try:
                bodies = [body_info_from_dict(b["info"]) for b in doc["bodies"]]
                topics = topics or {b["topic"]: bodies[k].name for k, b in enumerate(doc["bodies"])}
            except (KeyError, TypeError, ValueError) as exc:
                raise FormatError(self.path, f"malformed thirdhand metadata: {exc!r}") from None
        self.bodies = list(bodies)
        self.meta: dict[str, Any] = dict(meta if meta is not None else (doc or {}).get("meta", {}))
        if doc is not None and isinstance(doc.get("origin_ns"), int):
            self._origin = int(doc["origin_ns"])
        names = [b.name for b in self.bodies]
        topic_map = dict(topics or {f"/thirdhand/{n}/pose": n for n in names})
        unknown = sorted(set(topic_map.values()) - set(names))
        if unknown:
            raise ThirdhandError(f"topics name bodies that are not given: {', '.join(unknown)}")
        self._row = {topic: names.index(n) for topic, n in topic_map.items()}

    def _messages(self) -> Iterator[tuple[str, int, bytes]]:
        """``(topic, log_time_ns, data)`` of every message, as the file grows."""
        import struct

        from mcap.exceptions import McapError
        from mcap.records import Channel, Message, Schema

        while self._pending:
            yield self._pending.pop(0)
        while True:
            try:
                rec = next(self._records)
            except StopIteration:
                return
            except (McapError, struct.error, EOFError, ValueError):
                # The writer stopped mid-record and never closed the file (a crash,
                # a cut recording): the stream ends at its last complete message.
                self.unclosed = True
                return
            if isinstance(rec, Schema):
                self._schemas[rec.id] = rec.name
            elif isinstance(rec, Channel):
                self._channels[rec.id] = (rec.topic, self._schemas.get(rec.schema_id, ""))
            elif isinstance(rec, Message) and rec.channel_id in self._channels:
                yield self._channels[rec.channel_id][0], rec.log_time, rec.data

    def _meta_message(self) -> dict[str, Any] | None:
        """The ``/thirdhand/meta`` JSON, when it is the first message (else None)."""
        for topic, stamp, data in self._messages():
            if topic == META_TOPIC:
                msg: Any = self._store.deserialize_cdr(data, "std_msgs/msg/String")
                try:
                    doc = json.loads(msg.data)
                except ValueError as exc:
                    raise FormatError(self.path, f"malformed thirdhand metadata: {exc}") from None
                return doc if isinstance(doc, dict) else None
            self._pending.append((topic, stamp, data))
            return None
        return None

    def __iter__(self) -> Iterator[Frame]:
        n = len(self.bodies)
        pos, quat = np.zeros((n, 3)), np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
        valid = np.zeros(n, dtype=bool)
        first: int | None = None
        last_t = -np.inf
        try:
            for topic, log_time, data in self._messages():
                row = self._row.get(topic)
                if row is None:
                    continue
                msg: Any = self._store.deserialize_cdr(data, POSE_STAMPED)
                st = msg.header.stamp
                stamp = int(st.sec) * 1_000_000_000 + int(st.nanosec) or int(log_time)
                if self._origin is None:
                    self._origin = stamp
                if first is not None and (stamp - first > self._tolerance * 1e9 or valid[row]):
                    yield Frame((first - self._origin) / 1e9, pos, quat, valid, time.perf_counter())
                    last_t = (first - self._origin) / 1e9
                    pos, quat = pos.copy(), quat.copy()
                    valid = np.zeros(n, dtype=bool)
                    first = None
                if first is None:
                    if (stamp - self._origin) / 1e9 <= last_t:
                        self.late_messages += 1
                        continue
                    first = stamp
                elif stamp < first:
                    self.late_messages += 1
                    continue
                p, o = msg.pose.position, msg.pose.orientation
                pos[row] = (p.x, p.y, p.z)
                quat[row] = (o.x, o.y, o.z, o.w)
                valid[row] = True
            if first is not None and self._origin is not None:
                yield Frame((first - self._origin) / 1e9, pos, quat, valid, time.perf_counter())
        finally:
            self._tail.close()


__all__ = ["MAGIC", "McapSource", "being_written"]
