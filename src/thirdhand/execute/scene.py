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

This module builds the world; the pairs and the checks of configurations and
paths are in :mod:`thirdhand.execute.collision_check`.
"""

from __future__ import annotations

import os

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike

from thirdhand.arrays import FloatArray, IndexArray
from thirdhand.errors import ThirdhandError
from thirdhand.execute import meshes
from thirdhand.execute import sphere_check as sc
from thirdhand.execute.collision_check import (
    GRIPPER,
    ROBOT,
    Body,
    PairState,
    SceneChecks,
    coal_transform,
    world_aabb,
)
from thirdhand.execute.robot import PoseLike, Robot, pose_matrix

__all__ = ["GRIPPER", "ROBOT", "CollisionScene", "SceneError"]


class SceneError(ThirdhandError):
    """A scene operation named an unknown object or an impossible attachment."""


class CollisionScene(SceneChecks):
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
    n_checks : int
        Configurations checked so far (each :meth:`is_valid` call and each
        interpolated configuration of :meth:`check_path`); reset with
        :meth:`reset_counter`.
    n_narrow : int
        Exact (coal) pair tests so far.
    """

    def __init__(self, robot: Robot, *, tolerance: float = 1e-3, spheres: bool = True) -> None:
        self.robot = robot
        self.tolerance = float(tolerance)
        self.use_spheres = bool(spheres)
        self.n_checks = 0
        self.n_narrow = 0
        self._requests: dict[float, coal.CollisionRequest] = {}
        self._result = coal.CollisionResult()
        gm = robot.geometry
        self._links: list[Body] = []
        joints = []
        for g in gm.geometryObjects:
            c, h = meshes.local_aabb(g.geometry)
            link = robot.model.frames[g.parentFrame].name
            self._links.append(Body(link, g.geometry, g.placement.homogeneous.copy(), c, h))
            joints.append(int(g.parentJoint) - 1)
        self._link_joint = np.array(joints, dtype=np.intp)
        self._link_names = [b.name for b in self._links]
        self._self_pairs = [
            (int(cp.first), int(cp.second))
            for cp in gm.collisionPairs
            if self._link_joint[cp.first] >= 0 or self._link_joint[cp.second] >= 0
        ]
        self._objects: dict[str, Body] = {}
        self._attached: Body | None = None
        self._t_tool_attached = np.eye(4)
        self._touch_links: set[str] = set()
        self._allowed: set[frozenset[str]] = set()
        self._pairs: tuple[IndexArray, IndexArray] | None = None
        self._lever: FloatArray | None = None
        self._sworld: sc.SphereWorld | None = None
        self._chain_cache: tuple[object, sc.ChainArrays] | None = None
        self._path_margin_cache: dict[float, tuple[FloatArray, FloatArray, IndexArray] | None] = {}
        self._spairs: tuple[IndexArray, sc.PairBlocks, IndexArray, FloatArray] | None = None
        self._fixed: list[FloatArray | None] = []
        self._fixed_dist: dict[tuple[int, int], float] = {}
        self._margin_cache: dict[float, FloatArray] = {}
        self._pairs_key: frozenset[frozenset[str]] = frozenset()
        self._pair_states: dict[frozenset[frozenset[str]], PairState] = {}
        g_idx = self._link_joint >= 0
        self._moving = np.flatnonzero(g_idx)

    # -- building the world -----------------------------------------------------------

    @property
    def objects(self) -> list[str]:
        """Names of the objects in the world (the grasped one included)."""
        names = list(self._objects)
        if self._attached is not None:
            names.append(self._attached.name)
        return names

    @property
    def attached(self) -> str | None:
        """Name of the grasped object, or None."""
        return None if self._attached is None else self._attached.name

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
        or every configuration is in collision). The box's top is ``tolerance``
        below ``height`` so that mesh parts resting at ``height`` do not collide
        with it.

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
        # Links whose height above the table no joint can change (the base, and a
        # first link turning about the vertical) touch it by construction.
        tj = self.robot.chain.joint_transforms(self.robot.home[None])[0]
        vertical = np.abs(tj[:, :3, :3] @ self.robot.chain.axes[:, :, None])[:, 2, 0] > 1 - 1e-9
        t_home = self._transforms(self.robot.home[None])[0]
        for i, j in enumerate(self._link_joint.tolist()):
            if j < 0 or np.all(vertical[self.robot.chain.ancestors(j)]):
                link = self._links[i]
                c, h = world_aabb(t_home[i], link.center, link.half)
                if c[2] - h[2] >= height - thickness - 0.01:
                    self.allow(self._link_names[i], name)

    def add_box(self, name: str, pose: PoseLike, size: ArrayLike) -> None:
        """Add a box obstacle of full sides ``size`` (3,), metres, centred at ``pose`` (world)."""
        self._add(name, meshes.box(size), pose_matrix(pose))

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
        t = pose_matrix(pose)
        if mesh_path is not None:
            self._add(name, meshes.load_mesh(mesh_path, scale), t)
            return
        if size is None:
            raise SceneError(f"object {name!r}: give a mesh_path or a box size")
        offset = np.eye(4)
        offset[:3, 3] = np.asarray(box_center, dtype=np.float64)
        self._add(name, meshes.box(size), t, offset)

    def _add(
        self,
        name: str,
        geometry: coal.CollisionGeometry,
        t_world: FloatArray,
        offset: FloatArray | None = None,
    ) -> None:
        if name in self.objects or name in (GRIPPER, ROBOT) or name in self._link_names:
            raise SceneError(f"object {name!r}: the name is already used in the scene")
        c, h = meshes.local_aabb(geometry)
        off = np.eye(4) if offset is None else offset
        body = Body(name, geometry, t_world @ off, c, h, off)
        self._objects[name] = body
        self._invalidate()

    def _body(self, name: str) -> Body:
        if name in self._objects:
            return self._objects[name]
        if self._attached is not None and self._attached.name == name:
            return self._attached
        raise SceneError(f"unknown object {name!r}; the scene has {sorted(self.objects)}")

    def set_object_pose(self, name: str, pose: PoseLike) -> None:
        """Move a free (not grasped) object to ``pose`` in the world.

        Raises
        ------
        SceneError
            If the object is unknown or currently grasped.
        """
        if self._attached is not None and self._attached.name == name:
            raise SceneError(f"object {name!r} is grasped: detach it before moving it")
        body = self._body(name)
        body.transform = pose_matrix(pose) @ body.offset
        self._sworld = None
        self._invalidate(bodies=False)

    def object_pose(self, name: str, q: ArrayLike | None = None) -> tuple[FloatArray, FloatArray]:
        """Pose ``(pos, quat)`` of an object in the world; a grasped one needs the arm's ``q``."""
        from thirdhand import se3

        body = self._body(name)
        if self._attached is body:
            if q is None:
                raise SceneError(f"object {name!r} is grasped: its pose depends on q")
            t = self.robot.tool_transforms(self.robot.check_q(q)[None])[0] @ body.transform
        else:
            t = body.transform
        return se3.pose_from_matrix(t @ np.linalg.inv(body.offset))

    def remove_object(self, name: str) -> None:
        """Remove an object (grasped or not) from the world."""
        self._body(name)
        if self._attached is not None and self._attached.name == name:
            self._attached = None
            self._touch_links = set()
        else:
            del self._objects[name]
        self._allowed = {p for p in self._allowed if name not in p}
        self._invalidate()

    def allow(self, a: str, b: str) -> None:
        """Ignore collisions of ``a`` with ``b``: object/link names, ``"gripper"``, ``"robot"``."""
        self._allowed.add(frozenset((a, b)))
        self._invalidate(bodies=False, poses=False)

    def disallow(self, a: str, b: str) -> None:
        """Undo :meth:`allow` for the pair (no effect if it was not allowed)."""
        self._allowed.discard(frozenset((a, b)))
        self._invalidate(bodies=False, poses=False)

    def attach(self, name: str, q: ArrayLike) -> None:
        """Grasp object ``name``: from now on it moves rigidly with the tool frame.

        Its pose relative to the tool is taken at configuration ``q``. It is then
        checked against the other objects and against the robot's links except
        the gripper and any link it already touches at ``q``.

        Raises
        ------
        SceneError
            If another object is grasped or the name is unknown.
        """
        if self._attached is not None:
            raise SceneError(f"cannot grasp {name!r}: {self._attached.name!r} is already grasped")
        body = self._body(name)
        t_tool = self.robot.tool_transforms(self.robot.check_q(q)[None])[0]
        del self._objects[name]
        body.transform = np.linalg.inv(t_tool) @ body.transform
        self._attached = body
        self._touch_links = set()
        self._invalidate()
        tf_obj = coal_transform(t_tool @ body.transform)
        tj = self.robot.chain.joint_transforms(self.robot.check_q(q)[None])[0]
        for i, link in enumerate(self._links):
            j = self._link_joint[i]
            t_link = link.transform if j < 0 else tj[j] @ link.transform
            self._result.clear()
            if coal.collide(
                link.geometry,
                coal_transform(t_link),
                body.geometry,
                tf_obj,
                self._request(self._margin(link, body)),
                self._result,
            ):
                self._touch_links.add(link.name)

    def detach(self, name: str, q: ArrayLike) -> None:
        """Release the grasped object where it is at configuration ``q``.

        Raises
        ------
        SceneError
            If ``name`` is not the grasped object.
        """
        if self._attached is None or self._attached.name != name:
            raise SceneError(f"cannot release {name!r}: grasped is {self.attached!r}")
        body = self._attached
        t_tool = self.robot.tool_transforms(self.robot.check_q(q)[None])[0]
        body.transform = t_tool @ body.transform
        self._objects[name] = body
        self._attached = None
        self._touch_links = set()
        self._invalidate()

    # -- peer -------------------------------------------------------------------------

    def to_pinocchio(self) -> tuple[pin.GeometryModel, pin.GeometryData]:
        """The same world as a pinocchio geometry model with the same active pairs.

        For cross-checks and the benchmark: ``pin.computeCollisions(robot.model,
        robot.data, gm, gd, q, True)`` is True exactly when :meth:`is_valid` is
        False (within the joint limits).
        """
        gm = pin.GeometryModel()
        for g in self.robot.geometry.geometryObjects:
            gm.addGeometryObject(g.copy())
        for obj in self._objects.values():
            gm.addGeometryObject(
                pin.GeometryObject(obj.name, 0, pin.SE3(obj.transform), obj.geometry)
            )
        if self._attached is not None:
            fid = self.robot._tool_fid
            frame = self.robot.model.frames[fid]
            placement = frame.placement * pin.SE3(self._attached.transform)
            go = pin.GeometryObject(
                self._attached.name, int(frame.parentJoint), placement, self._attached.geometry
            )
            gm.addGeometryObject(go)
        first, second = self._active_pairs()
        for a, b in zip(first.tolist(), second.tolist(), strict=True):
            gm.addCollisionPair(pin.CollisionPair(min(a, b), max(a, b)))
        gd = pin.GeometryData(gm)
        for k, margin in enumerate(self._pair_margins().tolist()):
            gd.collisionRequests[k].security_margin = margin
        return gm, gd
