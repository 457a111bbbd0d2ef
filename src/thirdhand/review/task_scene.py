"""The review's 3D view of the task: the viser handles of the parts, the floor, the DOF
glyphs, the gizmo and the learned motion, drawn from a task and a
:class:`~thirdhand.review.view.ReviewView`.

Only handles live here; where things go is decided by the pure functions of
:mod:`~thirdhand.review.view`, :mod:`~thirdhand.review.dofs` and
:mod:`~thirdhand.review.scene3d`.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import viser

from thirdhand.arrays import FloatArray
from thirdhand.review import dofs as dofs_mod
from thirdhand.review.gizmo import DofGizmo, GizmoMove
from thirdhand.review.primitive_edit import PrimitivePath
from thirdhand.review.primitive_view import PrimitiveView
from thirdhand.review.scene3d import (
    DofGlyphView,
    PartsView,
    floor_height,
    framed_view,
    front_view,
    selection_colours,
)
from thirdhand.review.view import ReviewView, selected_constraint, selected_parent, shown_poses
from thirdhand.se3 import pose_compose
from thirdhand.task.geometry import DOF_NAMES
from thirdhand.taskfile import TaskFile

Vec3 = tuple[float, float, float]


class TaskScene:
    """The task drawn in a viser scene.

    Parameters
    ----------
    scene : viser.SceneApi
    task : TaskFile
    task_path : Path
        Where the task was read (meshes are looked for beside it).
    meshes : sequence of path-like
        Folders searched for part meshes (then ``THIRDHAND_MESH_PATH``).
    on_click : callable (str, str or None)
        A part clicked: its name and the modifier (``"shift"``, ``"cmd/ctrl"``, None).
    on_gizmo : callable (GizmoMove)
        The gizmo dragged.
    on_key_point : callable (int, ndarray (3,), int or None)
        A key point's handle released: its index, where (m, parent frame), the tab.

    Attributes
    ----------
    parts : PartsView
    grid : viser.GridHandle
    glyphs : DofGlyphView
    gizmo : DofGizmo
    motion_view : PrimitiveView
    """

    def __init__(
        self,
        scene: viser.SceneApi,
        task: TaskFile,
        task_path: Path,
        meshes: Sequence[str | os.PathLike[str]],
        *,
        on_click: Callable[[str, str | None], None],
        on_gizmo: Callable[[GizmoMove], None],
        on_key_point: Callable[[int, FloatArray, int | None], None],
    ) -> None:
        self.parts = PartsView(scene, task, task_path, [Path(m) for m in meshes])
        self.grid = scene.add_grid(
            "/floor",
            width=2.0,
            height=2.0,
            cell_size=0.1,
            section_size=0.5,
            position=(0.0, 0.0, floor_height(task)),
        )
        self.parts.on_click(on_click)
        self.glyphs = DofGlyphView(scene)
        self.gizmo = DofGizmo(scene, on_gizmo)
        self.motion_view = PrimitiveView(scene, on_drag=on_key_point)

    def camera_pose(self) -> tuple[Vec3, Vec3]:
        """Camera position and target looking at every part (:func:`scene3d.front_view`),
        world frame, m."""
        parts = self.parts
        centroids = np.array([parts.world_centroid(n) for n in parts.names]).reshape(-1, 3)
        return front_view(centroids, max(parts.extent.values(), default=0.3))

    def frame(self, client: viser.ClientHandle, name: str) -> None:
        """Point ``client``'s camera at part ``name``, from the direction it looks now."""
        centre = self.parts.world_centroid(name)
        size = self.parts.extent.get(name, 0.1)
        eye, target = framed_view(client.camera.position, client.camera.look_at, centre, size)
        client.camera.position = eye
        client.camera.look_at = target

    def hide_task_marks(self) -> None:
        """No DOF glyphs, gizmo or learned motion (a recording is played back)."""
        self.motion_view.clear()
        self.glyphs.clear()
        self.gizmo.hide()

    def show(self, task: TaskFile, view: ReviewView, path: PrimitivePath | None) -> None:
        """Parts at the keyframe shown, coloured by the selection; the selected constraint's
        DOF glyphs, gizmo and learned motion ``path`` (None: it has none)."""
        poses = shown_poses(task, view)
        self.parts.set_poses({n: (p.pos, p.quat) for n, p in poses.items()})
        parent = selected_parent(task, view)
        self.parts.set_colours(selection_colours(self.parts.names, view.selected, parent))
        c = selected_constraint(task, view)
        child = poses.get(c.child) if c is not None else None
        if c is None or child is None:
            self.hide_task_marks()
            return
        self._show_motion(path, poses.get(c.parent), view.key_point, c.child)
        ap, aq = pose_compose(child.pos, child.quat, c.frame.pos, c.frame.quat)
        ranges = c.free_dof_array()
        classes = [
            dofs_mod.classify_dof(lo, hi, d) for d, (lo, hi) in zip(DOF_NAMES, ranges, strict=True)
        ]
        size = self.parts.extent.get(c.child, 0.1)
        self.glyphs.show(ap, aq, ranges, classes, size=size)
        self.gizmo.show(c, classes, size)

    def _show_motion(
        self, path: PrimitivePath | None, parent: Any, key_point: int, child: str
    ) -> None:
        """Draw the learned motion ``path`` at its parent's pose (or nothing)."""
        if path is None or parent is None:
            self.motion_view.clear()
            return
        size = self.parts.extent.get(child, 0.1)
        self.motion_view.show(path, parent.pos, parent.quat, chosen=key_point, size=size)


__all__ = ["TaskScene"]
