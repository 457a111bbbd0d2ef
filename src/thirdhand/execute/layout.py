"""The work cell: robot, table, where the assembly is built, and seeded start layouts.

World frame: ``z`` up, the table top at ``z = 0.75`` m as in the synthetic
scenes, the robot facing ``+x``. Panda: its base on the table top at the
origin. Baxter: the model's root is its torso, 0.93 m above the floor where
its pedestal stands; the torso stands at ``(-0.25, 0.22)``, so the right arm
(the one used) has its shoulder near ``y = 0``; the table starts 2 cm in front
of the torso (``x = -0.03``, the pedestal's foot under it), its top 0.18 m
below the torso and 0.31 m below the shoulder; parts lie 0.25–0.88 m from the
shoulder (a top-down grasp reaches about 0.8 m, one from the side farther:
the half-table in the arm's reach is tight for the chair). The assembly is
built at ``assembly_xy`` in front of the arm, on the table; parts are laid
out in a band of distances from the arm's first joint (:attr:`Workcell.arm_xy`,
:attr:`Workcell.reach`).

The assembly pose of the base part (the root of the constraint tree, e.g. the
seat) is chosen from the geometry (:func:`assembly_base_pose`): of the six ways
of turning one of the base's axes up and four turns about the vertical, first
those that keep the finished assembly out of the arm's inner radius (the near
edge of :attr:`Workcell.reach`: nearer, a part stands in the robot's base or
where the arm cannot fold to place it); of these the one whose finished assembly
is the lowest (the smallest vertical extent), ties broken by the lowest fixture,
then the one that keeps the finished assembly nearest the robot. The base rests
on a fixture block when something attached to it reaches below its own
underside. For the synthetic chair this stands the seat on its edge with its
legs pointing sideways and the back sideways the other way (with the legs up,
the back would point into the table; turned towards the robot, it would end in
the robot's base); for the bench it lays the seat flat with its legs pointing up.

Start layouts (:func:`start_layout`): every other part lies on the table within
the robot's reach, a rod (one long axis) on its side spun at random about its
axis (a flat one, a board, with the side up that is up at its goal), any other
part with the face up that is up at its goal, turned about the vertical at
random; none overlaps another, the assembly's footprint or the robot's base.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import coal
import numpy as np

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.errors import ThirdhandError
from thirdhand.execute.collision_check import coal_transform
from thirdhand.execute.goals import goal_pose, sweep_dofs, vary
from thirdhand.execute.grasps import (
    FLAT_RATIO,
    MAX_GRIP_M,
    ROD_RATIO,
    is_wide_plate,
    pinch_grasps,
)
from thirdhand.execute.meshes import box, mesh_from_triangles
from thirdhand.segment.contact import box_corners
from thirdhand.task.constraint import Constraint
from thirdhand.task.meshes import body_triangles, object_triangles
from thirdhand.task.model import TaskFile, TaskObject

TABLE_Z = 0.75
#: Robot base poses per robot name: translation (m), world frame, facing +x.
ROBOT_BASES: dict[str, tuple[float, float, float]] = {
    "panda": (0.0, 0.0, TABLE_Z),
    # Baxter's torso ("base" frame) stands 0.93 m above the floor (its pedestal's foot),
    # behind the table; its right arm's shoulder is 0.26 m to its right: centre that arm.
    "baxter": (-0.25, 0.22, 0.93),
}
#: Table extent per robot (x min, x max, y min, y max), metres, world frame. Baxter's
#: pedestal column (at the table top's height) and torso end 0.16 m and 0.20 m in front of
#: the torso frame (x = -0.09, -0.05): the table starts 2 cm beyond; its wide foot (below
#: 0.3 m) stands under the table.
TABLE_EXTENT: dict[str, tuple[float, float, float, float]] = {
    "panda": (-0.30, 1.00, -0.90, 0.90),
    "baxter": (-0.03, 1.00, -0.90, 0.90),
}
#: World x, y of the arm's first joint (Baxter: the right shoulder ``right_s0``), metres.
ARM_XY: dict[str, tuple[float, float]] = {
    "panda": (0.0, 0.0),
    "baxter": (-0.186, -0.039),
}
#: Distances from the arm's first joint where parts are laid out, metres.
REACH: dict[str, tuple[float, float]] = {
    "panda": (0.3, 0.7),
    "baxter": (0.25, 0.88),
}
#: Default world x, y of the assembly per robot, metres.
ASSEMBLY_XY: dict[str, tuple[float, float]] = {
    "panda": (0.5, 0.0),
    "baxter": (0.42, 0.05),
}


class LayoutError(ThirdhandError):
    """A task's parts cannot be laid out (no geometry, no room on the table)."""


#: What to do about a part without geometry (a task learned from a recording alone).
NO_GEOMETRY_HINT = (
    " (learn the task with --scene scene_*.json, or give the object bbox_min/bbox_max)"
)


@dataclass
class Workcell:
    """Where everything is: robot base, table, fixture and the base part's assembly pose.

    Attributes
    ----------
    robot : str
        ``"panda"`` or ``"baxter"``.
    robot_base : ndarray, shape (4, 4)
        Robot root pose, world frame.
    table_z : float
        Height of the table top, metres.
    table_extent : tuple of 4 floats
        x min, x max, y min, y max of the table top, metres.
    base : str
        The base part (root of the constraints).
    base_pose : ndarray, shape (4, 4)
        The base part's assembly pose, world frame.
    fixtures : list of (str, ndarray (4, 4), ndarray (3,))
        Boxes holding the base: name, centre pose (world), full sides (m).
    arm_xy : tuple of 2 floats
        World x, y of the arm's first joint, metres.
    reach : tuple of 2 floats
        Band of distances from ``arm_xy`` where start layouts put the parts, metres.
    """

    robot: str
    robot_base: FloatArray
    table_z: float
    table_extent: tuple[float, float, float, float]
    base: str
    base_pose: FloatArray
    fixtures: list[tuple[str, FloatArray, FloatArray]] = field(default_factory=list)
    arm_xy: tuple[float, float] = (0.0, 0.0)
    reach: tuple[float, float] = (0.3, 0.7)

    @property
    def table_center(self) -> tuple[float, float]:
        """World x, y of the table top's centre, metres."""
        x0, x1, y0, y1 = self.table_extent
        return ((x0 + x1) / 2.0, (y0 + y1) / 2.0)

    @property
    def table_size(self) -> tuple[float, float]:
        """Extent of the table top along world x and y, metres."""
        x0, x1, y0, y1 = self.table_extent
        return (x1 - x0, y1 - y0)


def base_part(task: TaskFile) -> str:
    """The root of the constraint tree: a parent that is nobody's child.

    Raises
    ------
    LayoutError
        If there are no constraints or several roots.
    """
    parents = {c.parent for c in task.constraints}
    children = {c.child for c in task.constraints}
    roots = sorted(parents - children)
    if len(roots) != 1:
        raise LayoutError(
            f"task: expected one base part (a parent that is no part's child), got {roots}"
        )
    return roots[0]


def part_vertices(
    obj: TaskObject,
    task_path: str | os.PathLike[str] | None = None,
    search: Sequence[str | os.PathLike[str]] = (),
) -> FloatArray:
    """Vertices of the part's mesh (or bounding box), body frame, metres, shape (n, 3).

    Raises
    ------
    LayoutError
        If the object has neither a mesh nor a bounding box.
    """
    tri = object_triangles(obj, task_path, search)
    if tri is None:
        raise LayoutError(
            f"object {obj.name!r}: no mesh and no bounding box to lay it out{NO_GEOMETRY_HINT}"
        )
    return np.unique(np.asarray(tri, dtype=np.float64).reshape(-1, 3), axis=0)


def _transform(t: FloatArray, v: FloatArray) -> FloatArray:
    return np.asarray(v @ t[:3, :3].T + t[:3, 3], dtype=np.float64)


def assembled_vertices(
    task: TaskFile,
    base: str,
    vertices: dict[str, FloatArray],
) -> dict[str, FloatArray]:
    """Every part's vertices in the base frame when every constraint holds (nominal poses)."""
    poses = {base: np.eye(4)}
    pending = list(task.constraints)
    while pending:
        progressed = False
        for c in list(pending):
            if c.parent in poses:
                poses[c.child] = goal_pose(poses[c.parent], c)
                pending.remove(c)
                progressed = True
        if not progressed:
            break
    return {n: _transform(poses[n], v) for n, v in vertices.items() if n in poses}


def _rotation_up(axis: int, sign: float, yaw: float) -> FloatArray:
    """Rotation (3, 3) turning the base's axis ``axis`` (sign) to world +z, then yawing."""
    up = np.zeros(3)
    up[axis] = sign
    other = np.zeros(3)
    other[(axis + 1) % 3] = 1.0
    # columns: where base x, y, z go; build rows of R^T = world axes in base coordinates
    z_b = up
    x_b = other
    y_b = np.cross(z_b, x_b)
    r_world_base = np.stack([x_b, y_b, z_b])  # maps base coords to a z-up frame
    rz = rot_z(yaw)
    return np.asarray(rz @ r_world_base, dtype=np.float64)


def rot_z(yaw: float) -> FloatArray:
    """Rotation matrix (3, 3) about the world's vertical by ``yaw`` radians."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _hull(v: FloatArray) -> FloatArray:
    """The convex hull's vertices of a point cloud (the cloud itself when flat)."""
    if len(v) <= 8:
        return v
    from scipy.spatial import ConvexHull, QhullError

    try:
        return np.asarray(v[ConvexHull(v).vertices], dtype=np.float64)
    except (QhullError, ValueError):
        return v


def swept_poses(task: TaskFile, base: str) -> dict[str, FloatArray]:
    """Every child's poses in the base frame, turned and shifted through its free DOFs.

    The parent of each constraint stands at its nominal pose (:func:`_pose_in_base`);
    the child's displacements are :func:`thirdhand.execute.goals.sweep_dofs` (a leg free
    to spin: 37 turns 10° apart, the demonstrated one first).

    Returns
    -------
    dict of str to ndarray, shape (n, 4, 4)
        ``T_base_child`` per child of a constraint; the base itself: one identity.
    """
    out: dict[str, FloatArray] = {base: np.eye(4)[None]}
    for c in task.constraints:
        parent = _pose_in_base(task, base, c.parent)
        out[c.child] = np.asarray(parent @ vary(c, sweep_dofs(c)), dtype=np.float64)
    return out


def _swept_vertices(
    poses: dict[str, FloatArray], vertices: dict[str, FloatArray]
) -> dict[str, FloatArray]:
    """The hull vertices of each part at each of its swept poses, base frame, (n·m, 3)."""
    out = {}
    for n, ts in poses.items():
        if n in vertices:
            v = _hull(vertices[n])
            out[n] = np.vstack([_transform(t, v) for t in ts])
    return out


def _part_geometry(
    obj: TaskObject,
    task_path: str | os.PathLike[str] | None,
    search: Sequence[str | os.PathLike[str]],
) -> coal.CollisionGeometry:
    tri = object_triangles(obj, task_path, search)
    if tri is None:
        raise LayoutError(
            f"object {obj.name!r}: no mesh and no bounding box to lay it out{NO_GEOMETRY_HINT}"
        )
    return mesh_from_triangles(tri)


def _fixture_clear(
    lo: FloatArray,
    hi: FloatArray,
    parts: list[tuple[coal.CollisionGeometry, FloatArray]],
    margin: float,
) -> bool:
    """Whether the box ``[lo, hi]`` (world) keeps ``margin`` from every part pose."""
    geom = box(np.maximum(hi - lo, 1e-6))
    t = np.eye(4)
    t[:3, 3] = (lo + hi) / 2.0
    tf = coal_transform(t)
    req = coal.CollisionRequest()
    req.security_margin = margin
    for g, poses in parts:
        for p in poses:
            res = coal.CollisionResult()
            if coal.collide(g, coal_transform(p), geom, tf, req, res):
                return False
    return True


def fixture_box(
    base_pose: FloatArray,
    base_vertices: FloatArray,
    parts: list[tuple[coal.CollisionGeometry, FloatArray]],
    *,
    table_z: float,
    height: float,
    margin: float = 0.005,
    min_width: float = 0.02,
    iterations: int = 12,
) -> tuple[FloatArray, FloatArray]:
    """The fixture block under the base, narrowed until every swept child pose clears it.

    The block starts as the base's footprint from the table up to its underside; along
    the base's longer horizontal side each end is pulled in (bisection, each end on
    its own) until no child at any of its swept poses comes within ``margin`` of it
    (coal), keeping at least ``min_width`` around the base's centre; if that is not
    clear either, the shorter side is narrowed the same way.

    Parameters
    ----------
    base_pose : ndarray, shape (4, 4)
        ``T_world_base``.
    base_vertices : ndarray, shape (n, 3)
        The base's vertices, base frame.
    parts : list of (coal geometry, ndarray (m, 4, 4))
        Each child's geometry and its swept world poses.
    table_z, height : float
        Table top and the block's height, metres.
    margin, min_width : float
        Gap kept to the children and the narrowest block, metres.
    iterations : int
        Bisection steps per end.

    Returns
    -------
    centre : ndarray, shape (4, 4)
        The block's centre pose (world, axis-aligned).
    size : ndarray, shape (3,)
        Its full sides, metres.
    """
    base_w = _transform(base_pose, base_vertices)
    lo = base_w.min(axis=0).copy()
    hi = base_w.max(axis=0).copy()
    lo[2], hi[2] = table_z, table_z + height
    mid = (lo + hi) / 2.0
    long_side = int(np.argmax((hi - lo)[:2]))
    for a in (long_side, 1 - long_side):
        if _fixture_clear(lo, hi, parts, margin):
            break
        half = min_width / 2.0
        lo_min, hi_min = lo.copy(), hi.copy()
        lo_min[a], hi_min[a] = max(lo[a], mid[a] - half), min(hi[a], mid[a] + half)
        if not _fixture_clear(lo_min, hi_min, parts, margin):
            lo, hi = lo_min, hi_min  # as narrow as allowed; try the other side too
            continue
        # the high end with the low end narrow, then the low end with the high end found
        good, bad = hi_min[a], hi[a]
        for _ in range(iterations):
            trial = hi_min.copy()
            trial[a] = (good + bad) / 2.0
            if _fixture_clear(lo_min, trial, parts, margin):
                good = trial[a]
            else:
                bad = trial[a]
        hi_new = hi_min.copy()
        hi_new[a] = good
        good, bad = lo_min[a], lo[a]
        for _ in range(iterations):
            trial = lo_min.copy()
            trial[a] = (good + bad) / 2.0
            if _fixture_clear(trial, hi_new, parts, margin):
                good = trial[a]
            else:
                bad = trial[a]
        lo_new = lo_min.copy()
        lo_new[a] = good
        lo, hi = lo_new, hi_new
        break
    centre = np.eye(4)
    centre[:3, 3] = (lo + hi) / 2.0
    return centre, np.asarray(hi - lo, dtype=np.float64)


def base_pose_candidates(
    task: TaskFile,
    *,
    base: str | None = None,
    assembly_xy: tuple[float, float] = (0.5, 0.0),
    table_z: float = TABLE_Z,
    robot_xy: tuple[float, float] = (0.0, 0.0),
    clearance: float = 0.08,
    inner_radius: float = 0.0,
    task_path: str | os.PathLike[str] | None = None,
    search: Sequence[str | os.PathLike[str]] = (),
) -> list[tuple[tuple[float, float, float, float], FloatArray, float]]:
    """The 24 axis-aligned assembly poses of the base, best first by geometry.

    Each child is swept through its free DOFs (:func:`swept_poses`), so the
    demonstrated spin of a leg does not matter. Keys, compared in order (mm): how far
    the finished assembly comes inside ``inner_radius`` of the robot, its height, the
    fixture's height, its farthest reach from the robot.

    Returns
    -------
    list of (key, base_pose (4, 4), fixture height)
        Sorted by key; the fixture height is 0 when the base rests on the table.
    """
    base = base_part(task) if base is None else base
    objs = {o.name: o for o in task.objects}
    verts = {
        n: part_vertices(objs[n], task_path, search)
        for n in {base} | {c.child for c in task.constraints}
    }
    placed = _swept_vertices(swept_poses(task, base), verts)
    every = np.vstack(list(placed.values()))
    out = []
    for axis, sign in ((1, 1.0), (1, -1.0), (2, 1.0), (2, -1.0), (0, 1.0), (0, -1.0)):
        for yaw in (0.0, np.pi / 2, np.pi, 3 * np.pi / 2):
            rot = _rotation_up(axis, sign, yaw)
            world = every @ rot.T
            base_w = placed[base] @ rot.T
            height = float(world[:, 2].max() - world[:, 2].min())
            fixture = max(float(base_w[:, 2].min() - world[:, 2].min()), 0.0)
            if fixture > 0.0:
                fixture += clearance
            centre = (base_w.min(axis=0) + base_w.max(axis=0)) / 2.0
            xy = world[:, :2] - centre[:2] + np.asarray(assembly_xy) - np.asarray(robot_xy)
            dist = np.linalg.norm(xy, axis=1)
            reach = float(dist.max())
            intrusion = max(inner_radius - float(dist.min()), 0.0)
            key = (round(intrusion, 3), round(height, 3), round(fixture, 3), round(reach, 3))
            t = np.eye(4)
            t[:3, :3] = rot
            t[:2, 3] = np.asarray(assembly_xy) - centre[:2]
            t[2, 3] = table_z + fixture - float(base_w[:, 2].min())
            out.append((key, t, fixture))
    out.sort(key=lambda k: k[0])
    return out


def base_fixtures(
    task: TaskFile,
    pose: FloatArray,
    fixture: float,
    *,
    base: str | None = None,
    table_z: float = TABLE_Z,
    task_path: str | os.PathLike[str] | None = None,
    search: Sequence[str | os.PathLike[str]] = (),
) -> list[tuple[str, FloatArray, FloatArray]]:
    """The fixture holding the base at ``pose`` (``fixture`` m high; none when 0)."""
    if fixture <= 0.0:
        return []
    base = base_part(task) if base is None else base
    objs = {o.name: o for o in task.objects}
    sweeps = swept_poses(task, base)
    parts = [
        (_part_geometry(objs[n], task_path, search), pose @ ts)
        for n, ts in sweeps.items()
        if n != base
    ]
    centre, size = fixture_box(
        pose,
        part_vertices(objs[base], task_path, search),
        parts,
        table_z=table_z,
        height=fixture,
    )
    return [("fixture", centre, size)]


def assembly_base_pose(
    task: TaskFile,
    *,
    base: str | None = None,
    assembly_xy: tuple[float, float] = (0.5, 0.0),
    table_z: float = TABLE_Z,
    robot_xy: tuple[float, float] = (0.0, 0.0),
    clearance: float = 0.08,
    inner_radius: float = 0.0,
    task_path: str | os.PathLike[str] | None = None,
    search: Sequence[str | os.PathLike[str]] = (),
) -> tuple[FloatArray, list[tuple[str, FloatArray, FloatArray]]]:
    """The base part's assembly pose and the fixture holding it (see the module notes).

    Parameters
    ----------
    task : TaskFile
    base : str, optional
        The base part (default :func:`base_part`).
    assembly_xy : tuple of 2 floats
        World x, y of the base's bounding-box centre, metres.
    table_z : float
        Table height, metres.
    robot_xy : tuple of 2 floats
        World x, y of the robot; the turn about the vertical keeps the assembly near it.
    clearance : float
        Gap between the table and the lowest point any attached part reaches through
        its free DOFs when a fixture is needed, metres.
    inner_radius : float
        Horizontal distance from ``robot_xy`` that the finished assembly should keep,
        metres (:attr:`Workcell.reach`'s near edge): the orientations whose parts come
        nearer are taken only when every orientation does, the least intruding first.
        With boxes for parts the chair's 42 cm back would otherwise point at the robot
        and end 8 cm from its first joint, inside its base link.
    task_path, search
        Where to find meshes (:func:`thirdhand.task.meshes.resolve_mesh`).

    Returns
    -------
    base_pose : ndarray, shape (4, 4)
        ``T_world_base``.
    fixtures : list of (name, pose (4, 4), size (3,))
        Empty when the base rests on the table; otherwise one block, narrowed until every
        child swept through its free DOFs clears it (:func:`fixture_box`).
    """
    _, pose, fixture = base_pose_candidates(
        task,
        base=base,
        assembly_xy=assembly_xy,
        table_z=table_z,
        robot_xy=robot_xy,
        clearance=clearance,
        inner_radius=inner_radius,
        task_path=task_path,
        search=search,
    )[0]
    return pose, base_fixtures(
        task, pose, fixture, base=base, table_z=table_z, task_path=task_path, search=search
    )


def make_workcell(
    task: TaskFile,
    robot: str = "panda",
    *,
    assembly_xy: tuple[float, float] | None = None,
    task_path: str | os.PathLike[str] | None = None,
    search: Sequence[str | os.PathLike[str]] = (),
) -> Workcell:
    """The work cell of a task for a robot: base pose, table, assembly pose, fixture.

    ``assembly_xy`` defaults to :data:`ASSEMBLY_XY` of the robot.

    Raises
    ------
    LayoutError
        For an unknown robot or a task without a single base part.
    """
    if robot not in ROBOT_BASES:
        raise LayoutError(f"unknown robot {robot!r}: expected one of {sorted(ROBOT_BASES)}")
    rb = np.eye(4)
    rb[:3, 3] = ROBOT_BASES[robot]
    base = base_part(task)
    pose, fixtures = assembly_base_pose(
        task,
        base=base,
        assembly_xy=ASSEMBLY_XY[robot] if assembly_xy is None else assembly_xy,
        robot_xy=ARM_XY[robot],
        inner_radius=REACH[robot][0],
        task_path=task_path,
        search=search,
    )
    return Workcell(
        robot, rb, TABLE_Z, TABLE_EXTENT[robot], base, pose, fixtures, ARM_XY[robot], REACH[robot]
    )


def _is_rod(v: FloatArray) -> int | None:
    """Index of the long axis of a rod-shaped vertex cloud, or None."""
    ext = np.sort(v.max(axis=0) - v.min(axis=0))[::-1]
    if ext[0] >= ROD_RATIO * ext[1]:
        return int(np.argmax(v.max(axis=0) - v.min(axis=0)))
    return None


def _is_flat_bar(v: FloatArray, long_axis: int) -> bool:
    """Whether a rod's cross-section is flat (a board, not a leg).

    Flat as a plate in :func:`thirdhand.execute.grasps.shape_grasps`: the thinner side of
    the cross-section under :data:`~thirdhand.execute.grasps.FLAT_RATIO` times the wider one.
    """
    ext = v.max(axis=0) - v.min(axis=0)
    a, b = ext[(long_axis + 1) % 3], ext[(long_axis + 2) % 3]
    return bool(min(a, b) < FLAT_RATIO * max(a, b))


def _flat_bar_spin(long_axis: int, goal_rotation: FloatArray) -> float:
    """The spin about a flat bar's long axis that puts up its side that is up at its goal.

    Of the two cross-section axes, the one nearest to up at the goal (``goal_rotation``,
    world) is turned to world up with the same sign, so the edge (or face) free above the
    bar at its goal is free above it on the table too. In :func:`rest_rotation`'s frame
    the body axis ``long_axis + 2`` is up at spin 0 and ``long_axis + 1`` at spin π/2.
    """
    a, b = (long_axis + 1) % 3, (long_axis + 2) % 3
    up = goal_rotation[2]  # world z in body coordinates
    if abs(up[b]) >= abs(up[a]):
        return 0.0 if up[b] > 0 else float(np.pi)
    return float(np.pi / 2) if up[a] > 0 else float(-np.pi / 2)


def rest_rotation(
    v: FloatArray,
    goal_rotation: FloatArray,
    rng: np.random.Generator,
    stand_from: FloatArray | None = None,
) -> FloatArray:
    """A random resting orientation (3, 3) on the table for a part with body vertices ``v``.

    A rod lies on its side spun at random about its axis, unless its cross-section
    is flat (a board, :func:`_is_flat_bar`): then it stands on the edge, or lies on
    the face, that puts up its side that is up at its goal (:func:`_flat_bar_spin`);
    any other part keeps up the body axis nearest to up at its goal
    (``goal_rotation``, world). With ``stand_from`` (where the part meets its parent,
    body frame, metres), a plate wider than a gripper opens that would lie on its face
    stands on its edge farthest from there instead (:func:`plate_edge_up`). Every part
    is turned at random about the vertical.
    A board propped on a long edge at a random tilt is not a resting pose, and its
    grasps from above there came from below or the side at its goal, where the
    wrist hit the table (the toolbox's boards, 1.7 cm thick); a board lying flat has
    no grasp at all (the fingertips go into the table).
    """
    long_axis = _is_rod(v)
    yaw = rng.uniform(-np.pi, np.pi)
    rz = rot_z(yaw)
    if long_axis is not None:
        spin = rng.uniform(-np.pi, np.pi)
        if _is_flat_bar(v, long_axis):
            spin = _flat_bar_spin(long_axis, goal_rotation)
        axis = np.zeros(3)
        axis[long_axis] = 1.0
        r_spin = se3.matrix_from_rotvec(spin * axis)
        # the long axis onto world x, then spin about it, then yaw
        b = np.zeros((3, 3))
        b[0, long_axis] = 1.0
        b[1, (long_axis + 1) % 3] = 1.0
        b[2, (long_axis + 2) % 3] = 1.0
        return np.asarray(rz @ b @ r_spin, dtype=np.float64)
    up_in_body = goal_rotation[2]  # world z in body coordinates (row 2 of R_world_body)
    k = int(np.argmax(np.abs(up_in_body)))
    sign = float(np.sign(up_in_body[k]))
    edge = None if stand_from is None else plate_edge_up(v, k, stand_from)
    if edge is not None:
        k, sign = edge
    return np.asarray(rz @ _rotation_up(k, sign, 0.0), dtype=np.float64)


def pinched_through_face(triangles: FloatArray | None) -> bool:
    """Whether a wide plate lying on its face has a grasp from above: a slat or other
    narrow feature the fingers close on, going down the gaps beside it
    (:func:`~thirdhand.execute.grasps.pinch_grasps` through its face). False without a
    mesh (``triangles``, (t, 3, 3), body frame) or for a part that is no wide plate."""
    if triangles is None:
        return False
    v = triangles.reshape(-1, 3)
    if not is_wide_plate(v.min(axis=0), v.max(axis=0)):
        return False
    thin = int(np.argmin(v.max(axis=0) - v.min(axis=0)))
    return bool(pinch_grasps(triangles, axes=(thin,)))


def plate_edge_up(v: FloatArray, up_axis: int, meets: FloatArray) -> tuple[int, float] | None:
    """The body axis and sign to turn up so that a plate stands on an edge, or None.

    A plate (its thinnest extent under :data:`~thirdhand.execute.grasps.FLAT_RATIO`
    times the next) lying on its face (``up_axis`` its thinnest) and wider than a
    gripper opens (:data:`~thirdhand.execute.grasps.MAX_GRIP_M`) both ways in its plane
    has no grasp for a parallel gripper: from above the fingers meet its face, from the
    side the table. Standing on an edge, its top edge is pinched across its thickness;
    the edge farthest from ``meets`` (where it meets its parent, body frame, metres)
    goes up, so that the fingers stay clear of the parent when it is placed. None when
    the plate is thicker than the fingers open, or is no such plate.
    """
    lo, hi = v.min(axis=0), v.max(axis=0)
    ext = hi - lo
    thin, mid, long = (int(i) for i in np.argsort(ext, kind="stable"))
    if up_axis != thin or not is_wide_plate(lo, hi) or ext[thin] > MAX_GRIP_M:
        return None
    ends = [(float(hi[a] - meets[a]), a, 1.0) for a in (mid, long)]
    ends += [(float(meets[a] - lo[a]), a, -1.0) for a in (mid, long)]
    _, axis, sign = max(ends)
    return axis, sign


def _footprint(v_world: FloatArray, margin: float) -> FloatArray:
    lo = v_world[:, :2].min(axis=0) - margin
    hi = v_world[:, :2].max(axis=0) + margin
    return np.array([lo[0], hi[0], lo[1], hi[1]])


def _overlap(a: FloatArray, b: FloatArray) -> bool:
    return bool(a[0] < b[1] and b[0] < a[1] and a[2] < b[3] and b[2] < a[3])


def occupied_footprints(
    cell: Workcell, placed: Sequence[FloatArray], margin: float
) -> list[FloatArray]:
    """Table footprints already taken: ``placed`` world vertex sets, the fixtures, the robot.

    Parameters
    ----------
    placed : sequence of ndarray (k, 3)
        World vertices (metres) of the parts already on the table or assembled.
    margin : float
        Free space kept around each part and fixture, metres (half on each side).

    Returns
    -------
    list of ndarray (4,)
        ``[x_min, x_max, y_min, y_max]`` in the world frame, metres; the robot's base
        as a 32 cm square.
    """
    taken = [_footprint(v, margin / 2) for v in placed]
    taken += [_footprint(_transform(t, _box_vertices(s)), margin / 2) for _, t, s in cell.fixtures]
    bx, by = cell.robot_base[0, 3], cell.robot_base[1, 3]
    taken.append(np.array([bx - 0.16, bx + 0.16, by - 0.16, by + 0.16]))
    return taken


def table_spot(
    v: FloatArray, rot: FloatArray, cell: Workcell, r: float, ang: float, margin: float
) -> tuple[FloatArray, FloatArray | None]:
    """A part laid on the table ``r`` m from the arm, at angle ``ang``, turned by ``rot``.

    Parameters
    ----------
    v : ndarray (k, 3)
        The part's vertices in its own frame, metres.
    rot : ndarray (3, 3)
        The part's orientation in the world.
    r, ang : float
        Distance (m) and bearing (rad) of the part's bounding-box centre from the
        arm's first joint (``cell.arm_xy``).
    margin : float
        Free space kept around the footprint, metres (half on each side).

    Returns
    -------
    T_world_part : ndarray (4, 4)
        Resting on the table top (lowest vertex at ``cell.table_z``).
    footprint : ndarray (4,) or None
        ``[x_min, x_max, y_min, y_max]`` with the margin, or None when it leaves the table.
    """
    rx, ry = cell.arm_xy
    vw = v @ rot.T
    centre = (vw.min(axis=0) + vw.max(axis=0)) / 2.0
    t = np.eye(4)
    t[:3, :3] = rot
    t[0, 3] = rx + r * np.cos(ang) - centre[0]
    t[1, 3] = ry + r * np.sin(ang) - centre[1]
    t[2, 3] = cell.table_z - vw[:, 2].min()
    fp = _footprint(_transform(t, v), margin / 2)
    x0, x1, y0, y1 = cell.table_extent
    inside = fp[0] > x0 and fp[1] < x1 and fp[2] > y0 and fp[3] < y1
    return t, (fp if inside else None)


def start_layout(
    task: TaskFile,
    cell: Workcell,
    seed: int | np.random.Generator = 0,
    *,
    reach: tuple[float, float] | None = None,
    margin: float = 0.06,
    task_path: str | os.PathLike[str] | None = None,
    search: Sequence[str | os.PathLike[str]] = (),
    max_tries: int = 2000,
    restarts: int = 20,
    accept: Callable[[str, FloatArray], bool] | None = None,
    stand_plates: bool = False,
) -> dict[str, FloatArray]:
    """A seeded start layout: every part's world pose, the base at its assembly pose.

    Parameters
    ----------
    task : TaskFile
    cell : Workcell
    seed : int or numpy.random.Generator
    reach : tuple of 2 floats, optional
        Distance band from the arm's first joint (``cell.arm_xy``) where parts may
        lie, metres; default ``cell.reach``.
    margin : float
        Free space kept around each part's footprint (room for the fingers), metres.
    task_path, search
        Where to find meshes.
    max_tries : int
        Rejection-sampling budget per part.
    restarts : int
        Whole layouts tried (the same generator continued) when a part finds no spot.
    accept : callable, optional
        ``accept(name, T_world_part)``: whether a free spot will do (e.g. the arm reaches
        enough grasps there, :func:`thirdhand.execute.placement.reach_check`); a refused
        spot counts as a draw.
    stand_plates : bool
        Stand a plate that would lie on its face with no grasp a parallel gripper closes
        on (:func:`plate_edge_up`; one with a narrow feature the fingers pinch through its
        face lies flat, :func:`pinched_through_face`); physics needs it, the kinematic
        plan holds it by its face.

    Returns
    -------
    dict of str to ndarray (4, 4)
        ``T_world_part`` of the base and of every child of a constraint.

    Raises
    ------
    LayoutError
        If every layout leaves a part without a free spot in ``max_tries`` draws.
    """
    rng = np.random.default_rng(seed)
    objs = {o.name: o for o in task.objects}
    verts = {
        n: part_vertices(objs[n], task_path, search)
        for n in {cell.base} | {c.child for c in task.constraints}
    }
    placed = assembled_vertices(task, cell.base, verts)
    goal_rot = {
        n: (cell.base_pose[:3, :3] @ _pose_in_base(task, cell.base, n)[:3, :3]) for n in placed
    }
    assembled = [_transform(cell.base_pose, v) for v in placed.values()]
    taken = occupied_footprints(cell, assembled, margin)
    # where each part meets its parent (the parent's origin in the part's frame): a plate
    # the fingers cannot pinch through its face stands on its edge farthest from there
    # (``stand_plates``)
    meets = (
        {
            c.child: se3.transform_invert(c.pose.matrix())[:3, 3]
            for c in task.constraints
            if not pinched_through_face(body_triangles(objs[c.child], task_path, search))
        }
        if stand_plates else {}
    )  # fmt: skip
    reach = cell.reach if reach is None else reach
    order = [c.child for c in task.constraints if c.child in verts]
    # the largest parts first: they need the most room
    area = {n: float(np.prod(np.sort(np.ptp(verts[n], axis=0))[1:])) for n in order}
    stuck = ""
    for _ in range(restarts):
        poses = {cell.base: cell.base_pose.copy()}
        free = list(taken)
        for name in sorted(dict.fromkeys(order), key=lambda n: -area[n]):
            v = verts[name]
            for _ in range(max_tries):
                rot = rest_rotation(v, goal_rot.get(name, np.eye(3)), rng, meets.get(name))
                r = rng.uniform(*reach)
                ang = rng.uniform(-np.pi * 0.85, np.pi * 0.85)
                t, fp = table_spot(v, rot, cell, r, ang, margin)
                if (
                    fp is not None
                    and not any(_overlap(fp, o) for o in free)
                    and (accept is None or accept(name, t))
                ):
                    free.append(fp)
                    poses[name] = t
                    break
            else:
                stuck = name
                break  # the parts laid so far leave no room: start the layout again
        else:
            return poses
    raise LayoutError(
        f"part {stuck!r}: no free spot on the table in {max_tries} draws ({restarts} layouts tried)"
    )


def _box_vertices(size: FloatArray) -> FloatArray:
    h = np.asarray(size, dtype=np.float64) / 2.0
    return box_corners((-h, h))


def _pose_in_base(task: TaskFile, base: str, name: str) -> FloatArray:
    """``T_base_part`` with every constraint at its nominal pose."""
    by_child: dict[str, Constraint] = {c.child: c for c in task.constraints}
    t = np.eye(4)
    cur = name
    chain = []
    while cur != base and cur in by_child:
        chain.append(by_child[cur])
        cur = by_child[cur].parent
    for c in reversed(chain):
        t = goal_pose(t, c)
    return t
