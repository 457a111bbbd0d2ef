"""Transfer: a task mapped onto another object set, the start of the person's adaptation.

A chair task becomes a bench task: objects are matched by name and role
(``seating`` ↔ ``seat``, ``leg1`` ↔ ``leg1``; paths such as ``/bench/leg1`` are
reduced to their last part), objects without a counterpart are dropped with a
note (the chair's back), and each remaining constraint keeps its orientation and
free DOFs while its position is scaled by the ratio of the parents' bounding
boxes, per axis of the parent frame, about the box centres:

``p' = c_new + (p − c_old) · e_new / e_old``

with ``c`` the box centres and ``e`` the extents. It is a guess (a bench with
the chair's seat size gets the chair's leg slots), so transferred constraints
whose position was scaled get half their confidence: the clarification round
asks about them first. The plan keeps the steps whose objects remain, its
partial order re-linked through the dropped steps.

The target object set (``--to``) is one of:

- a synthetic scene name (``bench``, ``chair``...): the objects of
  ``truth_task(make_scene(name))``, with their meshes and bounding boxes;
- a 3rdHand scene file ``scene_*.json`` (``{"objects": {"/bench/leg1": {"type":
  "leg", "mesh": "bench_leg.stl", ...}}}``), meshes next to it;
- a folder holding exactly one ``scene_*.json``, or else STL files, one per
  object, named after it (``seat.stl``, ``leg1.stl``...).

Meshes in millimetres (an extent above 5 units) get ``scale = 0.001``. A mesh's
body frame is unknown, so it is taken from the matched source object: the mesh's
axes are paired with the source body axes by extent (longest with longest), and
its box is the source box scaled to the mesh's extents about the body origin.
"""

from __future__ import annotations

import functools
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from thirdhand.errors import ThirdhandError
from thirdhand.task.meshes import ROLE_SYNONYMS, align_bounds, mesh_scale, same_role_mesh
from thirdhand.task.model import TaskFile, TaskObject
from thirdhand.task.stages import TransferBlock


class TransferError(ThirdhandError):
    """The target object set cannot be read, or nothing of the task maps onto it."""


@dataclass(frozen=True)
class TargetSet:
    """The objects a task is transferred onto.

    Attributes
    ----------
    name : str
        How the set was named (scene name or path).
    objects : list of TaskObject
    body_frames : bool
        True when the objects' bounding boxes are in their body frames (a synthetic
        scene); False for meshes (the body frame is taken from the source object).
    mesh_bounds : dict of str to (ndarray, ndarray)
        Per mesh object, its scaled mesh box (metres, mesh coordinates).
    """

    name: str
    objects: list[TaskObject]
    body_frames: bool = True
    mesh_bounds: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)


@dataclass(frozen=True)
class TransferResult:
    """A transferred task and what happened on the way.

    Attributes
    ----------
    task : TaskFile
    mapping : dict of str to str
        Source object name to target object name.
    notes : list of str
        Dropped objects, constraints and steps, objects without a constraint, scales.
    """

    task: TaskFile
    mapping: dict[str, str]
    notes: list[str]


def _key(name: str) -> tuple[str, str, int | None]:
    """(short name, role, index) of an object name: ``/bench/leg3`` -> (leg3, leg, 3)."""
    short = name.rstrip("/").rsplit("/", 1)[-1].lower()
    m = re.match(r"^(.*?)[_\-\s]*(\d+)$", short)
    stem, index = (m.group(1), int(m.group(2))) if m else (short, None)
    return short, ROLE_SYNONYMS.get(stem, stem), index


def match_objects(source: Sequence[str], target: Sequence[str]) -> dict[str, str]:
    """Pair source and target object names.

    First identical short names, then the same role and index (``seating1`` ↔
    ``seat1``), then the same role in the order of the indices (``leg`` ↔ ``leg1``).

    Returns
    -------
    dict of str to str
        Source name to target name; unmatched names are absent.
    """
    out: dict[str, str] = {}
    free = list(target)
    keys = {n: _key(n) for n in [*source, *target]}
    for rule in (lambda a, b: a[0] == b[0], lambda a, b: a[1:] == b[1:]):
        for s in source:
            if s in out:
                continue
            for t in free:
                if rule(keys[s], keys[t]):
                    out[s] = t
                    free.remove(t)
                    break
    rest_s = sorted((s for s in source if s not in out), key=lambda n: (keys[n][2] or 0, n))
    for s in rest_s:
        for t in sorted(free, key=lambda n: (keys[n][2] or 0, n)):
            if keys[s][1] == keys[t][1]:
                out[s] = t
                free.remove(t)
                break
    return out


def _mesh_bounds(path: Path) -> tuple[np.ndarray, np.ndarray, float]:
    from thirdhand.io.stl import read_stl

    tri = read_stl(path).reshape(-1, 3)
    if not tri.size:
        raise TransferError(f"{path}: mesh has no triangles")
    lo, hi = tri.min(axis=0), tri.max(axis=0)
    scale = mesh_scale(lo, hi)
    return lo * scale, hi * scale, scale


def _mesh_set(name: str, entries: list[tuple[str, Path]]) -> TargetSet:
    objects, bounds = [], {}
    for obj_name, named in entries:
        mesh = named if named.is_file() else same_role_mesh(named)
        if mesh is None:
            raise TransferError(f"{name}: mesh {named} of object {obj_name!r} not found")
        lo, hi, scale = _mesh_bounds(mesh)
        objects.append(TaskObject(name=obj_name, kind="part", mesh=mesh.name, scale=scale))
        bounds[obj_name] = (lo, hi)
    return TargetSet(name=name, objects=objects, body_frames=False, mesh_bounds=bounds)


def _scene_file(path: Path) -> TargetSet:
    from thirdhand.errors import FormatError
    from thirdhand.task.scene_file import read_scene

    try:
        objs = read_scene(path)
    except FormatError as exc:
        raise TransferError(str(exc)) from None
    return _mesh_set(str(path), [(_key(key)[0], obj.mesh) for key, obj in objs.items()])


@functools.lru_cache(maxsize=8)
def _scene_target(name: str) -> TargetSet:
    """The objects of a synthetic scene's ground truth (made once per process)."""
    from thirdhand.synth import make_scene
    from thirdhand.synth.task import truth_task

    truth = truth_task(make_scene(name, seed=0, sensor=None))
    return TargetSet(name=name, objects=list(truth.objects))


def load_target(to: str | os.PathLike[str]) -> TargetSet:
    """The target object set named by ``--to`` (see the module notes).

    Raises
    ------
    TransferError
        Neither a scene name nor a readable scene file or mesh folder.
    """
    from thirdhand.synth import SCENES

    text = os.fspath(to)
    if text in SCENES and not Path(text).exists():
        return _scene_target(text)
    p = Path(text)
    if p.is_file() and p.suffix == ".json":
        return _scene_file(p)
    if p.is_dir():
        scenes = sorted(p.glob("scene_*.json"))
        if len(scenes) == 1:
            return _scene_file(scenes[0])
        if len(scenes) > 1:
            names = ", ".join(s.name for s in scenes)
            raise TransferError(f"{p}: several scene files ({names}); name one of them")
        stls = sorted(f for f in p.iterdir() if f.suffix.lower() == ".stl")
        if not stls:
            raise TransferError(f"{p}: no scene_*.json and no .stl mesh in this folder")
        return _mesh_set(str(p), [(f.stem, f) for f in stls])
    raise TransferError(
        f"--to {text!r}: not a scene name ({', '.join(SCENES)}), a scene_*.json or a mesh folder"
    )


def _box(obj: TaskObject) -> tuple[np.ndarray, np.ndarray] | None:
    if obj.bbox_min is None or obj.bbox_max is None:
        return None
    return np.asarray(obj.bbox_min, float), np.asarray(obj.bbox_max, float)


def _fit_mesh(
    src: TaskObject, target: TaskObject, bounds: tuple[np.ndarray, np.ndarray]
) -> TaskObject:
    """A mesh object given a body frame like the source object's (module notes)."""
    mlo, mhi = bounds
    m_ext = np.sort(mhi - mlo)[::-1]
    box = _box(src)
    if box is None:
        body_lo, body_hi = mlo - (mlo + mhi) / 2, mhi - (mlo + mhi) / 2
    else:
        slo, shi = box
        s_ext = shi - slo
        rank = np.argsort(-s_ext, kind="stable")
        t_ext = np.empty(3)
        t_ext[rank] = m_ext
        ratio = np.where(s_ext > 0, t_ext / np.where(s_ext > 0, s_ext, 1.0), 1.0)
        body_lo, body_hi = slo * ratio, shi * ratio
        flat = s_ext <= 0
        body_lo[flat], body_hi[flat] = -t_ext[flat] / 2, t_ext[flat] / 2
    pose = align_bounds(mlo, mhi, body_lo, body_hi)
    return target.model_copy(
        update={
            "mesh_to_body": pose,
            "bbox_min": tuple(float(v) for v in body_lo),
            "bbox_max": tuple(float(v) for v in body_hi),
        }
    )


def _relink(preds: list[list[int]], kept: list[int]) -> list[list[int]]:
    """Predecessors among the kept steps, through dropped ones, transitively reduced."""
    closure: list[set[int]] = []
    for p in preds:
        s: set[int] = set()
        for j in p:
            s |= {j} | closure[j]
        closure.append(s)
    new_of = {old: new for new, old in enumerate(kept)}
    out = []
    for old in kept:
        keep = {a for a in closure[old] if a in new_of}
        reduced = [a for a in keep if not any(a in closure[b] for b in keep if b != a)]
        out.append(sorted(new_of[a] for a in reduced))
    return out


def transfer_task(task: TaskFile, target: TargetSet) -> TransferResult:
    """Map ``task`` onto the parts of ``target`` (see the module notes).

    Returns
    -------
    TransferResult

    Raises
    ------
    TransferError
        If no constraint of the task maps onto the target.
    """
    notes: list[str] = []
    parts = [o for o in target.objects if o.kind == "part"]
    src_parts = [o for o in task.objects if o.kind == "part"]
    mapping = match_objects([o.name for o in src_parts], [o.name for o in parts])
    by_target = {o.name: o for o in parts}
    src_by_name = task.objects_by_name()
    new_objects: dict[str, TaskObject] = {}
    for src in src_parts:
        t = mapping.get(src.name)
        if t is None:
            notes.append(f"object {src.name}: no counterpart in {target.name}; dropped")
            continue
        obj = by_target[t]
        if not target.body_frames:
            obj = _fit_mesh(src, obj, target.mesh_bounds[t])
        new_objects[t] = obj
    for o in parts:
        if o.name not in new_objects:
            notes.append(f"object {o.name}: new in {target.name}, no constraint; place it yourself")
            new_objects[o.name] = o
    # The source's other bodies (fingers, tools) stay: the keyframes show them.
    for o in task.objects:
        if o.kind != "part" and o.name not in new_objects:
            new_objects[o.name] = o
            mapping.setdefault(o.name, o.name)
    constraints = []
    for c in task.constraints:
        if c.parent not in mapping or c.child not in mapping:
            missing = c.parent if c.parent not in mapping else c.child
            notes.append(f"constraint {c.id} ({c.parent} -> {c.child}): {missing} dropped; dropped")
            continue
        parent_new = mapping[c.parent]
        old_box, new_box = _box(src_by_name[c.parent]), _box(new_objects[parent_new])
        pos = np.asarray(c.pos, float)
        confidence = c.confidence
        if old_box is None or new_box is None:
            notes.append(f"constraint {c.id}: no bounding box of {c.parent}; position kept")
        else:
            e_old, e_new = old_box[1] - old_box[0], new_box[1] - new_box[0]
            ratio = np.where(e_old > 0, e_new / np.where(e_old > 0, e_old, 1.0), 1.0)
            centre_old, centre_new = (old_box[0] + old_box[1]) / 2, (new_box[0] + new_box[1]) / 2
            pos = centre_new + (pos - centre_old) * ratio
            if not np.allclose(ratio, 1.0):
                confidence = confidence / 2
                notes.append(
                    f"constraint {c.id}: position scaled by {np.round(ratio, 3).tolist()} "
                    f"({c.parent} -> {parent_new} bounding box)"
                )
        constraints.append(
            c.model_copy(
                update={
                    "parent": parent_new,
                    "child": mapping[c.child],
                    "pos": tuple(float(v) for v in pos),
                    "confidence": confidence,
                }
            )
        )
    if not constraints:
        raise TransferError(f"no constraint of the task maps onto {target.name}")
    kept_ids = {c.id for c in constraints}
    kept = [
        k
        for k, s in enumerate(task.plan)
        if s.parent in mapping
        and s.child in mapping
        and (s.constraint is None or s.constraint in kept_ids)
    ]
    for k, s in enumerate(task.plan):
        if k not in kept:
            notes.append(f"plan step {k} ({s.parent} -> {s.child}): dropped")
    afters: list[list[int] | None]
    if all(s.after is None for s in task.plan):
        afters = [None] * len(kept)
    else:
        afters = list(_relink(task.predecessors(), kept))
    plan = []
    for k, after in zip(kept, afters, strict=True):
        s = task.plan[k]
        keyframe = {mapping[n]: p for n, p in s.keyframe.items() if n in mapping}
        plan.append(
            s.model_copy(
                update={
                    "parent": mapping[s.parent],
                    "child": mapping[s.child],
                    "keyframe": keyframe,
                    "after": after,
                }
            )
        )
    stage = TransferBlock(
        to=target.name,
        mapping={k: v for k, v in mapping.items() if src_by_name[k].kind == "part"},
        notes=list(notes),
    )
    new = TaskFile.new(
        objects=list(new_objects.values()),
        constraints=constraints,
        plan=plan,
        stages={"transfer": stage},
        inputs=task.provenance.inputs,
        parameters={"source": "thirdhand transfer", "to": target.name},
    )
    return TransferResult(task=new, mapping=mapping, notes=notes)


def transfer(task: TaskFile, to: str | os.PathLike[str]) -> TransferResult:
    """:func:`transfer_task` onto :func:`load_target` ``(to)``."""
    return transfer_task(task, load_target(to))
