"""The simulated world of the executor: part poses, constraint detection and world events.

:class:`SimWorld` wraps a :class:`~thirdhand.execute.scene.CollisionScene` and
speaks body poses ``T_world_body`` (4, 4), world frame, metres; the scene holds
mesh parts at their mesh frame. :func:`detect_done` tells from the part poses
alone which constraints hold (online mode's observation), :func:`insertion_axis`
the direction a child backs out of its parent. World events of online mode
(:func:`person_does`, :func:`slip`) change the world between two robot steps.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence

import numpy as np

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.execute.goals import POS_TOL_M, ROT_TOL_RAD, constraint_holds, invert, sample_goals
from thirdhand.execute.grasps import (
    Grasp,
    is_wide_plate,
    mesh_centroid,
    nearest_com,
    pinch_grasps,
)
from thirdhand.execute.layout import NO_GEOMETRY_HINT, LayoutError, Workcell
from thirdhand.execute.robot import Robot
from thirdhand.execute.scene import CollisionScene
from thirdhand.task.constraint import Constraint
from thirdhand.task.meshes import body_triangles, resolve_mesh
from thirdhand.task.model import TaskFile

#: Pinch grasps kept per wide plate (:meth:`SimWorld.plate_grasps`), nearest its centre of
#: mass: each costs the step search its IK solves.
PLATE_GRASPS = 12


def trans(v: Sequence[float] | FloatArray) -> FloatArray:
    """A pure translation (4, 4) by ``v`` (3,), metres."""
    t = np.eye(4)
    t[:3, 3] = v
    return t


class SimWorld:
    """The simulated world: a collision scene plus every part's body pose.

    The scene holds mesh parts at their mesh frame (``T_world_body · mesh_to_body``);
    this class converts, so callers only see body poses (4, 4), world frame.
    """

    def __init__(
        self,
        robot: Robot,
        task: TaskFile,
        cell: Workcell,
        poses: Mapping[str, FloatArray],
        *,
        task_path: str | os.PathLike[str] | None = None,
        search: Sequence[str | os.PathLike[str]] = (),
    ) -> None:
        self.robot = robot
        self.scene = CollisionScene(robot)
        self.scene.add_table(height=cell.table_z, size=cell.table_size, center=cell.table_center)
        for name, pose, size in cell.fixtures:
            self.scene.add_box(name, se3.pose_from_matrix(pose), size)
            self.scene.allow(name, cell.base)
        self.offset: dict[str, FloatArray] = {}
        objs = {o.name: o for o in task.objects}
        self._objects = objs
        self._mesh_from = (task_path, tuple(search))
        self._triangles: dict[str, FloatArray | None] = {}
        self._plate_grasps: dict[str, list[Grasp]] = {}
        for name, pose in poses.items():
            obj = objs[name]
            path = resolve_mesh(obj, task_path, search)
            if path is not None:
                m = obj.mesh_to_body.matrix() if obj.mesh_to_body is not None else np.eye(4)
                self.offset[name] = m
                scale = obj.scale if obj.scale is not None else 1.0
                self.scene.add_object(
                    name, se3.pose_from_matrix(pose @ m), mesh_path=path, scale=scale
                )
            elif obj.bbox_min is not None and obj.bbox_max is not None:
                lo, hi = np.asarray(obj.bbox_min), np.asarray(obj.bbox_max)
                self.offset[name] = np.eye(4)
                self.scene.add_object(
                    name,
                    se3.pose_from_matrix(pose),
                    size=np.maximum(hi - lo, 1e-3),
                    box_center=(lo + hi) / 2.0,
                )
            else:
                raise LayoutError(
                    f"object {name!r}: no mesh and no bounding box to simulate{NO_GEOMETRY_HINT}"
                )

    def triangles(self, name: str) -> FloatArray | None:
        """A part's mesh triangles (t, 3, 3), body frame, metres; None without a mesh."""
        if name not in self._triangles:
            obj = self._objects.get(name)
            self._triangles[name] = (
                None if obj is None else body_triangles(obj, *self._mesh_from)
            )  # fmt: skip
        return self._triangles[name]

    def plate_grasps(self, name: str) -> list[Grasp]:
        """Pinch grasps on a wide plate's narrow features, nearest its centre of mass first.

        :func:`~thirdhand.execute.grasps.pinch_grasps` on the part's mesh, the
        :data:`PLATE_GRASPS` nearest its centre of mass; empty for a part that is no wide
        plate (:func:`~thirdhand.execute.grasps.is_wide_plate`) or has no mesh. Computed
        once per part.
        """
        if name not in self._plate_grasps:
            tri = self.triangles(name)
            found: list[Grasp] = []
            if tri is not None:
                v = tri.reshape(-1, 3)
                if is_wide_plate(v.min(axis=0), v.max(axis=0)):
                    found = nearest_com(pinch_grasps(tri), mesh_centroid(tri), PLATE_GRASPS)
            self._plate_grasps[name] = found
        return self._plate_grasps[name]

    def pose(self, name: str, q: FloatArray | None = None) -> FloatArray:
        """``T_world_body`` of a part (a grasped one needs the arm's ``q``)."""
        t = se3.matrix_from_pose(*self.scene.object_pose(name, q))
        return np.asarray(t @ invert(self.offset[name]), dtype=np.float64)

    def set_pose(self, name: str, pose: FloatArray) -> None:
        """Move a free part to ``T_world_body``."""
        self.scene.set_object_pose(name, se3.pose_from_matrix(pose @ self.offset[name]))

    def poses(self) -> dict[str, FloatArray]:
        """Every free part's body pose."""
        return {n: self.pose(n) for n in self.offset if n != self.scene.attached}

    def apply(self, change: tuple[str, ...], q: FloatArray) -> None:
        """Apply one world change of a :class:`Segment` at configuration ``q``."""
        kind = change[0]
        if kind == "allow":
            self.scene.allow(change[1], change[2])
        elif kind == "disallow":
            self.scene.disallow(change[1], change[2])
        elif kind == "attach":
            self.scene.attach(change[1], q)
        elif kind == "detach":
            self.scene.detach(change[1], q)


def insertion_axis(task: TaskFile, constraint: Constraint) -> FloatArray:
    """Unit vector (3,), child frame: the direction the child backs out of its parent.

    Of the child's body axes (±x, ±y, ±z), the one along which the shortest move
    separates the child's bounding box from the parent's (the parent's box taken
    at the goal and bounded in the child frame) — a leg backs out of its slot
    along its own axis, the chair's back out of its groove along its length.
    """
    objs = {o.name: o for o in task.objects}

    def box(name: str) -> tuple[FloatArray, FloatArray]:
        o = objs[name]
        if o.bbox_min is None or o.bbox_max is None:
            return np.zeros(3), np.zeros(3)
        return np.asarray(o.bbox_min, dtype=np.float64), np.asarray(o.bbox_max, dtype=np.float64)

    c_lo, c_hi = box(constraint.child)
    p_lo, p_hi = box(constraint.parent)
    corners = np.array([[(p_hi if (i >> k) & 1 else p_lo)[k] for k in range(3)] for i in range(8)])
    t_cp = invert(constraint.pose.matrix())
    pc = corners @ t_cp[:3, :3].T + t_cp[:3, 3]
    lo, hi = pc.min(axis=0), pc.max(axis=0)
    moves = np.concatenate([hi - c_lo, c_hi - lo])  # +x +y +z, then -x -y -z
    k = int(np.argmin(moves))
    axis = np.zeros(3)
    axis[k % 3] = 1.0 if k < 3 else -1.0
    return axis


def detect_done(
    world: SimWorld,
    task: TaskFile,
    *,
    pos_tol: float = POS_TOL_M,
    rot_tol: float = ROT_TOL_RAD,
) -> dict[str, bool]:
    """Which constraints hold in the world now (constraint id → bool), from part poses only."""
    poses = world.poses()
    out = {}
    for c in task.constraints:
        if c.parent not in poses or c.child not in poses:
            out[c.id] = False
            continue
        rel = invert(poses[c.parent]) @ poses[c.child]
        out[c.id] = constraint_holds(rel, c, pos_tol=pos_tol, rot_tol=rot_tol)
    return out


#: A world event of online mode: called with the world between two robot steps.
WorldEvent = Callable[[SimWorld], str]


def person_does(task: TaskFile, constraint_id: str, seed: int = 0) -> WorldEvent:
    """A world event: a simulated person puts the constraint's child at its goal.

    The goal is drawn inside the constraint's free DOFs (a person turns a leg
    however it comes).
    """
    c = next(c for c in task.constraints if c.id == constraint_id)

    def event(world: SimWorld) -> str:
        parent = world.pose(c.parent)
        goals, _ = sample_goals(parent, c, 2, seed, include_nominal=False)
        world.set_pose(c.child, goals[0])
        world.scene.allow(c.child, c.parent)
        return f"person: {c.child} onto {c.parent} ({c.id})"

    return event


def slip(task: TaskFile, constraint_id: str, distance: float = 0.04) -> WorldEvent:
    """A world event: the constraint's child slips ``distance`` metres out of its parent."""
    c = next(c for c in task.constraints if c.id == constraint_id)
    axis = insertion_axis(task, c)

    def event(world: SimWorld) -> str:
        moved: FloatArray = world.pose(c.child) @ trans(distance * axis)
        world.set_pose(c.child, moved)
        world.scene.disallow(c.child, c.parent)
        return f"slip: {c.child} out of {c.parent} by {distance:g} m ({c.id})"

    return event
