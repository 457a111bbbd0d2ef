"""Collision geometry of the parts: STL meshes as coal BVH models, boxes as a fallback.

The 3rdHand part meshes (``data/3rdhand/meshes/*.stl``) are in millimetres in
the part's own frame; :func:`load_mesh` scales them to metres and caches one
BVH per file and scale, so placing the same leg four times builds it once.
"""

from __future__ import annotations

import os
from functools import lru_cache
from pathlib import Path

import coal
import numpy as np
from numpy.typing import ArrayLike

from thirdhand.arrays import FloatArray
from thirdhand.errors import ThirdhandError
from thirdhand.io.stl import read_stl


def mesh_from_triangles(triangles: ArrayLike) -> coal.BVHModelOBBRSS:
    """A coal BVH model from triangle vertices.

    Parameters
    ----------
    triangles : array_like, shape (n_triangles, 3, 3)
        Vertex coordinates, metres, in the object's frame.

    Raises
    ------
    ThirdhandError
        If the array is empty or not of shape (n, 3, 3).
    """
    tri = np.asarray(triangles, dtype=np.float64)
    if tri.ndim != 3 or tri.shape[1:] != (3, 3) or tri.shape[0] == 0:
        raise ThirdhandError(f"expected triangles of shape (n, 3, 3), n > 0, got {tri.shape}")
    verts, inverse = np.unique(tri.reshape(-1, 3), axis=0, return_inverse=True)
    faces = inverse.reshape(-1, 3).astype(np.int64)
    model = coal.BVHModelOBBRSS()
    model.beginModel(faces.shape[0], verts.shape[0])
    model.addVertices(verts)
    model.addTriangles(faces)
    model.endModel()
    model.computeLocalAABB()
    return model


@lru_cache(maxsize=64)
def _cached_mesh(path: str, scale: float) -> coal.BVHModelOBBRSS:
    return mesh_from_triangles(read_stl(path) * scale)


def load_mesh(path: str | os.PathLike[str], scale: float = 1e-3) -> coal.BVHModelOBBRSS:
    """Read an STL file into a (cached) coal BVH model.

    Parameters
    ----------
    path : path-like
        Binary or ASCII STL.
    scale : float
        Multiplies the file's coordinates; 1e-3 turns the 3rdHand millimetres into metres.

    Raises
    ------
    FormatError
        If the file cannot be read as STL.
    """
    return _cached_mesh(str(Path(path).resolve()), float(scale))


def box(size: ArrayLike) -> coal.Box:
    """A coal box of full side lengths ``size`` (3,), metres, centred on its frame's origin.

    Raises
    ------
    ThirdhandError
        If a side is not positive and finite.
    """
    s = np.asarray(size, dtype=np.float64)
    if s.shape != (3,) or not np.all(np.isfinite(s)) or np.any(s <= 0):
        raise ThirdhandError(f"box size: expected 3 positive lengths in metres, got {s.tolist()}")
    geom = coal.Box(float(s[0]), float(s[1]), float(s[2]))
    geom.computeLocalAABB()
    return geom


def local_aabb(geometry: coal.CollisionGeometry) -> tuple[FloatArray, FloatArray]:
    """Centre (3,) and half extents (3,) of a geometry's bounding box in its own frame."""
    geometry.computeLocalAABB()
    lo = np.asarray(geometry.aabb_local.min_, dtype=np.float64)
    hi = np.asarray(geometry.aabb_local.max_, dtype=np.float64)
    return (lo + hi) / 2.0, (hi - lo) / 2.0
