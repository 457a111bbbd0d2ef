"""The bodies of a collision world: frozen records of where each geometry is and what may touch.

:class:`SceneBodies` is the snapshot :class:`~thirdhand.execute.scene.CollisionScene`
builds and replaces on every change and
:class:`~thirdhand.execute.collision_check.SceneChecks` checks. Poses are
homogeneous (4, 4) matrices, metres.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import coal
import numpy as np

from thirdhand.arrays import FloatArray, IndexArray
from thirdhand.execute import pair_table as pt
from thirdhand.execute.kinematics import Chain

__all__ = ["Body", "SceneBodies", "coal_transform", "fixed_link_frame", "touching_links"]


@dataclass(frozen=True, eq=False)
class Body:
    """A body of the world: a coal geometry, where it is, and its local bounding box.

    Attributes
    ----------
    name : str
    geometry : coal.CollisionGeometry
    transform : ndarray, shape (4, 4)
        ``T_world_geometry`` of a free object, ``T_joint_geometry`` of a robot link,
        ``T_tool_geometry`` of the grasped part; metres.
    center, half : ndarray, shape (3,)
        Centre and half extents of the geometry's bounding box in its frame, metres.
    offset : ndarray, shape (4, 4)
        ``T_part_geometry``: where the geometry sits in the part's frame.
    """

    name: str
    geometry: coal.CollisionGeometry
    transform: FloatArray
    center: FloatArray
    half: FloatArray
    offset: FloatArray = field(default_factory=lambda: np.eye(4))

    @property
    def is_mesh(self) -> bool:
        """The geometry is a triangle mesh (coal allows it no negative margin)."""
        return isinstance(self.geometry, coal.BVHModelBase)


@dataclass(frozen=True, eq=False)
class SceneBodies:
    """A snapshot of a collision world's bodies and of what may touch what.

    Bodies are numbered links, free objects, grasped part (see
    :mod:`~thirdhand.execute.pair_table`). The scene makes a new snapshot on every
    change (``dataclasses.replace``); nothing in one is changed in place.

    Attributes
    ----------
    links : tuple of Body
        The robot's collision geometries, ``transform`` in their joint's frame.
    link_joint : ndarray of intp, shape (L,)
        Joint (0-based) moving each link, -1 for links no joint moves.
    self_pairs : tuple of (int, int)
        Link pairs the SRDF leaves checked, at least one of them moving.
    gripper_links : frozenset of str
        Link names of the hand.
    objects : tuple of Body
        Free objects, in the order they were added (a released part last).
    attached : Body or None
        The grasped part, ``transform`` in the tool frame.
    touch_links : frozenset of str
        Links the grasped part touched when it was grasped.
    allowed : frozenset of frozenset of str
        Allowed pairs of names (or of the groups ``"robot"``, ``"gripper"``).
    """

    links: tuple[Body, ...]
    link_joint: IndexArray
    self_pairs: tuple[tuple[int, int], ...] = ()
    gripper_links: frozenset[str] = frozenset()
    objects: tuple[Body, ...] = ()
    attached: Body | None = None
    touch_links: frozenset[str] = frozenset()
    allowed: frozenset[frozenset[str]] = frozenset()

    @cached_property
    def bodies(self) -> tuple[Body, ...]:
        """Every body in index order: links, objects, the grasped part."""
        tail = () if self.attached is None else (self.attached,)
        return self.links + self.objects + tail

    @cached_property
    def link_local(self) -> FloatArray:
        """Every link's ``transform``, shape (L, 4, 4)."""
        return np.array([b.transform for b in self.links])

    def pair_world(self) -> pt.PairWorld:
        """The names, kinds and allowed pairs the pair table is built from."""

        def kind(body: Body, moves: bool) -> pt.BodyKind:
            return pt.BodyKind(body.name, body.is_mesh, moves)

        moving = (self.link_joint >= 0).tolist()
        return pt.PairWorld(
            links=tuple(kind(b, m) for b, m in zip(self.links, moving, strict=True)),
            self_pairs=self.self_pairs,
            gripper_links=self.gripper_links,
            objects=tuple(kind(b, False) for b in self.objects),
            attached=None if self.attached is None else kind(self.attached, True),
            touch_links=self.touch_links,
            allowed=self.allowed,
        )

    def find(self, name: str) -> Body | None:
        """The free or grasped object called ``name``, or None."""
        for body in self.objects:
            if body.name == name:
                return body
        if self.attached is not None and self.attached.name == name:
            return self.attached
        return None


def coal_transform(t: FloatArray) -> coal.Transform3s:
    """coal transform of a homogeneous matrix (4, 4)."""
    return coal.Transform3s(np.ascontiguousarray(t[:3, :3]), np.ascontiguousarray(t[:3, 3]))


def fixed_link_frame(link: Body, joint: int, chain: Chain) -> FloatArray | None:
    """World transform (4, 4) of a link no joint moves as a set, else None.

    A link no joint moves is where its ``transform`` says. A link on a first joint
    (no parent) whose geometry is symmetric about that joint's axis (a sphere centred
    on it, a cylinder or capsule along it) occupies the same space at every angle:
    Panda's ``panda_link1``.

    Parameters
    ----------
    link : Body
        The link, ``transform`` in its joint's frame.
    joint : int
        Joint moving it, -1 for none.
    chain : Chain
    """
    if joint < 0:
        return link.transform
    if chain.parents[joint] >= 0:
        return None
    axis = chain.axes[joint]
    on_axis = bool(np.linalg.norm(np.cross(axis, link.transform[:3, 3])) < 1e-9)
    geom = link.geometry
    if isinstance(geom, coal.Sphere):
        symmetric = on_axis
    elif isinstance(geom, (coal.Cylinder, coal.Capsule)):
        symmetric = on_axis and abs(abs(float(axis @ link.transform[:3, 2])) - 1.0) < 1e-12
    else:
        symmetric = False
    return chain.placements[joint] @ link.transform if symmetric else None


def touching_links(
    bodies: SceneBodies,
    part: Body,
    t_world_part: FloatArray,
    t_joints: FloatArray,
    tolerance: float,
) -> frozenset[str]:
    """Links in contact with ``part`` at its world pose ``t_world_part`` (4, 4), at their
    contact margins, with the joint frames ``t_joints`` (dof, 4, 4) of a configuration."""
    result = coal.CollisionResult()
    tf_part = coal_transform(t_world_part)
    out: set[str] = set()
    for link, j in zip(bodies.links, bodies.link_joint.tolist(), strict=True):
        t_link = link.transform if j < 0 else t_joints[j] @ link.transform
        request = coal.CollisionRequest()
        request.security_margin = pt.contact_margin(link.is_mesh, part.is_mesh, tolerance)
        result.clear()
        if coal.collide(
            link.geometry, coal_transform(t_link), part.geometry, tf_part, request, result
        ):
            out.add(link.name)
    return frozenset(out)
