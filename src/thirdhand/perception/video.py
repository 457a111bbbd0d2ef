"""Reading frames from a video file or a still image, with one-line errors.

OpenCV's ``VideoCapture`` fails silently (``isOpened()`` false, or no frame
decoded); here each failure becomes a :class:`~thirdhand.errors.FormatError`
naming the file.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from thirdhand.errors import FormatError
from thirdhand.perception._deps import cv2

UInt8Array = NDArray[np.uint8]

#: File extensions read as a single still image rather than a video.
IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff", ".webp")


@dataclass(frozen=True)
class VideoInfo:
    """What a video file says about itself.

    Attributes
    ----------
    path : str
    width, height : int
        Frame size, pixels.
    fps : float
        Frames per second (1.0 for a still image, 30.0 when the file does not say).
    n_frames : int
        Frame count from the container (may be approximate for some codecs).
    """

    path: str
    width: int
    height: int
    fps: float
    n_frames: int


def _check_path(path: Path) -> None:
    if not path.exists():
        raise FormatError(path, "no such file")
    if path.is_dir():
        raise FormatError(path, "is a folder, expected a video or image file")


def video_info(path: str | os.PathLike[str]) -> VideoInfo:
    """Size, rate and frame count of a video (or a still image) without decoding it all.

    Raises
    ------
    FormatError
        If the file is missing or OpenCV cannot open it as a video or image.
    """
    p = Path(path)
    _check_path(p)
    if p.suffix.lower() in IMAGE_SUFFIXES:
        img = _read_image(p)
        return VideoInfo(str(p), img.shape[1], img.shape[0], 1.0, 1)
    cap = _open(p)
    try:
        w = int(cap.get(cv2().CAP_PROP_FRAME_WIDTH))
        h = int(cap.get(cv2().CAP_PROP_FRAME_HEIGHT))
        fps = float(cap.get(cv2().CAP_PROP_FPS))
        n = int(cap.get(cv2().CAP_PROP_FRAME_COUNT))
    finally:
        cap.release()
    if not fps > 0 or not np.isfinite(fps):
        fps = 30.0
    return VideoInfo(str(p), w, h, fps, max(n, 0))


def _open(p: Path) -> Any:
    cap = cv2().VideoCapture(str(p))
    if not cap.isOpened():
        cap.release()
        raise FormatError(p, "cannot be opened as a video (unknown container or codec, or corrupt)")
    return cap


def _read_image(p: Path) -> UInt8Array:
    img = cv2().imread(str(p), cv2().IMREAD_COLOR)
    if img is None:
        raise FormatError(p, "cannot be decoded as an image")
    return np.asarray(img, dtype=np.uint8)


def read_frames(
    path: str | os.PathLike[str],
    *,
    start: int = 0,
    stop: int | None = None,
    step: int = 1,
) -> Iterator[tuple[int, float, UInt8Array]]:
    """Decode frames ``start, start + step, ... < stop`` of a video or still image.

    Parameters
    ----------
    path : path of a video (anything OpenCV's FFmpeg reads) or an image
    start, stop, step : int
        Frame indices to yield (``stop=None``: to the end).

    Yields
    ------
    index : int
        Frame index in the file.
    time : float
        Seconds, ``index / fps``.
    frame : ndarray, shape (height, width, 3), uint8, BGR
        OpenCV's channel order.

    Raises
    ------
    FormatError
        If the file is missing, cannot be opened, or no frame at all can be decoded.
    """
    if start < 0 or step < 1 or (stop is not None and stop < start):
        raise ValueError(f"bad frame range start={start} stop={stop} step={step}")
    p = Path(path)
    info = video_info(p)
    if p.suffix.lower() in IMAGE_SUFFIXES:
        if start == 0 and (stop is None or stop > 0):
            yield 0, 0.0, _read_image(p)
        return
    cap = _open(p)
    try:
        if start > 0:
            cap.set(cv2().CAP_PROP_POS_FRAMES, start)
        index = start
        decoded = 0
        while stop is None or index < stop:
            ok, frame = cap.read()
            if not ok or frame is None:
                break
            decoded += 1
            if (index - start) % step == 0:
                yield index, index / info.fps, frame
            index += 1
        if decoded == 0 and (stop is None or stop > start):
            raise FormatError(p, f"no frame could be decoded (from frame {start})")
    finally:
        cap.release()
