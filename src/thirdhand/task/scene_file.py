"""3rdHand scene files (``scene_*.json``): which mesh each tracked body carries, and where.

A scene file names, per tracked object, its mesh file and a ``transformation``
between the tracking sensor and the mesh::

    {"objects": {"/toolbox/side_left": {"mesh": "ToolboxPart3.stl",
                                        "transformation": [[x, y, z], [qx, qy, qz, qw]],
                                        "type": "side_short"}, ...},
     "agents": {"/human/lh/thumb": {"type": "digit"}, ...}}

Neither the quaternion order nor the direction of the transformation is
documented; both were decided from the real recording ``toolbox_coop_4`` and its
``scene_toolbox_coop.json`` (``tests/test_scene_file.py`` repeats the check):

- **The quaternion is scalar-last** ``(x, y, z, w)``. ``side_left`` reads
  ``[0, 0, 1, -6.1e-17]``: ``6.123e-17`` is ``cos(π/2)`` in floating point, the
  scalar part of a half turn, and it sits last.
- **The transformation is the sensor's pose in the mesh frame** (the mesh's pose
  in the body frame is its inverse). Of the four readings (scalar first or last,
  as given or inverted), only the inverses make the two boards touch during the
  last 35 s, when they are screwed together: a gap of 0.4 mm (median; 0.1–3.4 mm,
  10th–90th percentile) for this reading, 6–7 mm as given. With it the left thumb
  comes within 2–18 mm of the board's surface in 9 of the 12 labelled grasps
  (the scalar-first inverse: 2–50 mm), and the boards meet along an edge (6 % of
  the surface points within 2 mm), not at one point (0.1 %) with 8.5 mm of
  overlap as the scalar-first inverse would have them.

Mesh units are decided by extent like elsewhere (:func:`~thirdhand.task.meshes.mesh_scale`:
the 3rdHand meshes are millimetres). The translation's unit differs between the
files: metres in the toolbox scenes (``0.06``), the mesh's millimetres in the chair
and bench scenes (``280``, ``157.5``). A translation with a component beyond
:data:`MAX_METRES` is read in the mesh's units: no sensor sits 2 m from its part.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.errors import FormatError
from thirdhand.io.stl import read_stl
from thirdhand.readlimits import MAX_SIDE_BYTES, loads_json, read_text_input
from thirdhand.task.geometry import Pose
from thirdhand.task.meshes import mesh_scale, mesh_search_path, same_role_mesh

#: The largest translation component (absolute) read as metres; beyond, mesh units.
MAX_METRES = 2.0


@dataclass(frozen=True)
class SceneObject:
    """One object of a scene file.

    Attributes
    ----------
    name : str
        The tracked body's name (``/toolbox/side_left``).
    mesh : Path
        The mesh file, relative names taken from the scene file's folder.
    body_to_mesh : tuple of ndarray, shape (3,) and (4,)
        The sensor's pose in the mesh frame: position (m), quaternion (x, y, z, w).
        Identity when the file gives no transformation.
    type : str or None
        The file's part type (``side_short``), if any.
    """

    name: str
    mesh: Path
    body_to_mesh: tuple[FloatArray, FloatArray]
    type: str | None = None


def read_scene(path: str | os.PathLike[str]) -> dict[str, SceneObject]:
    """The objects of a 3rdHand scene file, by body name.

    Raises
    ------
    FormatError
        Unreadable JSON, no ``objects``, an object without a mesh file name, or a
        malformed transformation (one line naming the object and the field).
    """
    p = Path(path)

    def error(m: str) -> FormatError:
        return FormatError(p, f"cannot read 3rdHand scene file: {m}")

    text = read_text_input(p, what="scene file", limit=MAX_SIDE_BYTES, error=error)
    data = loads_json(text, error=error, strict=True)
    objs = data.get("objects") if isinstance(data, dict) else None
    if not isinstance(objs, dict) or not objs:
        raise FormatError(p, 'expected {"objects": {name: {"mesh": ...}}}')
    out: dict[str, SceneObject] = {}
    for name, spec in objs.items():
        where = f"objects.{name}"
        if not isinstance(spec, dict) or not isinstance(spec.get("mesh"), str) or not spec["mesh"]:
            raise FormatError(p, "expected a mesh file name", where=f"{where}.mesh")
        mesh = Path(spec["mesh"])
        kind = spec.get("type")
        out[str(name)] = SceneObject(
            name=str(name),
            mesh=mesh if mesh.is_absolute() else p.parent / mesh,
            body_to_mesh=_transformation(p, where, spec.get("transformation")),
            type=kind if isinstance(kind, str) else None,
        )
    return out


def _transformation(path: Path, where: str, value: Any) -> tuple[FloatArray, FloatArray]:
    if value is None:
        return np.zeros(3), se3.quat_identity()
    ok = (
        isinstance(value, list)
        and len(value) == 2
        and all(isinstance(v, list) for v in value)
        and [len(v) for v in value] == [3, 4]
        and all(
            isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)
            for v in value
            for x in v
        )
    )
    if not ok:
        raise FormatError(
            path,
            "expected [[x, y, z], [qx, qy, qz, qw]] of finite numbers",
            where=f"{where}.transformation",
        )
    q = np.asarray(value[1], dtype=np.float64)
    norm = float(np.linalg.norm(q))
    if abs(norm - 1.0) > 1e-3:
        raise FormatError(
            path, f"quaternion norm {norm:.4g}, expected 1", where=f"{where}.transformation"
        )
    return np.asarray(value[0], dtype=np.float64), q / norm


def scene_geometry(
    path: str | os.PathLike[str], names: Sequence[str], *, parts: Sequence[str] | None = None
) -> dict[str, dict[str, Any]]:
    """Task-object geometry fields for the bodies of ``names`` that a scene file lists.

    A scene file is the recording's only when it lists some of its bodies and,
    when ``parts`` are given, every part (as :func:`find_scene` requires of the
    file it finds): a scene of another object set is refused, not reported as used.

    Parameters
    ----------
    path : path-like
        The ``scene_*.json`` file.
    names : sequence of str
        Body names of the recording.
    parts : sequence of str, optional
        The recording's parts (bodies of kind ``part``), each of which the scene
        must list.

    Returns
    -------
    dict of str to dict
        Per listed body: ``mesh`` (the file's path, the scene file's folder joined
        to a relative name; a missing ``bench_seating.stl`` is the
        ``bench_sitting.stl`` beside it, :func:`~thirdhand.task.meshes.same_role_mesh`),
        ``scale`` (0.001 for millimetres),
        ``mesh_to_body`` (the inverse of the file's transformation) and
        ``bbox_min``/``bbox_max`` (the mesh's box in the body frame, metres).

    Raises
    ------
    FormatError
        A malformed scene file, a mesh file it names that is missing or malformed,
        or a scene that lists none of ``names`` or not every one of ``parts``.
    """
    scene = read_scene(path)
    listed = sorted(set(scene))
    if not set(names) & set(scene):
        raise FormatError(
            path,
            f"lists none of the recording's bodies (it lists {', '.join(listed[:4])}"
            f"{', …' if len(listed) > 4 else ''}): a scene of another object set",
        )
    missing = [p for p in parts or () if p not in scene]
    if missing:
        raise FormatError(
            path,
            f"does not list the recording's part {missing[0]!r}"
            f"{f' and {len(missing) - 1} more' if len(missing) > 1 else ''}: "
            "a scene of another object set",
        )
    out: dict[str, dict[str, Any]] = {}
    for name in names:
        obj = scene.get(name)
        if obj is None:
            continue
        mesh = obj.mesh if obj.mesh.is_file() else same_role_mesh(obj.mesh)
        if mesh is None:
            raise FormatError(path, f"mesh file {obj.mesh} not found", where=f"objects.{name}")
        vertices = read_stl(mesh).reshape(-1, 3)
        if not vertices.size:
            raise FormatError(mesh, "the mesh has no triangles")
        scale = mesh_scale(vertices.min(axis=0), vertices.max(axis=0))
        offset, turn = obj.body_to_mesh
        if float(np.max(np.abs(offset))) > MAX_METRES:
            offset = offset * scale
        pos, quat = se3.pose_invert(offset, turn)
        in_body = (vertices * scale) @ se3.matrix_from_quat(quat).T + pos
        out[name] = {
            "mesh": os.fspath(mesh),
            "scale": scale,
            "mesh_to_body": Pose.model_validate(
                {"pos": [float(v) for v in pos], "quat": [float(v) for v in quat]}
            ),
            "bbox_min": [float(v) for v in in_body.min(axis=0)],
            "bbox_max": [float(v) for v in in_body.max(axis=0)],
        }
    return out


def find_scene(names: Sequence[str], search: Sequence[str | os.PathLike[str]] = ()) -> Path | None:
    """The scene file along the mesh search path that lists every part of ``names``.

    Parameters
    ----------
    names : sequence of str
        The recording's part names (bodies of kind ``part``).
    search : sequence of path-like
        Folders tried first (then ``THIRDHAND_MESH_PATH``).

    Returns
    -------
    Path or None
        None when no scene file lists them all, or ``names`` is empty.

    Raises
    ------
    FormatError
        When several scene files list them all and disagree on a part's mesh or
        transformation (name one with ``--scene``).
    """
    if not names:
        return None
    found: list[Path] = []
    scenes: list[Mapping[str, SceneObject]] = []
    for folder in mesh_search_path(search):
        for candidate in sorted(folder.glob("scene_*.json")) if folder.is_dir() else []:
            try:
                listed: Mapping[str, SceneObject] = read_scene(candidate)
            except FormatError:
                continue
            if set(names) <= set(listed) and candidate not in found:
                found.append(candidate)
                scenes.append(listed)
    # Files that agree on every part (the toolbox scenes repeat two boards) are one answer.
    if len(found) > 1 and all(_same(scenes[0], other, names) for other in scenes[1:]):
        found = found[:1]
    if len(found) > 1:
        raise FormatError(
            found[0].parent,
            f"several scene files list every part ({', '.join(str(f) for f in found)}); "
            "name one with --scene",
        )
    return found[0] if found else None


def _same(a: Mapping[str, SceneObject], b: Mapping[str, SceneObject], names: Sequence[str]) -> bool:
    """Whether two scene files give the parts ``names`` the same mesh and transformation."""
    return all(
        a[n].mesh.name == b[n].mesh.name
        and np.allclose(a[n].body_to_mesh[0], b[n].body_to_mesh[0], atol=1e-9)
        and np.allclose(a[n].body_to_mesh[1], b[n].body_to_mesh[1], atol=1e-9)
        for n in names
    )
