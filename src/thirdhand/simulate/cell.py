"""The work cell of a task and a run, as the model holds it: table, parts, fastenings.

The table comes from the planner's work cell (:func:`thirdhand.execute.layout.make_workcell`),
the parts from the task's meshes (:func:`thirdhand.task.meshes.object_triangles`;
a part without a mesh is its bounding box, said once), each with its collision
pieces (:mod:`~thirdhand.simulate.parts`) and its start pose from the run.
"""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from thirdhand.arrays import FloatArray
from thirdhand.execute.layout import base_part, make_workcell
from thirdhand.simulate.carve import exact_pieces
from thirdhand.simulate.measure import box_corners
from thirdhand.simulate.model import CellModel, PartModel
from thirdhand.simulate.parts import (
    Piece,
    SimulateError,
    convex_hull,
    convex_pieces,
    mass_properties,
)
from thirdhand.simulate.plan import RunPlan
from thirdhand.simulate.settings import SimulateSettings
from thirdhand.task.meshes import body_triangles, box_triangles
from thirdhand.task.model import TaskFile


@dataclass
class BuiltCell:
    """The cell to compile and what building it found.

    Attributes
    ----------
    cell : CellModel
    corners : dict of str to ndarray (8, 3)
        Each part's bounding-box corners, body frame, metres.
    notes : list of str
        What the user should know (parts simulated as boxes).
    decomposition_s : float
        Wall-clock seconds of the convex decompositions (0 when all were cached).
    pieces : dict of str to int
        Collision pieces per part.
    """

    cell: CellModel
    corners: dict[str, FloatArray]
    notes: list[str] = field(default_factory=list)
    decomposition_s: float = 0.0
    pieces: dict[str, int] = field(default_factory=dict)


def build_cell(
    task: TaskFile,
    plan: RunPlan,
    settings: SimulateSettings,
    *,
    task_path: str | os.PathLike[str] | None = None,
    search: Sequence[str | os.PathLike[str]] = (),
) -> BuiltCell:
    """The cell model of ``task`` for the run ``plan``.

    Raises
    ------
    SimulateError
        A part of the run that has neither a mesh nor a bounding box, or whose
        decomposition fails.
    """
    wc = make_workcell(task, plan.robot, task_path=task_path, search=search)
    base = base_part(task)
    objects = {o.name: o for o in task.objects}
    cache = Path(settings.cache).expanduser() if settings.cache else None
    parts: list[PartModel] = []
    corners: dict[str, FloatArray] = {}
    boxes: list[str] = []
    pieces_n: dict[str, int] = {}
    spent = 0.0
    notes: list[str] = []
    for name in sorted(plan.start):
        obj = objects.get(name)
        if obj is None:
            raise SimulateError(f"part {name!r} of the run is not an object of the task")
        tri = body_triangles(obj, task_path, search)
        if tri is None:
            if obj.bbox_min is None or obj.bbox_max is None:
                raise SimulateError(f"part {name!r}: no mesh and no bounding box to simulate")
            tri = box_triangles(obj.bbox_min, obj.bbox_max)
            boxes.append(name)
            pieces = convex_hull(tri)
        elif settings.collision == "hull":
            pieces = convex_hull(tri)
        elif settings.collision == "exact" and (carved := exact_pieces(tri)) is not None:
            pieces = [Piece(v) for v in carved.pieces]
            if carved.missing_m3 > 0.01 * carved.volume_m3:
                notes.append(
                    f"part {name!r}: its exact pieces leave out {carved.missing_m3 * 1e6:.1f} cm³ "
                    "of it (a cavity far from convex)"
                )
        else:
            if settings.collision == "exact":
                notes.append(
                    f"part {name!r}: its mesh is not a closed surface: collides as its "
                    "approximate convex decomposition (CoACD)"
                )
            t0 = time.perf_counter()
            pieces, cached = convex_pieces(
                tri, name=f"part {name!r} ({obj.mesh})",
                threshold=settings.decomposition_threshold, cache=cache,
            )  # fmt: skip
            if not cached:
                spent += time.perf_counter() - t0
        verts = tri.reshape(-1, 3)
        corners[name] = box_corners(verts.min(axis=0), verts.max(axis=0))
        pieces_n[name] = len(pieces)
        parts.append(
            PartModel(name, pieces, mass_properties(tri, settings.density),
                      np.asarray(plan.start[name], dtype=np.float64), fixed=name == base)
        )  # fmt: skip
    joints = [(s.child, s.parent) for s in plan.steps if s.planned and s.child in plan.start]
    if boxes:
        whose = "its" if len(boxes) == 1 else "their"
        notes.append(f"no mesh found for {', '.join(boxes)}: simulated as {whose} bounding box")
    cell = CellModel(plan.robot, plan.robot_base, wc.table_z, wc.table_extent, parts, joints)
    return BuiltCell(cell, corners, notes, spent, pieces_n)
