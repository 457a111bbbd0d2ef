"""Conservative sphere covers of collision geometries: every point of the body inside a sphere.

The fast collision layer (:mod:`~thirdhand.execute.sphere_check`) approximates
every body by spheres, in the spirit of VAMP and cuRobo. A cover is
*conservative*: each point that coal counts as part of the geometry lies inside
some sphere, so two covers that do not overlap prove that coal finds no contact.

What coal counts as part of a geometry differs by kind: primitives (sphere,
cylinder, capsule, box) are solids, triangle meshes (BVH models) are their
triangles only (coal tests triangle against triangle or against a solid
primitive; a mesh inside another is not a contact). So primitives are covered
as solids and meshes as surfaces:

- sphere: itself;
- cylinder (axis z, centred): spheres along the axis, each covering a slab of the
  solid cylinder (radius ``sqrt(r² + (h/k)²)``);
- capsule: spheres along the axis (of radius ``r``, the caps are spheres);
- box: the solid box cut into cells no longer than ``cell`` a side, a sphere per cell;
- mesh: triangles split (in four) until each fits a ball of radius ``cell / 2``,
  then gathered per ``cell``-sized voxel into one sphere that encloses the
  balls of its triangles;
- anything else: its local bounding box, as a box.

Spheres are then grouped (per ``group``-sized voxel) under an enclosing sphere,
the middle level of a two-level hierarchy. Sphere arrays are ``(n, 4)``: centre
x, y, z in the geometry's frame (metres) and radius.
"""

from __future__ import annotations

from dataclasses import dataclass

import coal
import numpy as np

from thirdhand.arrays import FloatArray, IndexArray

#: Added to every radius: float round-off of the transforms, metres.
PAD = 1e-6

#: About how many spheres a mesh's cover may have (the cell grows for larger meshes).
MAX_MESH_SPHERES = 1500


@dataclass(frozen=True)
class SphereCover:
    """Spheres covering one geometry, in groups, in the geometry's frame.

    Attributes
    ----------
    spheres : ndarray, shape (n, 4)
        Centre (metres) and radius of each sphere; the spheres of a group are contiguous.
    groups : ndarray, shape (g, 4)
        Enclosing sphere of each group.
    group_range : ndarray of int, shape (g, 2)
        ``spheres[start:stop]`` of each group.
    bound : ndarray, shape (4,)
        Sphere enclosing the whole cover.
    """

    spheres: FloatArray
    groups: FloatArray
    group_range: IndexArray
    bound: FloatArray


def enclosing(spheres: FloatArray) -> FloatArray:
    """A sphere (4,) enclosing all of ``spheres`` (n, 4): centre of their box, largest reach."""
    lo = np.min(spheres[:, :3] - spheres[:, 3:], axis=0)
    hi = np.max(spheres[:, :3] + spheres[:, 3:], axis=0)
    c = (lo + hi) / 2.0
    r = float(np.max(np.linalg.norm(spheres[:, :3] - c, axis=1) + spheres[:, 3]))
    return np.array([c[0], c[1], c[2], r + PAD])


def cylinder_spheres(radius: float, half_length: float) -> FloatArray:
    """Spheres covering a solid cylinder (axis z, centred), at most ~12 % wider than it."""
    k = max(int(np.ceil(half_length / (0.5 * radius))), 1)
    h = half_length / k
    z = -half_length + (2 * np.arange(k) + 1) * h
    r = np.full(k, np.hypot(radius, h) + PAD)
    return np.column_stack([np.zeros(k), np.zeros(k), z, r])


def capsule_spheres(radius: float, half_length: float) -> FloatArray:
    """Spheres covering a capsule (axis z, centred): the cylinder part, and the two caps."""
    caps = np.array([[0.0, 0.0, -half_length, radius + PAD], [0.0, 0.0, half_length, radius + PAD]])
    return np.vstack([cylinder_spheres(radius, half_length), caps])


def box_spheres(half: FloatArray, cell: float) -> FloatArray:
    """Spheres covering a solid box of half extents ``half`` (3,) centred at the origin."""
    h = np.asarray(half, dtype=np.float64)
    counts = np.maximum(np.ceil(2.0 * h / cell).astype(int), 1)
    cell_half = h / counts
    axes = [-h[i] + (2 * np.arange(counts[i]) + 1) * cell_half[i] for i in range(3)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    r = np.full((grid.shape[0], 1), float(np.linalg.norm(cell_half)) + PAD)
    return np.hstack([grid, r])


def triangle_spheres(triangles: FloatArray, cell: float) -> FloatArray:
    """Spheres covering the surface of a triangle soup ``triangles`` (n, 3, 3), metres.

    Each triangle is split into four (at its edge midpoints) until the ball
    centred at its centroid through its farthest vertex — which holds the whole
    triangle — has radius at most ``cell / 2``; the balls are then gathered per
    voxel of side ``cell`` into one sphere enclosing them all.
    """
    tri = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    small: list[FloatArray] = []
    while tri.shape[0]:
        c = tri.mean(axis=1)
        r = np.max(np.linalg.norm(tri - c[:, None], axis=2), axis=1)
        ok = r <= cell / 2.0
        small.append(np.column_stack([c[ok], r[ok]]))
        big = tri[~ok]
        a, b, d = big[:, 0], big[:, 1], big[:, 2]
        ab, bd, da = (a + b) / 2.0, (b + d) / 2.0, (d + a) / 2.0
        tri = np.concatenate(
            [
                np.stack([a, ab, da], axis=1),
                np.stack([ab, b, bd], axis=1),
                np.stack([da, bd, d], axis=1),
                np.stack([ab, bd, da], axis=1),
            ]
        )
    balls = np.vstack(small)
    return _gather(balls, cell)


def _enclosing_runs(balls: FloatArray, starts: IndexArray) -> FloatArray:
    """:func:`enclosing` of each run ``balls[starts[i]:starts[i + 1]]``, shape (runs, 4)."""
    s0 = starts[:-1]
    lo = np.minimum.reduceat(balls[:, :3] - balls[:, 3:], s0, axis=0)
    hi = np.maximum.reduceat(balls[:, :3] + balls[:, 3:], s0, axis=0)
    c = (lo + hi) / 2.0
    run = np.repeat(np.arange(len(s0)), np.diff(starts))
    reach = np.linalg.norm(balls[:, :3] - c[run], axis=1) + balls[:, 3]
    r = np.maximum.reduceat(reach, s0) + PAD
    return np.column_stack([c, r])


def _voxel_runs(balls: FloatArray, side: float) -> tuple[FloatArray, IndexArray]:
    """``balls`` sorted by voxel of side ``side`` (by centre), and the start of each voxel's run."""
    cells = np.floor(balls[:, :3] / side).astype(np.int64)
    cells -= cells.min(axis=0)
    span = cells.max(axis=0) + 1
    keys = (cells[:, 0] * span[1] + cells[:, 1]) * span[2] + cells[:, 2]
    order = np.argsort(keys, kind="stable")
    starts = np.concatenate([[0], np.flatnonzero(np.diff(keys[order])) + 1, [len(balls)]])
    return balls[order], starts.astype(np.intp)


def _gather(balls: FloatArray, cell: float) -> FloatArray:
    """One enclosing sphere per voxel of side ``cell`` (by ball centre), shape (m, 4)."""
    sorted_balls, starts = _voxel_runs(balls, cell)
    return _enclosing_runs(sorted_balls, starts)


def group_cover(spheres: FloatArray, group: float) -> SphereCover:
    """Group ``spheres`` (n, 4) per voxel of side ``group`` (by centre) under enclosing spheres."""
    s, starts = _voxel_runs(np.asarray(spheres, dtype=np.float64).reshape(-1, 4), group)
    rng = np.column_stack([starts[:-1], starts[1:]]).astype(np.intp)
    groups = _enclosing_runs(s, starts)
    return SphereCover(s, groups, rng, enclosing(groups))


def mesh_triangles(geometry: coal.BVHModelBase) -> FloatArray:
    """Triangle vertices (n, 3, 3) of a coal BVH model, in its frame, metres."""
    verts = np.asarray(geometry.vertices(), dtype=np.float64).reshape(-1, 3)
    faces = np.empty((geometry.num_tris, 3), dtype=np.intp)
    for i in range(geometry.num_tris):
        t = geometry.tri_indices(i)
        faces[i] = (t[0], t[1], t[2])
    return np.asarray(verts[faces], dtype=np.float64)


def cover_geometry(
    geometry: coal.CollisionGeometry, *, cell: float = 0.012, group: float = 0.06
) -> SphereCover:
    """A conservative sphere cover of a coal geometry, in its own frame.

    Parameters
    ----------
    geometry : coal.CollisionGeometry
        Sphere, Cylinder, Capsule, Box or BVH mesh (others: their bounding box).
    cell : float
        Target size of the spheres of boxes and meshes, metres.
    group : float
        Voxel side of the groups, metres.
    """
    if isinstance(geometry, coal.Sphere):
        s = np.array([[0.0, 0.0, 0.0, float(geometry.radius) + PAD]])
    elif isinstance(geometry, coal.Cylinder):
        s = cylinder_spheres(float(geometry.radius), float(geometry.halfLength))
    elif isinstance(geometry, coal.Capsule):
        s = capsule_spheres(float(geometry.radius), float(geometry.halfLength))
    elif isinstance(geometry, coal.Box):
        s = box_spheres(np.asarray(geometry.halfSide, dtype=np.float64), cell)
    elif isinstance(geometry, coal.BVHModelBase):
        tri = mesh_triangles(geometry)
        area = (
            0.5
            * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum()
        )
        # at most about MAX_MESH_SPHERES spheres: a large mesh (Baxter's pedestal) gets larger ones
        s = triangle_spheres(tri, max(cell, float(np.sqrt(area / MAX_MESH_SPHERES))))
    else:
        geometry.computeLocalAABB()
        lo = np.asarray(geometry.aabb_local.min_, dtype=np.float64)
        hi = np.asarray(geometry.aabb_local.max_, dtype=np.float64)
        s = box_spheres((hi - lo) / 2.0, cell)
        s[:, :3] += (lo + hi) / 2.0
    return group_cover(s, group)


def transform_cover(cover: SphereCover, t: FloatArray) -> SphereCover:
    """The cover moved by a rigid transform ``t`` (4, 4) (radii unchanged)."""

    def move(s: FloatArray) -> FloatArray:
        out = s.copy()
        out[..., :3] = s[..., :3] @ t[:3, :3].T + t[:3, 3]
        return out

    return SphereCover(move(cover.spheres), move(cover.groups), cover.group_range,
                       move(cover.bound))  # fmt: skip
