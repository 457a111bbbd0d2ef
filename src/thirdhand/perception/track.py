"""Head pose over a video: landmarks, ``solvePnP`` in tracking mode, angles from calibration.

::

    from thirdhand.perception import track_head

    track = track_head("face.mp4", calibrate=0)
    track.angles          # (n, 3) yaw, pitch, roll in degrees from frame 0's pose
    track.max_jump()      # the largest frame-to-frame change, degrees
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from thirdhand.arrays import FloatArray
from thirdhand.errors import ThirdhandError
from thirdhand.perception.headpose import (
    HeadPose,
    camera_matrix,
    euler_from_relative,
    eye_boxes,
    relative_rotation,
    solve_head_pose,
)
from thirdhand.perception.landmarks import N_REFINED, FaceMeshTracker
from thirdhand.perception.video import read_frames, video_info

UInt8Array = NDArray[np.uint8]


@dataclass
class HeadTrack:
    """Head pose per processed frame of one video.

    Attributes
    ----------
    source : str
        The video (or image) path.
    size : tuple of int
        Frame width and height, pixels.
    fps : float
    camera : ndarray, shape (3, 3)
        Intrinsics used for the pose.
    frame : ndarray, shape (n,), int
        Indices of the processed frames in the file.
    time : ndarray, shape (n,), seconds
    found : ndarray, shape (n,), bool
        A face was found in the frame. Every per-frame array below is NaN (or -1
        for the boxes) where it was not.
    rotation : ndarray, shape (n, 3, 3)
        ``R_cam_head``, model into camera axes.
    translation : ndarray, shape (n, 3), metres, camera frame
    rms_px, confidence : ndarray, shape (n,)
        Reprojection error (pixels) and fit confidence in (0, 1] (see
        :attr:`HeadPose.confidence`).
    landmarks : ndarray, shape (n, 478, 2), float32, pixels
    eyes : ndarray, shape (n, 2, 4), int
        Eye boxes ``x0, y0, x1, y1`` (right, left), see :func:`eye_boxes`.
    calibration : int
        Index into the arrays (not the file) of the calibration frame, -1 if no face.
    """

    source: str
    size: tuple[int, int]
    fps: float
    camera: FloatArray
    frame: NDArray[np.int64]
    time: FloatArray
    found: NDArray[np.bool_]
    rotation: FloatArray
    translation: FloatArray
    rms_px: FloatArray
    confidence: FloatArray
    landmarks: NDArray[np.float32]
    eyes: NDArray[np.int64]
    calibration: int = -1
    meta: dict[str, Any] = field(default_factory=dict)

    def __len__(self) -> int:
        return int(self.frame.size)

    @property
    def n_found(self) -> int:
        """Frames with a face."""
        return int(np.count_nonzero(self.found))

    @property
    def angles(self) -> FloatArray:
        """Yaw, pitch, roll relative to the calibration frame, shape (n, 3), degrees.

        NaN where no face was found (everywhere if none was).
        """
        out = np.full((len(self), 3), np.nan)
        if self.calibration < 0:
            return out
        rel = relative_rotation(self.rotation[self.found], self.rotation[self.calibration])
        out[self.found] = euler_from_relative(rel)
        return out

    def max_jump(self) -> dict[str, float]:
        """Largest change between consecutive processed frames that both have a face.

        Returns
        -------
        dict
            ``yaw``, ``pitch``, ``roll``: largest absolute change of each angle;
            ``rotation``: largest angle of the relative rotation; degrees.
            ``frame``: the later frame (file index) of the largest rotation jump.
            Zeros with ``frame`` -1 when fewer than two consecutive frames have faces.
        """
        both = self.found[1:] & self.found[:-1]
        if not np.any(both):
            return {"yaw": 0.0, "pitch": 0.0, "roll": 0.0, "rotation": 0.0, "frame": -1}
        idx = np.flatnonzero(both)
        d_ang = np.abs(np.diff(self.angles, axis=0)[idx])
        a, b = self.rotation[idx], self.rotation[idx + 1]
        cos = (np.einsum("nij,nij->n", a, b) - 1.0) / 2.0
        rot = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
        k = int(np.argmax(rot))
        return {
            "yaw": float(d_ang[:, 0].max()),
            "pitch": float(d_ang[:, 1].max()),
            "roll": float(d_ang[:, 2].max()),
            "rotation": float(rot[k]),
            "frame": int(self.frame[idx[k] + 1]),
        }

    def to_dict(self) -> dict[str, Any]:
        """JSON-able summary and per-frame rows (what ``thirdhand headpose --json`` writes)."""
        ang = self.angles
        rows = []
        for i in range(len(self)):
            row: dict[str, Any] = {
                "frame": int(self.frame[i]),
                "time": float(self.time[i]),
                "face": bool(self.found[i]),
            }
            if self.found[i]:
                row.update(
                    yaw=round(float(ang[i, 0]), 3),
                    pitch=round(float(ang[i, 1]), 3),
                    roll=round(float(ang[i, 2]), 3),
                    confidence=round(float(self.confidence[i]), 4),
                    rms_px=round(float(self.rms_px[i]), 3),
                    position_m=[round(float(v), 4) for v in self.translation[i]],
                    eyes=self.eyes[i].tolist(),
                )
            rows.append(row)
        cal = int(self.frame[self.calibration]) if self.calibration >= 0 else None
        return {
            "source": self.source,
            "width": self.size[0],
            "height": self.size[1],
            "fps": self.fps,
            "focal_px": float(self.camera[0, 0]),
            "frames": len(self),
            "frames_with_face": self.n_found,
            "calibration_frame": cal,
            "angles": "yaw right, pitch up, roll counter-clockwise in the image; degrees",
            "max_jump_deg": self.max_jump(),
            "per_frame": rows,
        }


def estimate_head_poses(
    frames: Iterable[tuple[int, float, UInt8Array]],
    *,
    size: tuple[int, int],
    fps: float,
    source: str = "",
    calibrate: int | None = None,
    static: bool = False,
    focal_px: float | None = None,
) -> HeadTrack:
    """Landmarks and head pose for a stream of frames (see :func:`read_frames`).

    Parameters
    ----------
    frames : iterable of (index, time, frame BGR (h, w, 3) uint8)
    size : (width, height), pixels
    fps : float
    source : str
        Where the frames came from (for messages and the JSON).
    calibrate : int, optional
        File index of the frame whose pose is the zero of the angles; default the
        first frame with a face.
    static : bool
        Detect in every frame independently instead of tracking (and solve each
        pose from scratch instead of from the previous one).
    focal_px : float, optional
        See :func:`camera_matrix`.

    Raises
    ------
    ThirdhandError
        If ``calibrate`` names a frame that was not processed or has no face.
    """
    k = camera_matrix(size[0], size[1], focal_px=focal_px)
    idx: list[int] = []
    times: list[float] = []
    poses: list[HeadPose | None] = []
    marks: list[NDArray[np.float32] | None] = []
    previous: HeadPose | None = None
    with FaceMeshTracker(static=static) as tracker:
        for i, t, img in frames:
            faces = tracker.detect(img)
            idx.append(i)
            times.append(t)
            if not faces:
                poses.append(None)
                marks.append(None)
                previous = None
                continue
            pts = faces[0].points
            pose = solve_head_pose(pts, k, guess=None if static else previous)
            poses.append(pose)
            marks.append(pts.astype(np.float32))
            previous = pose
    n = len(idx)
    found = np.array([p is not None for p in poses], dtype=bool)
    rot = np.full((n, 3, 3), np.nan)
    trans = np.full((n, 3), np.nan)
    rms = np.full(n, np.nan)
    conf = np.full(n, np.nan)
    lms = np.full((n, N_REFINED, 2), np.nan, dtype=np.float32)
    eyes = np.full((n, 2, 4), -1, dtype=np.int64)
    for j, (fit, m) in enumerate(zip(poses, marks, strict=True)):
        if fit is None or m is None:
            continue
        rot[j], trans[j], rms[j], conf[j] = (
            fit.rotation,
            fit.translation,
            fit.rms_px,
            fit.confidence,
        )
        lms[j] = m
        eyes[j] = eye_boxes(m)
    frame_idx = np.asarray(idx, dtype=np.int64)
    if calibrate is None:
        cal = int(np.argmax(found)) if np.any(found) else -1
    else:
        hits = np.flatnonzero(frame_idx == calibrate)
        if hits.size == 0:
            raise ThirdhandError(f"{source}: calibration frame {calibrate} was not processed")
        cal = int(hits[0])
        if not found[cal]:
            raise ThirdhandError(f"{source}: no face in calibration frame {calibrate}")
    return HeadTrack(
        source=source,
        size=size,
        fps=fps,
        camera=k,
        frame=frame_idx,
        time=np.asarray(times, dtype=np.float64),
        found=found,
        rotation=rot,
        translation=trans,
        rms_px=rms,
        confidence=conf,
        landmarks=lms,
        eyes=eyes,
        calibration=cal,
        meta={"static": static},
    )


def track_head(
    path: str | os.PathLike[str],
    *,
    calibrate: int | None = None,
    start: int = 0,
    stop: int | None = None,
    step: int = 1,
    static: bool = False,
    focal_px: float | None = None,
) -> HeadTrack:
    """Head pose in frames ``start:stop:step`` of a video (or a still image).

    See :func:`estimate_head_poses` for the parameters; ``step > 1`` tracks on a
    subsampled stream (larger motion between frames).

    Raises
    ------
    FormatError
        If the file is missing, corrupt or not a video.
    ThirdhandError
        See :func:`estimate_head_poses`.
    """
    info = video_info(path)
    return estimate_head_poses(
        read_frames(path, start=start, stop=stop, step=step),
        size=(info.width, info.height),
        fps=info.fps,
        source=os.fspath(path),
        calibrate=calibrate,
        static=static or info.n_frames == 1,
        focal_px=focal_px,
    )
