"""Reading ROS 1 and ROS 2 bags (see :mod:`thirdhand.io.rosbag`)."""

from __future__ import annotations

import os
import sqlite3
import struct
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from thirdhand.demonstration import Demonstration
from thirdhand.errors import FormatError
from thirdhand.io.rosbag.assemble import _assemble
from thirdhand.io.rosbag.collect import _collect, _one_line
from thirdhand.io.rosbag.constants import _NS, _ROS2_SUFFIXES, DEFAULT_MERGE_TOLERANCE, PathLike


def bag_parts(folder: Path) -> list[Path]:
    """The ROS 1 ``.bag`` files directly in ``folder``, sorted by name; empty for a ROS 2 bag.

    A folder of ``.bag`` parts (one recording split in several files, e.g.
    ``part1.bag`` … ``part4.bag``) is read as one recording; a folder with a
    ``metadata.yaml`` is a ROS 2 bag instead.
    """
    p = Path(folder)
    if not p.is_dir() or (p / "metadata.yaml").exists():
        return []
    return sorted(f for f in p.iterdir() if f.suffix.lower() == ".bag" and f.is_file())


def sniff(path: Path) -> bool:
    """A ``.bag``, ``.mcap`` or ``.db3`` file, a ROS 2 bag folder (``metadata.yaml`` and such
    files) or a folder of ROS 1 ``.bag`` parts."""
    p = Path(path)
    if p.is_dir():
        if bag_parts(p):
            return True
        return (p / "metadata.yaml").is_file() and any(
            any(s.lower() in _ROS2_SUFFIXES for s in f.suffixes) for f in p.iterdir()
        )
    return p.is_file() and p.suffix.lower() in (".bag", *_ROS2_SUFFIXES)


def _as_paths(path: PathLike | Sequence[PathLike]) -> list[Path]:
    if isinstance(path, str | os.PathLike):
        parts = bag_parts(Path(path))
        return parts if parts else [Path(path)]
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
        A ROS 1 ``.bag`` file (or several, read as one recording, or a folder
        of them, read in name order), a ROS 2 bag folder, or a lone ``.mcap`` /
        ``.db3`` file.
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
