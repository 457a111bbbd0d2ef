"""Part meshes of a task: where the file is, how it sits in the body frame, its triangles.

A task object names its mesh file (``TaskObject.mesh``), the mesh units
(``scale``, e.g. 0.001 for millimetres) and the mesh's pose in the body frame
(``mesh_to_body``). The review GUI draws the triangles, execution checks them
for collisions; an object whose mesh is not found falls back to its bounding
box (``bbox_min``/``bbox_max``).

Mesh files are looked up, in order: as given when absolute, relative to the
task file's folder, then in every folder of the search path (the ``search``
argument, then the ``THIRDHAND_MESH_PATH`` environment variable,
``os.pathsep``-separated). A learned task records the files it found relative
to the task file (:func:`anchor_meshes`), so it needs no search path later.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from thirdhand.arrays import FloatArray
from thirdhand.io.stl import read_stl
from thirdhand.se3 import matrix_from_quat, quat_from_matrix
from thirdhand.task.geometry import Pose
from thirdhand.task.model import TaskFile, TaskObject

if TYPE_CHECKING:
    from thirdhand.demonstration import Demonstration


#: Environment variable: extra folders (``os.pathsep``-separated) searched for meshes.
MESH_PATH_ENV = "THIRDHAND_MESH_PATH"


#: Bounding boxes of the 3rdHand mesh files, ``(min, max)`` in the files' millimetres
#: (read by :func:`thirdhand.io.stl.stl_bounds`; a test checks them against the files).
MESH_BOUNDS_MM: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = {
    "chair_seating.stl": ((-150.0, -150.0, 0.0), (150.0, 150.0, 20.0)),
    "chair_leg.stl": ((-40.0, -40.0, 0.0), (40.0, 40.0, 280.0)),
    "chair_back.stl": ((-193.1, -320.0, 0.0), (193.1, 100.0, 30.0)),
    "bench_sitting.stl": ((0.4, 1.5, 1.5), (40.4, 301.5, 301.5)),
    "bench_leg.stl": ((1.8, 0.0, 1.8), (62.6, 240.0, 62.6)),
    "ToolboxPart1.stl": ((-195.0, -60.0, 0.0), (195.0, 120.1, 17.0)),
    "ToolboxPart2.stl": ((-100.0, 0.0, 0.0), (160.0, 120.0, 17.0)),
    "ToolboxPart3.stl": ((-212.5, 0.0, 0.0), (212.5, 120.0, 17.0)),
}


#: Names of the same role in different object sets.
ROLE_SYNONYMS: dict[str, str] = {
    "seating": "seat",
    "sitting": "seat",
    "seat": "seat",
    "leg": "leg",
    "back": "back",
    "backrest": "back",
}


def same_role_mesh(mesh: Path) -> Path | None:
    """A mesh next to ``mesh`` named with a synonym (``bench_seating`` -> ``bench_sitting``).

    The 3rdHand scene files name meshes that are stored under another word for the
    same role; the one STL file of the same prefix and role, or None.
    """

    def role(stem: str) -> tuple[str, str]:
        prefix, _, last = stem.lower().rpartition("_")
        return prefix, ROLE_SYNONYMS.get(last, last)

    want = role(mesh.stem)
    if not mesh.parent.is_dir():
        return None
    found = [f for f in sorted(mesh.parent.glob("*.stl")) if role(f.stem) == want]
    return found[0] if len(found) == 1 else None


def mesh_scale(lo: FloatArray, hi: FloatArray) -> float:
    """Metres per mesh unit, from the mesh's extent: millimetres when it spans over 5 units.

    A part larger than 5 m is not an assembly part, and one under 5 mm is not
    either, so the two readings cannot be confused for the parts of this domain.

    Parameters
    ----------
    lo, hi : array_like, shape (3,)
        The mesh's bounding box in file units.
    """
    return 1e-3 if float(np.max(np.asarray(hi, float) - np.asarray(lo, float))) > 5.0 else 1.0


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


def object_geometry(demo: Demonstration) -> dict[str, dict[str, Any]]:
    """Task-object geometry fields per body, from a recording's ``meta["geometry"]``.

    Synthetic scenes write it; a native-format recording carries it along.

    Returns
    -------
    dict of str to dict
        Per body with known geometry: ``bbox_min``/``bbox_max`` (body frame,
        metres) and, when the part has a 3rdHand mesh, ``mesh`` (file name, looked
        up along the mesh search path), ``scale`` (0.001, millimetres) and
        ``mesh_to_body`` (the scene's own, else the mesh bounding box aligned onto the
        body's).
    """
    geometry = demo.meta.get("geometry")
    out: dict[str, dict[str, Any]] = {}
    if not isinstance(geometry, Mapping):
        return out
    for name, g in geometry.items():
        if not isinstance(g, Mapping) or "bbox_min_m" not in g:
            continue
        lo = [float(v) for v in g["bbox_min_m"]]
        hi = [float(v) for v in g["bbox_max_m"]]
        fields: dict[str, Any] = {"bbox_min": lo, "bbox_max": hi}
        mesh = g.get("mesh")
        if isinstance(mesh, str) and mesh in MESH_BOUNDS_MM:
            mlo, mhi = (np.asarray(b, float) * 1e-3 for b in MESH_BOUNDS_MM[mesh])
            fields["mesh"] = mesh
            fields["scale"] = 1e-3
            given = g.get("mesh_to_body")
            fields["mesh_to_body"] = (
                Pose.model_validate(given)
                if isinstance(given, Mapping)
                else align_bounds(mlo, mhi, np.asarray(lo), np.asarray(hi))
            )
        out[str(name)] = fields
    return out


def _relative(path: Path, folder: Path) -> str:
    """``path`` relative to ``folder`` (POSIX separators), or absolute when it cannot be."""
    try:
        return Path(os.path.relpath(path.resolve(), folder.resolve())).as_posix()
    except ValueError:  # another drive (Windows)
        return path.resolve().as_posix()


def anchor_meshes(
    task: TaskFile,
    task_path: str | os.PathLike[str],
    search: Sequence[str | os.PathLike[str]] = (),
) -> TaskFile:
    """A copy of ``task`` whose meshes name the files found, relative to ``task_path``.

    Called when a learned task is written: the mesh files found now (beside the
    task file, along ``search`` and ``THIRDHAND_MESH_PATH``) are recorded by their
    path from the task file's folder, so ``review`` and ``execute`` find them with
    no flag and no environment variable. A mesh not found is left as named; the
    scene file of ``stages.scene`` is made relative the same way.
    """
    out = task.model_copy(deep=True)
    folder = Path(task_path).parent
    for obj in out.objects:
        found = resolve_mesh(obj, task_path, search)
        if found is not None:
            obj.mesh = _relative(found, folder)
    scene = out.stages.scene
    if scene is not None and scene.file is not None and Path(scene.file).is_file():
        scene.file = _relative(Path(scene.file), folder)
    return out


def missing_meshes(
    task: TaskFile,
    task_path: str | os.PathLike[str] | None = None,
    search: Sequence[str | os.PathLike[str]] = (),
) -> dict[str, str]:
    """Objects whose recorded mesh file is not found: object name to the mesh as recorded."""
    return {
        o.name: o.mesh
        for o in task.objects
        if o.mesh and resolve_mesh(o, task_path, search) is None
    }


def missing_mesh_note(
    task: TaskFile,
    task_path: str | os.PathLike[str] | None = None,
    search: Sequence[str | os.PathLike[str]] = (),
) -> str | None:
    """One line saying which recorded mesh files are missing and where they were looked for.

    None when every mesh the task names is found.
    """
    missing = missing_meshes(task, task_path, search)
    if not missing:
        return None
    listed = ", ".join(f"{n} ({m})" for n, m in missing.items())
    where = f"beside {task_path}" if task_path is not None else "in the current folder"
    return (
        f"mesh files not found, drawn and checked as boxes: {listed}; looked {where}, "
        f"in --meshes folders and along {MESH_PATH_ENV}"
    )
