"""The collision world: table, obstacles, placed parts, the robot and a grasped part.

Every body is a coal geometry with a world transform. A configuration is
checked in two phases, batched over many configurations at once: world-frame
bounding boxes of every robot link (numpy, from :class:`~thirdhand.execute.kinematics.Chain`)
against every other body over a fixed list of active pairs, then coal's exact
narrow phase on the pairs whose boxes overlap, stopping at the first contact.

Active pairs: robot link × robot link (the SRDF's disabled pairs removed),
robot link × object, grasped part × object and grasped part × robot link except
the gripper (the report's simplification: finger–part contacts are ignored).
Any pair can be allowed by name (:meth:`CollisionScene.allow`); the group name
``"gripper"`` stands for the robot's hand and finger links, ``"robot"`` for all links.

Penetrations shallower than ``tolerance`` (1 mm by default) count as contact,
not collision, between primitive shapes (robot links, boxes). coal does not
support this for triangle meshes, so the table top is lowered by ``tolerance``:
a mesh part resting on it then clears it. Mesh parts meant to touch each other
(a leg seated in the seat) must be allowed as a pair while they touch.

This module builds the world, as a :class:`~thirdhand.execute.scene_bodies.SceneBodies`
snapshot replaced on every change; which pairs are checked with which margins is
decided in :mod:`thirdhand.execute.pair_table`, and the checks of configurations
and paths are made by :class:`~thirdhand.execute.collision_check.SceneChecks`
(:attr:`CollisionScene.checks`), to which the scene's checking methods delegate.
"""

from __future__ import annotations

import dataclasses
import os

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike

from thirdhand.arrays import BoolArray, FloatArray
from thirdhand.errors import ThirdhandError
from thirdhand.execute import meshes
from thirdhand.execute.collision_check import SceneChecks, world_aabb
from thirdhand.execute.pair_table import GRIPPER, ROBOT
from thirdhand.execute.robot import PoseLike, Robot, pose_matrix
from thirdhand.execute.scene_bodies import Body, SceneBodies, touching_links

__all__ = ["GRIPPER", "ROBOT", "CollisionScene", "SceneError", "robot_bodies"]


class SceneError(ThirdhandError):
    """A scene operation named an unknown object or an impossible attachment."""


def robot_bodies(robot: Robot) -> SceneBodies:
    """The world of a robot alone: its collision geometries and the SRDF's checked pairs.

    Link pairs of which no joint moves either are left out (they never change).
    """
    gm = robot.geometry
    links: list[Body] = []
    joints: list[int] = []
    for g in gm.geometryObjects:
        c, h = meshes.local_aabb(g.geometry)
        link = robot.model.frames[g.parentFrame].name
        links.append(Body(link, g.geometry, g.placement.homogeneous.copy(), c, h))
        joints.append(int(g.parentJoint) - 1)
    link_joint = np.array(joints, dtype=np.intp)
    self_pairs = tuple(
        (int(cp.first), int(cp.second))
        for cp in gm.collisionPairs
        if link_joint[cp.first] >= 0 or link_joint[cp.second] >= 0
    )
    return SceneBodies(
        links=tuple(links),
        link_joint=link_joint,
        self_pairs=self_pairs,
        gripper_links=frozenset(robot.gripper_links),
    )


def resting_links(
    bottom_z: FloatArray, height_fixed: BoolArray, table_height: float, thickness: float
) -> BoolArray:
    """Links allowed to touch a table: those no joint can lift or lower whose lowest point
    is no more than 1 cm below the table's underside (mounted on it, not standing beside
    it on the floor).

    Parameters
    ----------
    bottom_z : ndarray, shape (L,)
        World z of each link's bounding box bottom at home, metres.
    height_fixed : ndarray of bool, shape (L,)
        No joint changes the link's height (no joint moves it, or only joints about
        the vertical).
    table_height, thickness : float
        World z of the top face and thickness of the top, metres.

    Returns
    -------
    ndarray of bool, shape (L,)
    """
    return height_fixed & (bottom_z >= table_height - thickness - 0.01)


class CollisionScene:
    """Collision world around one :class:`Robot`.

    Parameters
    ----------
    robot : Robot
        The arm; its links and SRDF filters are taken from ``robot.geometry``.
    tolerance : float
        Penetration depth, metres, below which two bodies only touch.
    spheres : bool
        Use the sphere layer (:mod:`~thirdhand.execute.sphere_check`) as the broad
        phase and for path checks; False checks as before it (bounding boxes, then
        coal), with the same verdicts, slower. :attr:`use_spheres` may be switched.

    Attributes
    ----------
    checks : SceneChecks
        The checker of this world (pair table, margins, sphere covers, counters).
    n_checks : int
        Configurations checked so far (each :meth:`is_valid` call and each
        interpolated configuration of :meth:`check_path`); reset with
        :meth:`reset_counter`.
    """

    def __init__(self, robot: Robot, *, tolerance: float = 1e-3, spheres: bool = True) -> None:
        self.robot = robot
        self.tolerance = float(tolerance)
        self.checks = SceneChecks(
            robot, robot_bodies(robot), tolerance=self.tolerance, spheres=spheres
        )

    @property
    def use_spheres(self) -> bool:
        """Whether the sphere layer is the broad phase (may be switched)."""
        return self.checks.use_spheres

    @use_spheres.setter
    def use_spheres(self, value: bool) -> None:
        self.checks.use_spheres = bool(value)

    @property
    def n_checks(self) -> int:
        """Configurations checked so far (see the class notes)."""
        return self.checks.n_checks

    # -- building the world -----------------------------------------------------------

    @property
    def objects(self) -> list[str]:
        """Names of the objects in the world (the grasped one included)."""
        state = self.checks.bodies
        names = [b.name for b in state.objects]
        if state.attached is not None:
            names.append(state.attached.name)
        return names

    @property
    def attached(self) -> str | None:
        """Name of the grasped object, or None."""
        part = self.checks.bodies.attached
        return None if part is None else part.name

    def add_table(
        self,
        *,
        height: float = 0.75,
        size: tuple[float, float] = (2.0, 1.6),
        center: tuple[float, float] = (0.0, 0.0),
        thickness: float = 0.05,
        name: str = "table",
    ) -> None:
        """Add a table top: a box whose upper face is at ``z = height``.

        The robot's links that no joint can lift or lower (its base, and a first
        link turning about the vertical) are allowed to touch it when the robot is
        mounted on it (Panda), not when such a link reaches below the table's
        underside (Baxter's pedestal stands on the floor: the table must clear it,
        or every configuration is in collision; :func:`resting_links`). The box's
        top is ``tolerance`` below ``height`` so that mesh parts resting at
        ``height`` do not collide with it.

        Parameters
        ----------
        height : float
            World z of the top face, metres (``Demonstration.meta["table_z_m"]``).
        size : tuple of 2 floats
            Extent along world x and y, metres.
        center : tuple of 2 floats
            World x, y of the top's centre, metres.
        thickness : float
            Thickness of the top, metres.
        name : str
            Object name.
        """
        pos = np.array([center[0], center[1], height - self.tolerance - thickness / 2.0])
        self.add_box(name, (pos, np.array([0.0, 0.0, 0.0, 1.0])), (size[0], size[1], thickness))
        chain = self.robot.chain
        tj = chain.joint_transforms(self.robot.home[None])[0]
        vertical = np.abs(tj[:, :3, :3] @ chain.axes[:, :, None])[:, 2, 0] > 1 - 1e-9
        t_home = self.checks.transforms(self.robot.home[None])[0]
        state = self.checks.bodies
        joints = state.link_joint.tolist()
        height_fixed = np.array(
            [j < 0 or bool(np.all(vertical[chain.ancestors(j)])) for j in joints]
        )
        bottom = np.empty(len(joints))
        for i, link in enumerate(state.links):
            c, h = world_aabb(t_home[i], link.center, link.half)
            bottom[i] = c[2] - h[2]
        for k in np.flatnonzero(resting_links(bottom, height_fixed, height, thickness)).tolist():
            self.allow(state.links[k].name, name)

    def add_box(self, name: str, pose: PoseLike, size: ArrayLike) -> None:
        """Add a box obstacle of full sides ``size`` (3,), metres, centred at ``pose`` (world)."""
        self.add_geometry(name, meshes.box(size), pose)

    def add_object(
        self,
        name: str,
        pose: PoseLike,
        *,
        mesh_path: str | os.PathLike[str] | None = None,
        size: ArrayLike | None = None,
        scale: float = 1e-3,
        box_center: ArrayLike = (0.0, 0.0, 0.0),
    ) -> None:
        """Add a part: its STL mesh, or a box when there is no mesh.

        Parameters
        ----------
        name : str
            Unique object name (the part's body name).
        pose : pose
            Pose of the part's frame in the world.
        mesh_path : path-like, optional
            STL in the part's frame; coordinates times ``scale`` are metres.
        size : array_like, shape (3,), optional
            Box sides, metres, used when ``mesh_path`` is None.
        scale : float
            Mesh units to metres (1e-3 for the 3rdHand millimetre meshes).
        box_center : array_like, shape (3,)
            Centre of the fallback box in the part's frame, metres.

        Raises
        ------
        SceneError
            If neither a mesh nor a size is given, or the name is taken.
        FormatError
            If the mesh cannot be read.
        """
        if mesh_path is not None:
            self.add_geometry(name, meshes.load_mesh(mesh_path, scale), pose)
            return
        if size is None:
            raise SceneError(f"object {name!r}: give a mesh_path or a box size")
        offset = np.eye(4)
        offset[:3, 3] = np.asarray(box_center, dtype=np.float64)
        self.add_geometry(name, meshes.box(size), pose, offset=offset)

    def add_geometry(
        self,
        name: str,
        geometry: coal.CollisionGeometry,
        pose: PoseLike,
        *,
        offset: FloatArray | None = None,
    ) -> None:
        """Add an object of any coal geometry, its part frame at ``pose`` (world).

        ``offset`` (4, 4) places the geometry in the part's frame (default: identity).

        Raises
        ------
        SceneError
            If the name is taken (by an object, a link or a group).
        """
        state = self.checks.bodies
        if (
            name in self.objects
            or name in (GRIPPER, ROBOT)
            or any(link.name == name for link in state.links)
        ):
            raise SceneError(f"object {name!r}: the name is already used in the scene")
        c, h = meshes.local_aabb(geometry)
        off = np.eye(4) if offset is None else offset
        body = Body(name, geometry, pose_matrix(pose) @ off, c, h, off)
        self.checks.update(dataclasses.replace(state, objects=(*state.objects, body)))

    def _body(self, name: str) -> Body:
        body = self.checks.bodies.find(name)
        if body is None:
            raise SceneError(f"unknown object {name!r}; the scene has {sorted(self.objects)}")
        return body

    def set_object_pose(self, name: str, pose: PoseLike) -> None:
        """Move a free (not grasped) object to ``pose`` in the world.

        Raises
        ------
        SceneError
            If the object is unknown or currently grasped.
        """
        if self.attached == name:
            raise SceneError(f"object {name!r} is grasped: detach it before moving it")
        body = self._body(name)
        moved = dataclasses.replace(body, transform=pose_matrix(pose) @ body.offset)
        state = self.checks.bodies
        objects = tuple(moved if b is body else b for b in state.objects)
        self.checks.update(dataclasses.replace(state, objects=objects), moved=False)

    def object_pose(self, name: str, q: ArrayLike | None = None) -> tuple[FloatArray, FloatArray]:
        """Pose ``(pos, quat)`` of an object in the world; a grasped one needs the arm's ``q``."""
        from thirdhand import se3

        body = self._body(name)
        if self.checks.bodies.attached is body:
            if q is None:
                raise SceneError(f"object {name!r} is grasped: its pose depends on q")
            t = self.robot.tool_transforms(self.robot.check_q(q)[None])[0] @ body.transform
        else:
            t = body.transform
        return se3.pose_from_matrix(t @ np.linalg.inv(body.offset))

    def remove_object(self, name: str) -> None:
        """Remove an object (grasped or not) from the world."""
        body = self._body(name)
        state = self.checks.bodies
        allowed = frozenset(p for p in state.allowed if name not in p)
        if state.attached is body:
            state = dataclasses.replace(
                state, attached=None, touch_links=frozenset(), allowed=allowed
            )
        else:
            objects = tuple(b for b in state.objects if b is not body)
            state = dataclasses.replace(state, objects=objects, allowed=allowed)
        self.checks.update(state)

    def allow(self, a: str, b: str) -> None:
        """Ignore collisions of ``a`` with ``b``: object/link names, ``"gripper"``, ``"robot"``."""
        state = self.checks.bodies
        allowed = state.allowed | {frozenset((a, b))}
        self.checks.update(dataclasses.replace(state, allowed=allowed), moved=False, posed=False)

    def disallow(self, a: str, b: str) -> None:
        """Undo :meth:`allow` for the pair (no effect if it was not allowed)."""
        state = self.checks.bodies
        allowed = state.allowed - {frozenset((a, b))}
        self.checks.update(dataclasses.replace(state, allowed=allowed), moved=False, posed=False)

    def attach(self, name: str, q: ArrayLike) -> None:
        """Grasp object ``name``: from now on it moves rigidly with the tool frame.

        Its pose relative to the tool is taken at configuration ``q``. It is then
        checked against the other objects and against the robot's links except
        the gripper and any link it already touches at ``q`` (:func:`touching_links`).

        Raises
        ------
        SceneError
            If another object is grasped or the name is unknown.
        """
        state = self.checks.bodies
        if state.attached is not None:
            raise SceneError(f"cannot grasp {name!r}: {state.attached.name!r} is already grasped")
        body = self._body(name)
        qa = self.robot.check_q(q)[None]
        t_tool = self.robot.tool_transforms(qa)[0]
        part = dataclasses.replace(body, transform=np.linalg.inv(t_tool) @ body.transform)
        touch = touching_links(
            state,
            part,
            t_tool @ part.transform,
            self.robot.chain.joint_transforms(qa)[0],
            self.tolerance,
        )
        objects = tuple(b for b in state.objects if b is not body)
        self.checks.update(
            dataclasses.replace(state, objects=objects, attached=part, touch_links=touch)
        )

    def detach(self, name: str, q: ArrayLike) -> None:
        """Release the grasped object where it is at configuration ``q``.

        Raises
        ------
        SceneError
            If ``name`` is not the grasped object.
        """
        state = self.checks.bodies
        if state.attached is None or state.attached.name != name:
            raise SceneError(f"cannot release {name!r}: grasped is {self.attached!r}")
        t_tool = self.robot.tool_transforms(self.robot.check_q(q)[None])[0]
        body = dataclasses.replace(state.attached, transform=t_tool @ state.attached.transform)
        self.checks.update(
            dataclasses.replace(
                state, objects=(*state.objects, body), attached=None, touch_links=frozenset()
            )
        )

    # -- checking (see SceneChecks) ----------------------------------------------------

    def valid_mask(
        self, qs: ArrayLike, *, stop_at_first: bool = False, exact: bool = False
    ) -> BoolArray:
        """Collision-free and within-limits flag of many configurations (n, dof), shape (n,)
        (:meth:`SceneChecks.valid_mask`)."""
        return self.checks.valid_mask(qs, stop_at_first=stop_at_first, exact=exact)

    def is_valid(self, q: ArrayLike) -> bool:
        """True if ``q`` (dof,) is within the joint limits and collision-free."""
        return bool(self.checks.valid_mask(self.robot.check_q(q)[None])[0])

    def collisions(self, q: ArrayLike) -> list[tuple[str, str]]:
        """Every colliding pair of body (link or object) names at ``q`` (dof,), for diagnostics."""
        return self.checks.collisions(q)

    def check_path(
        self,
        qs: ArrayLike,
        *,
        max_step_m: float = 0.01,
        max_step_rad: float = 0.02,
        clearance: bool = True,
        chunk: int = 64,
    ) -> bool:
        """True if a piecewise-linear joint path (n, dof) is collision-free, checked densely
        (:meth:`SceneChecks.check_path`)."""
        return self.checks.check_path(
            qs, max_step_m=max_step_m, max_step_rad=max_step_rad, clearance=clearance, chunk=chunk
        )

    def interpolate(
        self, qs: ArrayLike, *, max_step_m: float = 0.01, max_step_rad: float = 0.02
    ) -> FloatArray:
        """Densely interpolate a joint path (n, dof) so that no point moves more than
        ``max_step_m`` (:meth:`SceneChecks.interpolate`)."""
        return self.checks.interpolate(qs, max_step_m=max_step_m, max_step_rad=max_step_rad)

    def sphere_free_mask(self, qs: ArrayLike, margins: FloatArray | None = None) -> BoolArray:
        """True where the sphere covers alone prove a configuration (n, dof) collision-free,
        shape (n,) (:meth:`SceneChecks.sphere_free_mask`)."""
        return self.checks.sphere_free_mask(qs, margins)

    def path_free_spheres(
        self, qs: ArrayLike, *, max_step_m: float = 0.01, max_step_rad: float = 0.02
    ) -> bool:
        """True if the sphere covers alone prove a path free with :meth:`check_path`'s
        clearance (:meth:`SceneChecks.path_free_spheres`)."""
        return self.checks.path_free_spheres(qs, max_step_m=max_step_m, max_step_rad=max_step_rad)

    def reset_counter(self) -> None:
        """Set the check counters to zero."""
        self.checks.reset_counter()

    # -- peer -------------------------------------------------------------------------

    def to_pinocchio(self) -> tuple[pin.GeometryModel, pin.GeometryData]:
        """The same world as a pinocchio geometry model with the same active pairs.

        For cross-checks and the benchmark: ``pin.computeCollisions(robot.model,
        robot.data, gm, gd, q, True)`` is True exactly when :meth:`is_valid` is
        False (within the joint limits).
        """
        state = self.checks.bodies
        gm = pin.GeometryModel()
        for g in self.robot.geometry.geometryObjects:
            gm.addGeometryObject(g.copy())
        for obj in state.objects:
            gm.addGeometryObject(
                pin.GeometryObject(obj.name, 0, pin.SE3(obj.transform), obj.geometry)
            )
        if state.attached is not None:
            frame = self.robot.model.frames[self.robot.tool_frame_id]
            placement = frame.placement * pin.SE3(state.attached.transform)
            go = pin.GeometryObject(
                state.attached.name, int(frame.parentJoint), placement, state.attached.geometry
            )
            gm.addGeometryObject(go)
        table = self.checks.pair_table()
        for a, b in zip(table.first.tolist(), table.second.tolist(), strict=True):
            gm.addCollisionPair(pin.CollisionPair(min(a, b), max(a, b)))
        gd = pin.GeometryData(gm)
        for k, margin in enumerate(self.checks.pair_margins().tolist()):
            gd.collisionRequests[k].security_margin = margin
        return gm, gd
