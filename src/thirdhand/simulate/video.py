"""The run's video: offscreen frames (no GPU: Mesa's EGL or OSMesa) with the step's name, MP4.

MuJoCo picks its OpenGL back end from ``MUJOCO_GL`` when it is first imported;
:func:`choose_backend` sets ``egl`` unless the user chose one (``osmesa`` needs
Debian's ``libosmesa6`` and ``PYOPENGL_PLATFORM=osmesa``). When no renderer can
be made, :func:`open_video` says why and the run is simulated without a video.
Frames are encoded to H.264 by the ``ffmpeg`` that ``imageio-ffmpeg`` ships.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from thirdhand.arrays import FloatArray


def choose_backend() -> str:
    """Set ``MUJOCO_GL`` (``egl`` unless set) before MuJoCo is imported; returns it."""
    gl = os.environ.setdefault("MUJOCO_GL", "egl")
    if gl == "osmesa":
        os.environ.setdefault("PYOPENGL_PLATFORM", "osmesa")
    return gl


#: The fixed camera that sees the work cell: azimuth and elevation, degrees.
FRONT_AZIMUTH = 150.0
FRONT_ELEVATION = -28.0


def front_camera(lookat: FloatArray, distance: float) -> Any:
    """The fixed camera of the run's video (a ``mujoco.MjvCamera``).

    Parameters
    ----------
    lookat : ndarray, shape (3,)
        Point the camera looks at, world frame, metres.
    distance : float
        Camera distance from it, metres.
    """
    import mujoco

    camera = mujoco.MjvCamera()
    camera.lookat[:] = lookat
    camera.distance = distance
    camera.azimuth = FRONT_AZIMUTH
    camera.elevation = FRONT_ELEVATION
    return camera


def cell_lookat(robot_base: FloatArray, base_part: FloatArray | None) -> FloatArray:
    """Where the fixed camera looks: between the robot and the base part, 0.1 m up.

    Parameters
    ----------
    robot_base : ndarray, shape (4, 4)
        Robot root pose, world frame.
    base_part : ndarray, shape (4, 4) or None
        The base part's start pose, world frame (None: the robot's root alone).
    """
    robot = np.asarray(robot_base)[:3, 3]
    part = robot if base_part is None else np.asarray(base_part)[:3, 3]
    return np.asarray((part + robot) / 2.0 + [0.0, 0.0, 0.1], dtype=np.float64)


class VideoWriter:
    """Renders frames of a running simulation and encodes them to an MP4 file.

    Parameters
    ----------
    renderer : mujoco.Renderer
    writer
        An ``imageio`` writer open on the temporary output.
    lookat : ndarray, shape (3,)
        Point the camera looks at, world frame, metres.
    distance : float
        Camera distance, metres.
    """

    def __init__(self, renderer: Any, writer: Any, lookat: FloatArray, distance: float) -> None:
        self.renderer = renderer
        self.writer = writer
        self.camera = front_camera(lookat, distance)
        self.frames = 0
        self._font: Any = None

    def __call__(self, model: Any, data: Any, label: str) -> None:
        """Render the current state with ``label`` written on it and append it."""
        self.renderer.update_scene(data, camera=self.camera)
        pixels = self.renderer.render()
        self.writer.append_data(self._caption(pixels, label, float(data.time)))
        self.frames += 1

    def _caption(self, pixels: np.ndarray, label: str, t: float) -> np.ndarray:
        from PIL import Image, ImageDraw, ImageFont

        if self._font is None:
            self._font = ImageFont.load_default(size=max(12, pixels.shape[0] // 28))
        img = Image.fromarray(pixels)
        draw = ImageDraw.Draw(img)
        text = f"{t:6.2f} s  {label}"
        box = draw.textbbox((8, 6), text, font=self._font)
        draw.rectangle((box[0] - 4, box[1] - 3, box[2] + 4, box[3] + 3), fill=(0, 0, 0))
        draw.text((8, 6), text, fill=(255, 255, 255), font=self._font)
        return np.asarray(img)

    def close(self) -> None:
        """Finish the file and free the renderer."""
        try:
            self.writer.close()
        finally:
            self.renderer.close()


def open_video(
    model: Any, path: Path, *, fps: int, width: int, height: int, lookat: FloatArray,
    distance: float,
) -> tuple[VideoWriter | None, str | None]:  # fmt: skip
    """A video writer on ``path``, or None and the reason no frame can be rendered.

    Parameters
    ----------
    model : mujoco.MjModel
    path : pathlib.Path
        The file to encode to (a temporary path; the caller renames it).
    fps, width, height : int
    lookat : ndarray, shape (3,)
    distance : float
    """
    import mujoco

    try:
        renderer = mujoco.Renderer(model, height=height, width=width)
    except Exception as exc:  # any GL failure: missing library, no display, bad back end
        gl = os.environ.get("MUJOCO_GL", "")
        why = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        return None, (
            f"no offscreen renderer (MUJOCO_GL={gl}): {why}; install Debian's libegl1 and "
            "libgl1-mesa-dri (egl) or libosmesa6 (MUJOCO_GL=osmesa)"
        )
    import imageio.v2 as imageio

    writer = imageio.get_writer(
        str(path), format="FFMPEG", mode="I", fps=fps, codec="libx264", quality=7,
        pixelformat="yuv420p", macro_block_size=8,
    )  # fmt: skip
    return VideoWriter(renderer, writer, lookat, distance), None


def count_frames(path: Path) -> int:
    """Frames an MP4 file decodes to (a check that it plays)."""
    import imageio.v2 as imageio

    reader: Any = imageio.get_reader(str(path), format="FFMPEG")
    n = 0
    try:
        for _ in reader:
            n += 1
        return n
    finally:
        reader.close()
