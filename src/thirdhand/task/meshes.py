"""Part meshes of a task: where the file is, how it sits in the body frame, its triangles.

A task object names its mesh file (``TaskObject.mesh``), the mesh units
(``scale``, e.g. 0.001 for millimetres) and the mesh's pose in the body frame
(``mesh_to_body``). The review GUI draws the triangles, execution checks them
for collisions; an object whose mesh is not found falls back to its bounding
box (``bbox_min``/``bbox_max``).

Mesh files are looked up, in order: as given when absolute, next to the task
file, then in every folder of the search path (the ``search`` argument, then
the ``THIRDHAND_MESH_PATH`` environment variable, ``os.pathsep``-separated).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from thirdhand.io.stl import read_stl
from thirdhand.se3 import matrix_from_quat, quat_from_matrix
from thirdhand.task.geometry import Pose
from thirdhand.task.model import TaskObject

FloatArray = NDArray[np.float64]

#: Environment variable: extra folders (``os.pathsep``-separated) searched for meshes.
MESH_PATH_ENV = "THIRDHAND_MESH_PATH"


def mesh_search_path(search: Sequence[str | os.PathLike[str]] = ()) -> list[Path]:
    """The folders searched for mesh files: ``search`` then ``THIRDHAND_MESH_PATH``."""
    folders = [Path(s) for s in search]
    env = os.environ.get(MESH_PATH_ENV, "")
    folders += [Path(s) for s in env.split(os.pathsep) if s]
    return folders


def resolve_mesh(
    obj: TaskObject,
    task_path: str | os.PathLike[str] | None = None,
    search: Sequence[str | os.PathLike[str]] = (),
) -> Path | None:
    """The mesh file of ``obj``, or None when it names none or none is found.

    Parameters
    ----------
    obj : TaskObject
    task_path : path-like, optional
        The task file; relative mesh paths are tried next to it first.
    search : sequence of path-like
        Folders tried next (then ``THIRDHAND_MESH_PATH``).
    """
    if not obj.mesh:
        return None
    name = Path(obj.mesh)
    if name.is_absolute():
        return name if name.is_file() else None
    folders = ([Path(task_path).parent] if task_path is not None else []) + mesh_search_path(search)
    for folder in folders:
        for candidate in (folder / name, folder / name.name):
            if candidate.is_file():
                return candidate
    return None


def align_bounds(
    mesh_lo: FloatArray, mesh_hi: FloatArray, body_lo: FloatArray, body_hi: FloatArray
) -> Pose:
    """The pose of a mesh in a body frame that maps its bounding box onto the body's.

    Axes are paired by extent (the longest mesh axis onto the longest body axis,
    ties kept in axis order), the pairing made a proper rotation by flipping the
    last axis if needed, and the box centres matched. Boxes of distinct extents
    are matched exactly; symmetric parts (a square leg) are matched up to their
    symmetry, which is all a bounding box can tell.

    Parameters
    ----------
    mesh_lo, mesh_hi : array_like, shape (3,)
        The mesh's bounding box in its own (scaled) coordinates, metres.
    body_lo, body_hi : array_like, shape (3,)
        The object's bounding box in the body frame, metres.

    Returns
    -------
    Pose
        ``mesh_to_body``: maps scaled mesh coordinates into the body frame.
    """
    mlo, mhi = np.asarray(mesh_lo, float), np.asarray(mesh_hi, float)
    blo, bhi = np.asarray(body_lo, float), np.asarray(body_hi, float)
    m_order = np.argsort(-(mhi - mlo), kind="stable")
    b_order = np.argsort(-(bhi - blo), kind="stable")
    rot = np.zeros((3, 3))
    for mi, bi in zip(m_order, b_order, strict=True):
        rot[bi, mi] = 1.0
    if np.linalg.det(rot) < 0:
        rot[b_order[2], m_order[2]] = -1.0
    centre = rot @ ((mlo + mhi) / 2)
    pos = (blo + bhi) / 2 - centre
    q = quat_from_matrix(rot)
    return Pose.model_validate({"pos": [float(v) for v in pos], "quat": [float(v) for v in q]})


def body_triangles(
    obj: TaskObject,
    task_path: str | os.PathLike[str] | None = None,
    search: Sequence[str | os.PathLike[str]] = (),
) -> FloatArray | None:
    """The object's mesh triangles in its body frame, metres, or None without a mesh file.

    Returns
    -------
    ndarray, shape (n_triangles, 3, 3) or None
    """
    path = resolve_mesh(obj, task_path, search)
    if path is None:
        return None
    tri = read_stl(path) * (obj.scale if obj.scale is not None else 1.0)
    if obj.mesh_to_body is not None:
        rot = matrix_from_quat(np.asarray(obj.mesh_to_body.quat))
        tri = tri @ rot.T + np.asarray(obj.mesh_to_body.pos)
    return np.ascontiguousarray(tri, dtype=float)


def box_triangles(lo: Sequence[float], hi: Sequence[float]) -> FloatArray:
    """The 12 triangles of an axis-aligned box, outward normals by winding.

    Returns
    -------
    ndarray, shape (12, 3, 3)
    """
    lo_a, hi_a = np.asarray(lo, float), np.asarray(hi, float)
    corners = np.array([[(hi_a if (i >> k) & 1 else lo_a)[k] for k in range(3)] for i in range(8)])
    faces = [
        (0, 2, 3, 1),  # z = lo
        (4, 5, 7, 6),  # z = hi
        (0, 1, 5, 4),  # y = lo
        (2, 6, 7, 3),  # y = hi
        (0, 4, 6, 2),  # x = lo
        (1, 3, 7, 5),  # x = hi
    ]
    tris = [(a, b, c) for a, b, c, d in faces] + [(a, c, d) for a, b, c, d in faces]
    return corners[np.array(tris)]


def object_triangles(
    obj: TaskObject,
    task_path: str | os.PathLike[str] | None = None,
    search: Sequence[str | os.PathLike[str]] = (),
) -> FloatArray | None:
    """The mesh triangles when found, else the bounding box's, else None (body frame, m)."""
    tri = body_triangles(obj, task_path, search)
    if tri is not None:
        return tri
    if obj.bbox_min is not None and obj.bbox_max is not None:
        return box_triangles(obj.bbox_min, obj.bbox_max)
    return None
