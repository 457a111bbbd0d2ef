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
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from thirdhand.errors import ThirdhandError
from thirdhand.execute import meshes
from thirdhand.execute.robot import PoseLike, Robot, pose_matrix

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.intp]

GRIPPER = "gripper"
ROBOT = "robot"


class SceneError(ThirdhandError):
    """A scene operation named an unknown object or an impossible attachment."""


@dataclass
class _Body:
    name: str
    geometry: coal.CollisionGeometry
    transform: FloatArray  # T_world_body (objects) or T_joint_geom (robot links), (4, 4)
    center: FloatArray  # local AABB centre (3,)
    half: FloatArray  # local AABB half extents (3,)
    offset: FloatArray = field(default_factory=lambda: np.eye(4))  # T_part_geometry


def _tf(t: FloatArray) -> coal.Transform3s:
    """coal transform of a homogeneous matrix (4, 4)."""
    return coal.Transform3s(np.ascontiguousarray(t[:3, :3]), np.ascontiguousarray(t[:3, 3]))


def _coarse_to_fine(n: int) -> NDArray[np.intp]:
    """A permutation of ``range(n)`` by bit-reversed index: 0, n/2, n/4, 3n/4, ..."""
    bits = max(int(n - 1).bit_length(), 1)
    idx = np.arange(n)
    rev = np.zeros(n, dtype=np.int64)
    for b in range(bits):
        rev |= ((idx >> b) & 1) << (bits - 1 - b)
    return np.argsort(rev, kind="stable").astype(np.intp)


def _world_aabb(
    t: FloatArray, center: FloatArray, half: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """World AABB centres and half extents of boxes under transforms ``t`` (..., 4, 4)."""
    rot = t[..., :3, :3]
    c = np.einsum("...ij,...j->...i", rot, center) + t[..., :3, 3]
    h = np.einsum("...ij,...j->...i", np.abs(rot), half)
    return c, h


class CollisionScene:
    """Collision world around one :class:`Robot`.

    Parameters
    ----------
    robot : Robot
        The arm; its links and SRDF filters are taken from ``robot.geometry``.
    tolerance : float
        Penetration depth, metres, below which two bodies only touch.

    Attributes
    ----------
    n_checks : int
        Configurations checked so far (each :meth:`is_valid` call and each
        interpolated configuration of :meth:`check_path`); reset with
        :meth:`reset_counter`.
    n_narrow : int
        Exact (coal) pair tests so far.
    """

    def __init__(self, robot: Robot, *, tolerance: float = 1e-3) -> None:
        self.robot = robot
        self.tolerance = float(tolerance)
        self.n_checks = 0
        self.n_narrow = 0
        self._requests: dict[float, coal.CollisionRequest] = {}
        self._result = coal.CollisionResult()
        gm = robot.geometry
        self._links: list[_Body] = []
        joints = []
        for g in gm.geometryObjects:
            c, h = meshes.local_aabb(g.geometry)
            link = robot.model.frames[g.parentFrame].name
            self._links.append(_Body(link, g.geometry, g.placement.homogeneous.copy(), c, h))
            joints.append(int(g.parentJoint) - 1)
        self._link_joint = np.array(joints, dtype=np.intp)
        self._link_names = [b.name for b in self._links]
        self._self_pairs = [
            (int(cp.first), int(cp.second))
            for cp in gm.collisionPairs
            if self._link_joint[cp.first] >= 0 or self._link_joint[cp.second] >= 0
        ]
        self._objects: dict[str, _Body] = {}
        self._attached: _Body | None = None
        self._t_tool_attached = np.eye(4)
        self._touch_links: set[str] = set()
        self._allowed: set[frozenset[str]] = set()
        self._pairs: tuple[IntArray, IntArray] | None = None
        self._lever: FloatArray | None = None
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
                c, h = _world_aabb(t_home[i], link.center, link.half)
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
        body = _Body(name, geometry, t_world @ off, c, h, off)
        self._objects[name] = body
        self._invalidate()

    def _body(self, name: str) -> _Body:
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
        return se3.matrix_to_pose(t @ np.linalg.inv(body.offset))

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
        self._invalidate()

    def disallow(self, a: str, b: str) -> None:
        """Undo :meth:`allow` for the pair (no effect if it was not allowed)."""
        self._allowed.discard(frozenset((a, b)))
        self._invalidate()

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
        tf_obj = _tf(t_tool @ body.transform)
        tj = self.robot.chain.joint_transforms(self.robot.check_q(q)[None])[0]
        for i, link in enumerate(self._links):
            j = self._link_joint[i]
            t_link = link.transform if j < 0 else tj[j] @ link.transform
            self._result.clear()
            if coal.collide(
                link.geometry,
                _tf(t_link),
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

    # -- pairs ------------------------------------------------------------------------

    def _invalidate(self) -> None:
        """Forget the cached pair list and lever arms after the world changed."""
        self._pairs = None
        self._lever = None

    def _is_allowed(self, a: str, b: str, a_is_link: bool) -> bool:
        al = self._allowed
        if frozenset((a, b)) in al:
            return True
        if a_is_link:
            if frozenset((ROBOT, b)) in al:
                return True
            if a in self.robot.gripper_links and frozenset((GRIPPER, b)) in al:
                return True
        return False

    def _active_pairs(self) -> tuple[IntArray, IntArray]:
        """Body index pairs: links 0..G-1, objects G..G+E-1, grasped part G+E."""
        if self._pairs is not None:
            return self._pairs
        names = self._link_names
        n_links = len(names)
        objs = list(self._objects.values())
        first: list[int] = []
        second: list[int] = []
        for i, j in self._self_pairs:
            if frozenset((names[i], names[j])) not in self._allowed:
                first.append(i)
                second.append(j)
        for k, obj in enumerate(objs):
            for i in range(n_links):
                if not self._is_allowed(names[i], obj.name, True):
                    first.append(i)
                    second.append(n_links + k)
        if self._attached is not None:
            a_idx = n_links + len(objs)
            a_name = self._attached.name
            for k, obj in enumerate(objs):
                if frozenset((a_name, obj.name)) not in self._allowed:
                    first.append(a_idx)
                    second.append(n_links + k)
            exempt = set(self.robot.gripper_links) | self._touch_links
            for i in range(n_links):
                if names[i] not in exempt and not self._is_allowed(names[i], a_name, True):
                    first.append(a_idx)
                    second.append(i)
        self._pairs = (np.array(first, dtype=np.intp), np.array(second, dtype=np.intp))
        return self._pairs

    def _margin(self, a: _Body, b: _Body) -> float:
        """Contact margin of a pair: ``-tolerance``, or 0 with a mesh (coal's limitation)."""
        mesh = isinstance(a.geometry, coal.BVHModelBase) or isinstance(
            b.geometry, coal.BVHModelBase
        )
        return 0.0 if mesh else -self.tolerance

    def _request(self, margin: float) -> coal.CollisionRequest:
        req = self._requests.get(margin)
        if req is None:
            req = coal.CollisionRequest()
            req.security_margin = margin
            self._requests[margin] = req
        return req

    def _pair_margins(self, clearance: float = 0.0) -> FloatArray:
        """Security margin of every active pair, metres, shape (P,).

        Without clearance, the contact margin. With it, pairs with one moving body
        need ``clearance`` and pairs of two moving bodies twice that.
        """
        first, second = self._active_pairs()
        bodies = self._bodies()
        base = np.array(
            [self._margin(bodies[a], bodies[b]) for a, b in zip(first, second, strict=True)]
        )
        if clearance <= 0.0:
            return base
        n_links = len(self._links)
        moving = np.zeros(len(bodies), dtype=bool)
        moving[:n_links] = self._link_joint >= 0
        if self._attached is not None:
            moving[-1] = True
        n_moving = moving[first].astype(int) + moving[second].astype(int)
        return np.where(n_moving > 0, clearance * n_moving, base)

    def _bodies(self) -> list[_Body]:
        bodies = self._links + list(self._objects.values())
        if self._attached is not None:
            bodies.append(self._attached)
        return bodies

    def _transforms(self, qs: FloatArray) -> FloatArray:
        """World transforms of all bodies, shape (n, B, 4, 4)."""
        n = qs.shape[0]
        bodies = self._bodies()
        out = np.empty((n, len(bodies), 4, 4))
        tj = self.robot.chain.joint_transforms(qs)
        n_links = len(self._links)
        local = np.array([b.transform for b in self._links])
        static = self._link_joint < 0
        out[:, :n_links] = local[None]
        mv = ~static
        out[:, :n_links][:, mv] = tj[:, self._link_joint[mv]] @ local[mv]
        k = n_links
        for obj in self._objects.values():
            out[:, k] = obj.transform
            k += 1
        if self._attached is not None:
            out[:, k] = self.robot.tool_transforms(qs) @ self._attached.transform
        return out

    # -- checking ---------------------------------------------------------------------

    def valid_mask(self, qs: ArrayLike, *, stop_at_first: bool = False) -> BoolArray:
        """Collision-free and within-limits flag of many configurations.

        Parameters
        ----------
        qs : array_like, shape (n, dof)
            Configurations, radians.
        stop_at_first : bool
            Stop at the first invalid configuration (in order); the ones after it
            are reported invalid without being checked.

        Returns
        -------
        ndarray of bool, shape (n,)
        """
        qa = np.asarray(qs, dtype=np.float64).reshape(-1, self.robot.dof)
        return self._check(qa, self._pair_margins(), stop_at_first)

    def _check(self, qa: FloatArray, margins: FloatArray, stop_at_first: bool) -> BoolArray:
        """:meth:`valid_mask` with a security margin per active pair."""
        n = qa.shape[0]
        ok = np.all((qa >= self.robot.lower - 1e-9) & (qa <= self.robot.upper + 1e-9), axis=1)
        first, second = self._active_pairs()
        bodies = self._bodies()
        centers = np.array([b.center for b in bodies])
        halves = np.array([b.half for b in bodies])
        t = self._transforms(qa)
        c, h = _world_aabb(t, centers[None], halves[None])
        reach = h[:, first] + h[:, second] + np.maximum(margins, 0.0)[None, :, None] + 1e-9
        overlap = np.all(np.abs(c[:, first] - c[:, second]) <= reach, axis=2)
        requests = [self._request(float(m)) for m in margins]
        for i in range(n):
            if not ok[i]:
                self.n_checks += 1
                if stop_at_first:
                    ok[i:] = False
                    break
                continue
            self.n_checks += 1
            tfs: dict[int, coal.Transform3s] = {}  # one coal transform per body and config
            for p in np.flatnonzero(overlap[i]):
                a, b = int(first[p]), int(second[p])
                self.n_narrow += 1
                self._result.clear()
                ta = tfs.get(a)
                if ta is None:
                    ta = tfs[a] = _tf(t[i, a])
                tb = tfs.get(b)
                if tb is None:
                    tb = tfs[b] = _tf(t[i, b])
                if coal.collide(
                    bodies[a].geometry, ta, bodies[b].geometry, tb, requests[p], self._result
                ):
                    ok[i] = False
                    break
            if stop_at_first and not ok[i]:
                ok[i:] = False
                break
        return ok

    def is_valid(self, q: ArrayLike) -> bool:
        """True if ``q`` (dof,) is within the joint limits and collision-free."""
        return bool(self.valid_mask(self.robot.check_q(q)[None])[0])

    def collisions(self, q: ArrayLike) -> list[tuple[str, str]]:
        """Every colliding pair of body (link or object) names at ``q`` (dof,), for diagnostics."""
        first, second = self._active_pairs()
        bodies = self._bodies()
        hits = self._pair_hits(self.robot.check_q(q), self._pair_margins())
        out: list[tuple[str, str]] = []
        for p in np.flatnonzero(hits):
            pair = (bodies[first[p]].name, bodies[second[p]].name)
            if pair not in out:
                out.append(pair)
        return out

    def _pair_hits(self, q: FloatArray, margins: FloatArray) -> NDArray[np.bool_]:
        """Which active pairs collide at ``q`` (dof,) under ``margins`` (P,)."""
        first, second = self._active_pairs()
        bodies = self._bodies()
        t = self._transforms(q[None])[0]
        c, h = _world_aabb(
            t, np.array([b.center for b in bodies]), np.array([b.half for b in bodies])
        )
        reach = h[first] + h[second] + np.maximum(margins, 0.0)[:, None] + 1e-9
        hits = np.zeros(len(first), dtype=bool)
        for p in np.flatnonzero(np.all(np.abs(c[first] - c[second]) <= reach, axis=1)):
            a, b = int(first[p]), int(second[p])
            self._result.clear()
            hits[p] = bool(
                coal.collide(
                    bodies[a].geometry,
                    _tf(t[a]),
                    bodies[b].geometry,
                    _tf(t[b]),
                    self._request(float(margins[p])),
                    self._result,
                )
            )
        return hits

    def motion_bound(self) -> FloatArray:
        """Per-joint lever arm, metres: no robot or grasped point moves more than ``Σ |Δq_j| r_j``.

        ``r_j`` bounds the distance of any body moved by joint ``j`` from that
        joint's axis (the distance from the joint origin to the far corner of
        each body's bounding box, at the home configuration — the chain is rigid
        between joints, so this distance does not depend on ``q``).

        Returns
        -------
        ndarray, shape (dof,)
        """
        if self._lever is not None:
            return self._lever
        q = self.robot.home[None]
        tj = self.robot.chain.joint_transforms(q)[0]
        bodies = self._bodies()
        t = self._transforms(q)[0]
        radius = np.zeros(self.robot.dof)
        n_links = len(self._links)
        for k, body in enumerate(bodies):
            if k < n_links:
                j = int(self._link_joint[k])
                if j < 0:
                    continue
                moved = self.robot.chain.ancestors(j)
            elif self._attached is body:
                moved = self.robot.chain.ancestors(self.robot._tool_joint)
            else:
                continue
            c, h = _world_aabb(t[k], body.center, body.half)
            far = np.linalg.norm(c[None] - tj[:, :3, 3], axis=1) + np.linalg.norm(h)
            radius = np.where(moved, np.maximum(radius, far), radius)
        self._lever = radius
        return radius

    def interpolate(
        self, qs: ArrayLike, *, max_step_m: float = 0.01, max_step_rad: float = 0.02
    ) -> FloatArray:
        """Densely interpolate a joint path so that no point moves more than ``max_step_m``.

        Parameters
        ----------
        qs : array_like, shape (n, dof)
            Waypoints, radians.
        max_step_m : float
            Largest displacement of any robot or grasped-part point between
            consecutive configurations, metres (bounded by :meth:`motion_bound`).
        max_step_rad : float
            Largest change of any joint between consecutive configurations, radians.

        Returns
        -------
        ndarray, shape (m, dof)
            The waypoints and the configurations between them, in order.
        """
        qa = np.asarray(qs, dtype=np.float64).reshape(-1, self.robot.dof)
        if qa.shape[0] < 2:
            return qa.copy()
        lever = self.motion_bound()
        d = np.abs(np.diff(qa, axis=0))
        steps = np.maximum(d @ lever / max_step_m, d.max(axis=1) / max_step_rad)
        counts = np.maximum(np.ceil(steps).astype(np.intp), 1)
        parts = [qa[:1]]
        for k in range(qa.shape[0] - 1):
            s = (np.arange(1, counts[k] + 1) / counts[k])[:, None]
            parts.append((1.0 - s) * qa[k] + s * qa[k + 1])
        return np.vstack(parts)

    def check_path(
        self,
        qs: ArrayLike,
        *,
        max_step_m: float = 0.01,
        max_step_rad: float = 0.02,
        clearance: bool = True,
        chunk: int = 64,
    ) -> bool:
        """True if a piecewise-linear joint path is collision-free, checked densely.

        Every segment is interpolated by :meth:`interpolate` (no point moves more
        than ``max_step_m`` between checks) and each configuration checked, stopping
        at the first collision; the configurations are visited coarse to fine
        (every 2^k-th first), so a path that collides is usually rejected after a
        few checks.

        With ``clearance`` (the default) the check is conservative for the
        continuous motion: between two checks no point is farther than
        ``max_step_m / 2`` from where it was checked, so each checked configuration
        must keep that distance to the world (twice it between two moving bodies).
        Pairs that are closer than that at the first or the last waypoint — a
        grasped part leaving the table, a hand at its grasp — are checked at
        their contact tolerance instead.

        Parameters
        ----------
        qs : array_like, shape (n, dof)
            Waypoints, radians.
        max_step_m, max_step_rad : float
            Density of the check (see :meth:`interpolate`).
        clearance : bool
            Require the clearance above; without it only the checked
            configurations are guaranteed collision-free.
        chunk : int
            Configurations checked per batch.
        """
        qa = np.asarray(qs, dtype=np.float64).reshape(-1, self.robot.dof)
        margins = self._pair_margins()
        if clearance and len(qa) > 1:
            wide = self._pair_margins(max_step_m / 2.0)
            if not np.all(self._check(qa[[0, -1]], margins, False)):
                return False
            near = self._pair_hits(qa[0], wide) | self._pair_hits(qa[-1], wide)
            margins = np.where(near, margins, wide)
        dense = self.interpolate(qa, max_step_m=max_step_m, max_step_rad=max_step_rad)
        # coarse to fine (bit-reversed order): a colliding stretch is hit after few checks
        dense = dense[_coarse_to_fine(dense.shape[0])]
        for k in range(0, dense.shape[0], chunk):
            if not np.all(self._check(dense[k : k + chunk], margins, True)):
                return False
        return True

    def reset_counter(self) -> None:
        """Set :attr:`n_checks` and :attr:`n_narrow` to zero."""
        self.n_checks = 0
        self.n_narrow = 0

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
