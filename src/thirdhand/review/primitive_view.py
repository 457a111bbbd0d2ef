"""The 3D drawing of a learned motion: its path and its editable key points.

The path (:class:`~thirdhand.review.primitive_edit.PrimitivePath`) is in the
parent's frame; it is drawn under an anchor frame placed at the parent's
world pose, so the viewer puts it where the parent is. The chosen key point
carries a translation handle: releasing it moves the key point there.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import viser

from thirdhand.arrays import FloatArray
from thirdhand.review.primitive_edit import PrimitivePath
from thirdhand.review.scene3d import SELECTED_RGB, wxyz

#: Colour of the path and of the key points not chosen (a violet apart from the
#: selection orange, the parent blue and the hands' colours).
PATH_RGB = (132, 94, 247)


class PrimitiveView:
    """The path of one motion and its key points (the chosen one in the selection orange).

    Parameters
    ----------
    scene : viser.SceneApi
    root : str
        Scene-tree name of the anchor frame (the parent's pose).
    """

    def __init__(
        self,
        scene: viser.SceneApi,
        root: str = "/motion",
        on_drag: Callable[[int, FloatArray, int | None], None] | None = None,
    ) -> None:
        self.scene = scene
        self.root = root
        #: Called as ``on_drag(index, point, client_id)`` when the chosen key point's
        #: handle is released (point: metres, parent frame).
        self.on_drag = on_drag
        self.anchor = scene.add_frame(root, show_axes=False)
        self._handles: list[viser.SceneNodeHandle] = []
        self.handle: viser.TransformControlsHandle | None = None
        #: What is drawn: the path's key, and the chosen key point (None: nothing drawn).
        self.shown: tuple[str, int] | None = None
        self.key_points: FloatArray = np.zeros((0, 3))

    def clear(self) -> None:
        """Remove the path and its key points."""
        for h in self._handles:
            h.remove()
        self._handles = []
        self.handle = None
        self.shown = None
        self.key_points = np.zeros((0, 3))

    def show(
        self,
        path: PrimitivePath,
        parent_pos: FloatArray,
        parent_quat: FloatArray,
        *,
        chosen: int,
        size: float,
    ) -> None:
        """Draw ``path`` at the parent's world pose (``parent_quat`` x y z w).

        ``size`` (m, the child's extent) scales the key points' spheres.
        """
        self.clear()
        self.anchor.position = np.asarray(parent_pos, dtype=np.float64)
        self.anchor.wxyz = wxyz(parent_quat)
        pts = path.drawn()
        segments = np.stack([pts[:-1], pts[1:]], axis=1).astype(np.float32)
        self._handles.append(
            self.scene.add_line_segments(
                f"{self.root}/path",
                segments,
                colors=PATH_RGB,
                thickness=3.0,
                thickness_units="screen",
            )
        )
        radius = max(0.008, 0.06 * size)
        for i, p in enumerate(path.key_points):
            self._handles.append(
                self.scene.add_icosphere(
                    f"{self.root}/key{i}",
                    radius=radius,
                    color=SELECTED_RGB if i == chosen else PATH_RGB,
                    position=np.asarray(p, dtype=np.float64),
                )
            )
        # The chosen key point can be dragged (translation only; it lives in the
        # anchor, so its position is already in the parent's frame).
        self.handle = self.scene.add_transform_controls(
            f"{self.root}/handle",
            scale=max(0.05, 0.4 * size),
            disable_rotations=True,
            depth_test=False,
            position=np.asarray(path.key_points[chosen], dtype=np.float64),
        )
        self.handle.on_update(self.on_event)
        self._handles.append(self.handle)
        self.shown = (path.key, chosen)
        self.key_points = path.key_points.copy()

    def on_event(self, event: Any) -> None:
        """A drag of the key point's handle: on release, report where it was left."""
        if event.phase != "end" or self.on_drag is None or self.shown is None:
            return
        point = np.asarray(event.target.position, dtype=np.float64)
        self.on_drag(self.shown[1], point, getattr(event, "client_id", None))


__all__ = ["PATH_RGB", "PrimitiveView"]
