"""Head pose from 2D face landmarks and the 3D canonical face model (``cv2.solvePnP``).

The 3rdHand head tracker used OpenCV's POSIT; ``solvePnP`` is its modern
replacement. Frames and conventions:

- camera frame: ``x`` to the image's right, ``y`` down, ``z`` along the optical
  axis (OpenCV's); pinhole intrinsics ``K`` with square pixels, no distortion.
- model frame: :data:`CANONICAL_FACE`, metres, nose tip at the origin, aligned with
  the camera frame for a face looking straight into the camera (the face looks
  along the model's ``−z``).
- ``R_cam_head`` (3, 3) maps model coordinates into the camera frame, ``t`` (3,)
  is the nose tip in the camera frame, metres (its scale is that of the canonical
  face: a person's real face size scales it).

Angles are reported relative to a calibration pose ``R_cal``: the relative
rotation in camera axes ``R_rel = R_cam_head · R_calᵀ`` is split as
``R_rel = R_z(−roll) · R_y(−yaw) · R_x(−pitch)`` (extrinsic x, y, z), so that, in
degrees, **yaw > 0 turns the face towards the image's right** (the person's left),
**pitch > 0 tilts it up**, and **roll > 0 tilts it counter-clockwise as seen in the
image**. Rotating an image counter-clockwise by θ about the principal point adds
exactly θ of roll and nothing else.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.errors import ThirdhandError
from thirdhand.perception._canonical_face import CANONICAL_FACE
from thirdhand.perception._deps import cv2
from thirdhand.perception.landmarks import (
    LEFT_EYE_CORNERS,
    LEFT_IRIS,
    RIGHT_EYE_CORNERS,
    RIGHT_IRIS,
)

#: Indices of the face-mesh points above the nose tip (model ``y < 0``): eyes, brows,
#: forehead, nose bridge, upper cheeks. They move little when a person talks or
#: smiles, unlike the lips and jaw; fitting them alone halves the pitch error and
#: keeps the roll error under 2° on frames rotated by ±40° (see the tests).
RIGID_POINTS: NDArray[np.int64] = np.flatnonzero(CANONICAL_FACE[:, 1] < 0.0)

__all__ = [
    "CANONICAL_FACE",
    "RIGID_POINTS",
    "HeadPose",
    "camera_matrix",
    "euler_from_relative",
    "eye_boxes",
    "relative_rotation",
    "solve_head_pose",
]


def camera_matrix(width: int, height: int, *, focal_px: float | None = None) -> FloatArray:
    """Pinhole intrinsics with the principal point at the image centre.

    Parameters
    ----------
    width, height : int, pixels
    focal_px : float, optional
        Focal length in pixels; default ``width`` (a horizontal field of view of
        about 53°, typical of webcams and phones). Angles relative to a
        calibration pose depend little on it.

    Returns
    -------
    ndarray, shape (3, 3)
    """
    f = float(width if focal_px is None else focal_px)
    if not f > 0 or width < 1 or height < 1:
        raise ThirdhandError(f"camera: bad size {width}x{height} or focal length {focal_px}")
    return np.array([[f, 0.0, width / 2.0], [0.0, f, height / 2.0], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class HeadPose:
    """The canonical face fitted to one frame's landmarks.

    Attributes
    ----------
    rotation : ndarray, shape (3, 3)
        ``R_cam_head``: model frame into camera frame.
    translation : ndarray, shape (3,), metres, camera frame
        The nose tip (model origin), at the canonical face's scale.
    rms_px : float
        Root-mean-square reprojection error of the :data:`RIGID_POINTS`, pixels.
    scale_px : float
        Outer eye-corner distance in the image, pixels (the face's size).
    """

    rotation: FloatArray
    translation: FloatArray
    rms_px: float
    scale_px: float

    @property
    def rvec(self) -> FloatArray:
        """Rotation vector of :attr:`rotation`, shape (3,), radians."""
        return se3.rotvec_from_matrix(self.rotation)

    @property
    def confidence(self) -> float:
        """How well a rigid face explains the landmarks, in (0, 1].

        ``exp(−(rms / scale) / 0.2)``: 1 for a perfect fit, about 0.8 for the typical
        residual of a real face (4-5 % of the eye-corner distance: a person is not
        the canonical face), ½ at 14 % (a strong grimace, a mistaken face).
        """
        return float(np.exp(-(self.rms_px / max(self.scale_px, 1e-9)) / 0.2))


def solve_head_pose(
    points_px: ArrayLike,
    camera: ArrayLike,
    *,
    guess: HeadPose | None = None,
) -> HeadPose:
    """Fit the canonical face to 468 face-mesh points.

    Parameters
    ----------
    points_px : array_like, shape (468, 2) or (478, 2), pixels
        Face-mesh landmarks (iris points beyond 468 are ignored; only
        :data:`RIGID_POINTS` enter the fit).
    camera : array_like, shape (3, 3)
        Intrinsics :func:`camera_matrix`.
    guess : HeadPose, optional
        The previous frame's pose (tracking): Levenberg-Marquardt from there.
        Without it the global SQPnP solver runs first.

    Returns
    -------
    HeadPose
    """
    pts = np.ascontiguousarray(np.asarray(points_px, dtype=np.float64)[: len(CANONICAL_FACE)])
    if pts.shape != (len(CANONICAL_FACE), 2) or not np.all(np.isfinite(pts)):
        raise ThirdhandError(f"head pose: expected 468 finite 2D points, got shape {pts.shape}")
    k = np.asarray(camera, dtype=np.float64)
    cv = cv2()
    model = np.ascontiguousarray(CANONICAL_FACE[RIGID_POINTS])
    image = np.ascontiguousarray(pts[RIGID_POINTS])
    if guess is None:
        ok, rvec, tvec = cv.solvePnP(model, image, k, None, flags=cv.SOLVEPNP_SQPNP)
        rvec, tvec = np.asarray(rvec, dtype=np.float64), np.asarray(tvec, dtype=np.float64)
    else:
        rvec = guess.rvec.reshape(3, 1).copy()
        tvec = guess.translation.reshape(3, 1).copy()
        ok = True
    if ok:
        ok, rvec, tvec = cv.solvePnP(model, image, k, None, rvec, tvec, True, cv.SOLVEPNP_ITERATIVE)
    if not ok:
        raise ThirdhandError("head pose: solvePnP found no pose for these landmarks")
    rvec = np.asarray(rvec, dtype=np.float64).reshape(3)
    tvec = np.asarray(tvec, dtype=np.float64).reshape(3)
    proj, _ = cv.projectPoints(model, rvec, tvec, k, None)
    rms = float(np.sqrt(np.mean(np.sum((proj.reshape(-1, 2) - image) ** 2, axis=1))))
    scale = float(np.linalg.norm(pts[RIGHT_EYE_CORNERS[0]] - pts[LEFT_EYE_CORNERS[1]]))
    rot = se3.matrix_from_rotvec(rvec)
    return HeadPose(rot, tvec, rms, scale)


def relative_rotation(rotation: ArrayLike, calibration: ArrayLike) -> FloatArray:
    """``R_rel = R · R_calᵀ``, camera axes: (..., 3, 3) from (..., 3, 3) and (3, 3)."""
    r = np.asarray(rotation, dtype=np.float64)
    c = np.asarray(calibration, dtype=np.float64)
    return np.asarray(r @ c.T, dtype=np.float64)


def euler_from_relative(r_rel: ArrayLike) -> FloatArray:
    """Yaw, pitch and roll in degrees of relative rotations (module conventions).

    Parameters
    ----------
    r_rel : array_like, shape (..., 3, 3)

    Returns
    -------
    ndarray, shape (..., 3), degrees: yaw, pitch, roll
    """
    r = np.asarray(r_rel, dtype=np.float64)
    flat = r.reshape(-1, 3, 3)
    ax, ay, az = se3.euler_from_matrix(flat, "xyz", degrees=True).T
    return np.stack([-ay, -ax, -az], axis=-1).reshape(*r.shape[:-2], 3)


def eye_boxes(points_px: ArrayLike, *, scale: float = 1.6) -> NDArray[np.int64]:
    """Square eye regions around the iris centres, for gaze estimation later.

    Parameters
    ----------
    points_px : array_like, shape (478, 2), pixels
        Refined face-mesh landmarks (with the iris points).
    scale : float
        Side of the square over the eye's corner-to-corner width.

    Returns
    -------
    ndarray, shape (2, 4), int
        ``x0, y0, x1, y1`` (pixels, ``x1``/``y1`` exclusive) of the right eye (row 0)
        and the left eye (row 1); not clipped to the image.
    """
    p = np.asarray(points_px, dtype=np.float64)
    out = np.empty((2, 4), dtype=np.int64)
    for row, (iris, corners) in enumerate(
        ((RIGHT_IRIS, RIGHT_EYE_CORNERS), (LEFT_IRIS, LEFT_EYE_CORNERS))
    ):
        c = p[iris[0]]
        half = 0.5 * scale * float(np.linalg.norm(p[corners[0]] - p[corners[1]]))
        out[row] = np.round([c[0] - half, c[1] - half, c[0] + half, c[1] + half]).astype(np.int64)
    return out
