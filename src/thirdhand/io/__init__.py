"""Reading and writing recordings: every format behind one ``load`` / ``save``.

Each format lives in its own module exposing

- ``sniff(path) -> bool``: does this path look like the format (cheap: name, a few bytes)?
- ``read(path, **options) -> Demonstration``
- ``write(demo, path, **options) -> None`` for the writable formats.

``load`` tries them in :data:`FORMATS` order; ``save`` picks by extension or name.
"""

from __future__ import annotations

import importlib
import os
import unicodedata
from pathlib import Path
from types import ModuleType
from typing import Any

from thirdhand.demonstration import Demonstration
from thirdhand.errors import FormatError
from thirdhand.readlimits import check_regular

#: Format name -> module under ``thirdhand.io``, in detection order.
FORMATS: dict[str, str] = {
    "native": "native",
    "motive": "motive",
    "c3d": "c3d",
    "rosbag": "rosbag",
    "mlr": "mlr",
    "articulation": "articulation",
}

#: Extension -> format, for writing.
WRITE_EXTENSIONS: dict[str, str] = {
    ".parquet": "native",
    ".csv": "motive",
    ".c3d": "c3d",
    ".bag": "rosbag",
    ".mcap": "rosbag",
    ".db3": "rosbag",
    ".log": "articulation",
    ".txt": "articulation",
}


def format_module(name: str) -> ModuleType:
    """The module implementing format ``name``."""
    if name not in FORMATS:
        raise FormatError(name, f"unknown format; known formats are {', '.join(FORMATS)}")
    return importlib.import_module(f"thirdhand.io.{FORMATS[name]}")


def detect(path: str | os.PathLike[str]) -> str:
    """Name of the format of ``path``.

    Raises
    ------
    FormatError
        If the path does not exist or no reader recognises it.
    """
    p = Path(path)
    if not p.exists():
        raise FormatError(p, "no such file or directory")
    if not p.is_dir():
        check_regular(p, what="recording file or folder")
    for name in FORMATS:
        if format_module(name).sniff(p):
            return name
    from thirdhand.io.mlr import ANNOTATIONS, ELAN, POSES

    labels = [n for n in (ANNOTATIONS, ELAN) if p.is_dir() and (p / n).is_file()]
    if labels:
        raise FormatError(
            p,
            f"holds labels ({', '.join(labels)}) but no {POSES}: labels without their "
            "recording; put them in the recording's folder beside its poses.dat",
        )
    if p.suffix.lower() in (".mat", ".npy"):
        raise FormatError(
            p,
            "not a recording of bodies: a .mat (Figueroa's labelled layout, LASA shapes) or an "
            ".npy pose track (t x y z [qx qy qz qw]) is read by `thirdhand primitives library` "
            "and `primitives evaluate`",
        )
    if p.suffix.lower() == ".csv":
        raise FormatError(
            p,
            'not a Motive CSV export (no "Format Version" header); a CSV pose track (t x y z '
            "[qx qy qz qw]) is read by `thirdhand primitives library`",
        )
    raise FormatError(
        p, f"unrecognised recording format; readable formats are {', '.join(FORMATS)}"
    )


def load(
    path: str | os.PathLike[str], *, format: str | None = None, **options: Any
) -> Demonstration:
    """Read a recording of any supported format into a :class:`Demonstration`.

    Parameters
    ----------
    path : path-like
        A file (``.parquet``, Motive ``.csv``, ``.c3d``, ROS 1 ``.bag``, articulation
        ``.txt``/``.log``) or a folder (ROS 2 bag, ROS 1 ``.bag`` parts of one recording, 3rdHand
        ``poses.dat`` folder).
    format : str, optional
        Skip detection and use this format.
    **options
        Passed to the format's reader.
    """
    name = format or detect(path)
    demo: Demonstration = format_module(name).read(Path(path), **options)
    return demo


def save(
    demo: Demonstration,
    path: str | os.PathLike[str],
    *,
    format: str | None = None,
    **options: Any,
) -> None:
    """Write a demonstration; the format comes from ``format`` or the extension.

    A folder path without extension writes the 3rdHand ``poses.dat`` format.
    Every format is written atomically (a uniquely named temporary file or
    folder beside ``path``, then one rename); an existing ``path`` is replaced
    and kept as its next numbered backup (``.bak``, ``.bak.1``, …). Whether a
    command may replace it at all is decided before, by
    :func:`thirdhand.fileops.check_output`.
    """
    p = Path(path)
    name = format or WRITE_EXTENSIONS.get(p.suffix.lower(), "mlr" if not p.suffix else "")
    if not name:
        raise FormatError(
            p,
            f"cannot tell the format from the extension {p.suffix!r}; "
            f"writable extensions are {', '.join(sorted(WRITE_EXTENSIONS))} (or a folder)",
        )
    module = format_module(name)
    if not hasattr(module, "write"):
        raise FormatError(p, f"format {name} is read-only")
    for body in demo.body_names:
        bad = [c for c in body if unicodedata.category(c) in ("Cc", "Cf", "Zl", "Zp")]
        if bad or body != body.strip():
            raise FormatError(
                p,
                f"body name {body!r} holds a control character, line break or surrounding "
                "blank; no recording format reads it back the same (rename the body)",
            )
    if name in ("mlr", "rosbag"):
        options.setdefault("overwrite", True)
    module.write(demo, p, **options)


__all__ = ["FORMATS", "detect", "format_module", "load", "save"]
