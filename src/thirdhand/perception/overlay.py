"""Pictures of a head track: pose axes, landmarks, eye boxes and angles drawn on the frames.

``render_overlay(track, out)`` writes a video (``.mp4``, ``.avi``) with every
processed frame annotated, or an image strip (``.png``, ``.jpg``): a grid of
evenly spaced frames with their eye crops. An existing file is kept as
``<name>.bak``; the new one appears complete or not at all.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from thirdhand.errors import ThirdhandError
from thirdhand.fileops import atomic_output, atomic_write_bytes
from thirdhand.perception._deps import cv2
from thirdhand.perception.track import HeadTrack
from thirdhand.perception.video import read_frames

UInt8Array = NDArray[np.uint8]

VIDEO_SUFFIXES = (".mp4", ".avi")
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")
_AXIS_M = 0.06  # drawn axis length, metres at the canonical face's scale


def annotate(frame: UInt8Array, track: HeadTrack, row: int) -> UInt8Array:
    """A copy of ``frame`` with row ``row`` of ``track`` drawn on it (BGR, same size)."""
    cv = cv2()
    img = frame.copy()
    if not track.found[row]:
        cv.putText(img, "no face", (10, 25), cv.FONT_HERSHEY_SIMPLEX, 0.7, (0, 0, 255), 2)
        return img
    for x, y in track.landmarks[row][::4]:
        cv.circle(img, (round(float(x)), round(float(y))), 1, (200, 200, 200), -1)
    for x0, y0, x1, y1 in track.eyes[row]:
        cv.rectangle(img, (int(x0), int(y0)), (int(x1), int(y1)), (0, 255, 255), 1)
    rvec, _ = cv.Rodrigues(track.rotation[row])
    axes = np.array([[0, 0, 0], [_AXIS_M, 0, 0], [0, -_AXIS_M, 0], [0, 0, -_AXIS_M]], float)
    pts, _ = cv.projectPoints(axes, rvec, track.translation[row], track.camera, None)
    p = [tuple(round(float(v)) for v in q) for q in pts.reshape(-1, 2)]
    for end, colour in zip(p[1:], ((0, 0, 255), (0, 255, 0), (255, 0, 0)), strict=True):
        cv.line(img, p[0], end, colour, 2)
    yaw, pitch, roll = track.angles[row]
    text = f"yaw {yaw:+.1f} pitch {pitch:+.1f} roll {roll:+.1f} conf {track.confidence[row]:.2f}"
    cv.putText(img, text, (10, 25), cv.FONT_HERSHEY_SIMPLEX, 0.6, (0, 0, 0), 3)
    cv.putText(img, text, (10, 25), cv.FONT_HERSHEY_SIMPLEX, 0.6, (255, 255, 255), 1)
    return img


def eye_crops(frame: UInt8Array, boxes: NDArray[np.int64]) -> list[UInt8Array]:
    """The eye regions (right, left) cut out of ``frame``, clipped to it (may be empty)."""
    h, w = frame.shape[:2]
    out = []
    for x0, y0, x1, y1 in boxes:
        xa, ya, xb, yb = max(int(x0), 0), max(int(y0), 0), min(int(x1), w), min(int(y1), h)
        out.append(frame[ya : max(yb, ya), xa : max(xb, xa)].copy())
    return out


def _strip(track: HeadTrack, n_tiles: int, tile_width: int) -> UInt8Array:
    cv = cv2()
    rows = np.unique(np.linspace(0, len(track) - 1, n_tiles).round().astype(int))
    wanted = {int(track.frame[r]): int(r) for r in rows}
    tiles = []
    scale = tile_width / track.size[0]
    th = round(track.size[1] * scale)
    for index, _, frame in read_frames(track.source, stop=max(wanted) + 1):
        if index not in wanted:
            continue
        r = wanted[index]
        tile = cv.resize(annotate(frame, track, r), (tile_width, th))
        if track.found[r]:
            side = th // 4
            for k, crop in enumerate(eye_crops(frame, track.eyes[r])):
                if crop.size:
                    tile[th - side :, k * side : (k + 1) * side] = cv.resize(crop, (side, side))
        tiles.append(tile)
    cols = min(4, len(tiles))
    while len(tiles) % cols:
        tiles.append(np.zeros_like(tiles[0]))
    grid = [np.hstack(tiles[i : i + cols]) for i in range(0, len(tiles), cols)]
    return np.asarray(np.vstack(grid), dtype=np.uint8)


def render_overlay(
    track: HeadTrack,
    out: str | os.PathLike[str],
    *,
    n_tiles: int = 8,
    tile_width: int = 320,
) -> Path:
    """Write the annotated frames of ``track`` as a video or an image strip.

    Parameters
    ----------
    track : HeadTrack
        Its ``source`` is read again for the pixels.
    out : path ending in .mp4, .avi (video) or .png, .jpg (strip)
    n_tiles, tile_width : int
        Strip only: number of frames and each tile's width, pixels.

    Returns
    -------
    Path
        ``out``.
    """
    cv = cv2()
    p = Path(out)
    suffix = p.suffix.lower()
    if len(track) == 0:
        raise ThirdhandError(f"{p}: no frames to draw")
    if suffix in IMAGE_SUFFIXES:
        ok, data = cv.imencode(suffix, _strip(track, n_tiles, tile_width))
        if not ok:
            raise ThirdhandError(f"{p}: OpenCV could not encode the strip")
        atomic_write_bytes(p, data.tobytes())
        return p
    if suffix not in VIDEO_SUFFIXES:
        raise ThirdhandError(
            f"{p}: overlay must end in {', '.join(VIDEO_SUFFIXES + IMAGE_SUFFIXES)}"
        )
    fourcc = cv.VideoWriter_fourcc(*("mp4v" if suffix == ".mp4" else "MJPG"))
    step = int(track.frame[1] - track.frame[0]) if len(track) > 1 else 1
    rows = {int(f): r for r, f in enumerate(track.frame)}
    with atomic_output(p) as tmp:
        writer = cv.VideoWriter(str(tmp), fourcc, track.fps / max(step, 1), track.size)
        if not writer.isOpened():
            raise ThirdhandError(f"{p}: OpenCV cannot write this video format here")
        try:
            for index, _, frame in read_frames(track.source, stop=int(track.frame[-1]) + 1):
                if index in rows:
                    writer.write(annotate(frame, track, rows[index]))
        finally:
            writer.release()
    return p
