"""MP4 video of a dataset's cameras: encoding, concatenation and frame-exact decoding.

Every call runs the ``ffmpeg`` executable shipped in ``imageio-ffmpeg`` (the
``sim`` extra), imported only here and only when a video is written or read.
Frames are encoded as LeRobot encodes them with ``vcodec="h264"``: libx264,
``yuv420p``, a key frame every 2 frames (``-g 2``), ``-crf 30``, at the
dataset's frame rate, so frame ``i`` of a file is shown at ``i / fps`` seconds.
An episode is encoded on its own, and the episodes of one file are joined
without re-encoding (ffmpeg's concat demuxer, as LeRobot's
``concatenate_video_files``), so an episode starting at frame ``k`` of a file
starts at ``k / fps`` seconds.
"""

from __future__ import annotations

import os
import re
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from thirdhand.errors import FormatError, OutputError

#: Codec, pixel format and encoder options; ``meta/info.json`` states the first two.
CODEC = "h264"
PIX_FMT = "yuv420p"
_ENCODER = ["-c:v", "libx264", "-pix_fmt", PIX_FMT, "-g", "2", "-crf", "30"]
_PTS = re.compile(rb"\bn:\s*(\d+)\s+pts:\s*(-?\d+)\s+pts_time:\s*(-?[0-9.eE+-]+)")
_STREAM = re.compile(rb"Stream #\S+.*?Video: (\w+).*?, (\w+)[(,].*?, (\d+)x(\d+)")


def _ffmpeg() -> str:
    try:
        import imageio_ffmpeg
    except ImportError:  # pragma: no cover - the sim extra is missing
        raise OutputError(
            "videos need the ffmpeg of imageio-ffmpeg: pip install 'thirdhand[sim]'"
        ) from None
    return str(imageio_ffmpeg.get_ffmpeg_exe())


def _run(args: list[str], *, stdin: bytes | None = None) -> subprocess.CompletedProcess[bytes]:
    return subprocess.run(
        [_ffmpeg(), "-hide_banner", "-nostdin", *args],
        input=stdin,
        capture_output=True,
        check=False,
    )


def _last_line(stderr: bytes) -> str:
    lines = [ln.strip() for ln in stderr.decode("utf-8", "replace").splitlines() if ln.strip()]
    return lines[-1] if lines else "no message"


def encode_frames(frames: NDArray[np.uint8], path: Path, *, fps: int) -> None:
    """Encode RGB frames into a new MP4 file.

    Parameters
    ----------
    frames : ndarray of uint8, shape (n_frames, height, width, 3)
        RGB frames; height and width even (``yuv420p`` halves the colour planes).
    path : pathlib.Path
        The MP4 file to create.
    fps : int
        Frames per second: frame ``i`` is shown at ``i / fps`` s.

    Raises
    ------
    OutputError
        ffmpeg failed (its last line is quoted).
    """
    n, h, w, _ = frames.shape
    args = ["-loglevel", "error", "-f", "rawvideo", "-pix_fmt", "rgb24", "-s", f"{w}x{h}"]
    args += ["-r", str(fps), "-i", "pipe:0", *_ENCODER, "-r", str(fps), "-an", "-y", str(path)]
    done = _run(args, stdin=np.ascontiguousarray(frames).tobytes())
    if done.returncode != 0 or not path.is_file():
        raise OutputError(f"{path}: ffmpeg could not encode {n} frames: {_last_line(done.stderr)}")


def concatenate(parts: list[Path], path: Path) -> None:
    """Join MP4 files of one codec and size into ``path`` without re-encoding.

    Raises
    ------
    OutputError
        ffmpeg failed.
    """
    fd, listing = tempfile.mkstemp(suffix=".ffconcat", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write("ffconcat version 1.0\n")
            for p in parts:
                quoted = str(p.resolve()).replace("'", "'\\''")
                fh.write(f"file '{quoted}'\n")
        args = ["-loglevel", "error", "-f", "concat", "-safe", "0", "-i", listing]
        args += ["-c", "copy", "-movflags", "faststart", "-y", str(path)]
        done = _run(args)
    finally:
        os.unlink(listing)
    if done.returncode != 0 or not path.is_file():
        raise OutputError(
            f"{path}: ffmpeg could not join {len(parts)} episode videos: {_last_line(done.stderr)}"
        )


@dataclass(frozen=True)
class VideoProbe:
    """What a decoder finds in an MP4 file.

    Attributes
    ----------
    codec, pix_fmt : str
        The video stream's codec (``"h264"``) and pixel format (``"yuv420p"``).
    width, height : int
        Frame size, pixels.
    pts : ndarray, shape (n_frames,), seconds
        Presentation time of every decoded frame, in decoding order.
    """

    codec: str
    pix_fmt: str
    width: int
    height: int
    pts: NDArray[np.float64]


def probe(path: Path) -> VideoProbe:
    """Decode ``path`` once and return its stream's format and every frame's time.

    Raises
    ------
    FormatError
        The file holds no decodable video stream.
    """
    done = _run(
        [
            "-loglevel",
            "info",
            "-i",
            str(path),
            "-map",
            "0:v:0",
            "-vf",
            "showinfo",
            "-f",
            "null",
            "-",
        ]
    )
    stream = _STREAM.search(done.stderr)
    if done.returncode != 0 or stream is None:
        raise FormatError(path, f"not a decodable video: {_last_line(done.stderr)}")
    pts = np.array([float(m.group(3)) for m in _PTS.finditer(done.stderr)], dtype=np.float64)
    return VideoProbe(
        codec=stream.group(1).decode(),
        pix_fmt=stream.group(2).decode(),
        width=int(stream.group(3)),
        height=int(stream.group(4)),
        pts=pts,
    )


def decode_frames(path: Path, *, width: int, height: int) -> NDArray[np.uint8]:
    """Every frame of ``path`` as RGB, in presentation order.

    Returns
    -------
    ndarray of uint8, shape (n_frames, height, width, 3)

    Raises
    ------
    FormatError
        ffmpeg could not decode the file, or it decoded a partial frame.
    """
    done = _run(
        [
            "-loglevel",
            "error",
            "-i",
            str(path),
            "-map",
            "0:v:0",
            "-f",
            "rawvideo",
            "-pix_fmt",
            "rgb24",
            "-fps_mode",
            "passthrough",
            "pipe:1",
        ]
    )
    size = width * height * 3
    if done.returncode != 0 or len(done.stdout) % size:
        raise FormatError(path, f"could not decode the video: {_last_line(done.stderr)}")
    return np.frombuffer(done.stdout, dtype=np.uint8).reshape(-1, height, width, 3)
