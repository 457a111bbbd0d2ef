"""A transform gizmo at a constraint frame, limited to the constraint's free DOFs.

By default the gizmo explores: only the free axes are active, each within its
range (viser's limits are relative to the rest pose), and dragging moves the
child as a preview. In editing mode every axis is active and releasing the
gizmo corrects the constraint's pose (the caller applies the edit).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import viser

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.review.scene3d import xyzw
from thirdhand.se3 import pose_compose, pose_invert
from thirdhand.task.constraint import Constraint
from thirdhand.task.geometry import Pose


@dataclass(frozen=True)
class GizmoMove:
    """The gizmo's motion from its rest pose, in the constraint frame.

    Attributes
    ----------
    phase : {"start", "update", "end"}
    pos : ndarray, shape (3,), metres
    quat : ndarray, shape (4,), x y z w
    client_id : int or None
        The tab that dragged it (None: not known, the server itself).
    """

    phase: str
    pos: FloatArray
    quat: FloatArray
    client_id: int | None = None


def moved_child(
    child: Pose, frame: Pose, pos: FloatArray, quat: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """The child's world pose after a motion ``(pos, quat)`` in its constraint frame.

    ``T_world_child' = T_world_child ∘ F ∘ M ∘ F⁻¹`` with ``F`` the constraint frame
    (a pose in the child frame) and ``M`` the motion.

    Returns
    -------
    pos : ndarray, shape (3,), metres, world frame
    quat : ndarray, shape (4,), x y z w
    """
    ip, iq = pose_invert(frame.pos, frame.quat)
    ap, aq = pose_compose(child.pos, child.quat, frame.pos, frame.quat)
    mp, mq = pose_compose(ap, aq, pos, quat)
    return pose_compose(mp, mq, ip, iq)


def dominant_operation(pos: FloatArray, quat: FloatArray) -> str:
    """Effort operation of a gizmo motion: its largest translation (m) or rotation (rad x 0.1 m)."""
    rotvec = se3.rotvec_from_quat(quat)
    scores = np.concatenate([np.abs(pos), 0.1 * np.abs(rotvec)])
    return ("movex", "movey", "movez", "rotx", "roty", "rotz")[int(np.argmax(scores))]


class DofGizmo:
    """The gizmo of the selected constraint.

    Parameters
    ----------
    scene : viser.SceneApi
    on_move : callable
        Called with a :class:`GizmoMove` at every drag event.
    name : str
        Scene-tree name, under the frame where the DOF glyphs are drawn (the
        constraint frame), so its rest pose is the identity.
    """

    def __init__(
        self,
        scene: viser.SceneApi,
        on_move: Callable[[GizmoMove], None],
        name: str = "/dofs/gizmo",
    ) -> None:
        self.scene, self.on_move, self.name = scene, on_move, name
        self.edits = False
        self.handle: viser.TransformControlsHandle | None = None

    def hide(self) -> None:
        """Remove the gizmo."""
        if self.handle is not None:
            self.handle.remove()
            self.handle = None

    def show(self, c: Constraint, classes: Sequence[str], size: float) -> None:
        """Place the gizmo for constraint ``c`` (DOF classes in ``DOF_NAMES`` order)."""
        self.hide()
        ranges = c.free_dof_array()
        free = [cls != "locked" for cls in classes]
        kwargs: dict[str, Any] = {}
        if self.edits:
            axes, no_t, no_r = (True, True, True), False, False
        else:
            axes = (free[0] or free[3], free[1] or free[4], free[2] or free[5])
            no_t, no_r = not any(free[:3]), not any(free[3:])
            if no_t and no_r:
                return
            kwargs["translation_limits"] = tuple((float(lo), float(hi)) for lo, hi in ranges[:3])
            kwargs["rotation_limits"] = tuple((float(lo), float(hi)) for lo, hi in ranges[3:])
        self.handle = self.scene.add_transform_controls(
            self.name,
            scale=max(0.08, 0.5 * size),
            active_axes=axes,
            disable_axes=no_t,
            disable_sliders=no_t or sum(free[:3]) < 2,
            disable_rotations=no_r,
            depth_test=False,
            **kwargs,
        )
        self.handle.on_update(self.on_event)

    def on_event(self, event: Any) -> None:
        """Handle a viser drag event (start, update, end) of the gizmo."""
        target = event.target
        move = GizmoMove(
            phase=str(event.phase),
            pos=np.asarray(target.position, dtype=np.float64),
            quat=np.asarray(xyzw(target.wxyz), dtype=np.float64),
            client_id=getattr(event, "client_id", None),
        )
        self.on_move(move)
