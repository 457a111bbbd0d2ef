"""The task file, built once from the typed results of the learning stages.

:func:`build_task` takes what :func:`~thirdhand.learn.run.learn_task` found (the
plan stage's :class:`~thirdhand.learn.results.Learned`, and the blocks of the
optional stages) and returns the ``thirdhand.task/2`` document; nothing changes it
afterwards. :func:`task_objects` and :func:`task_constraints` are the parts of it
that a later stage (the demonstrated grasps) needs before the whole is built.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from pydantic import BaseModel, TypeAdapter, ValidationError

from thirdhand.demonstration import DOF_NAMES, Demonstration
from thirdhand.errors import TaskFileError
from thirdhand.plan.keyframes import Keyframe
from thirdhand.plan.symbols import Symbol
from thirdhand.task.constraint import Constraint
from thirdhand.task.errors import first_error
from thirdhand.task.meshes import object_geometry
from thirdhand.task.model import TaskFile, TaskObject
from thirdhand.task.stages import (
    ConstraintsBlock,
    GraspsBlock,
    PlanBlock,
    PrimitivesBlock,
    RewardBlock,
    SceneBlock,
    Stages,
)

if TYPE_CHECKING:
    from thirdhand.learn.results import Learned

_KINDS = {"part", "tool", "finger", "hand", "head"}

M = TypeVar("M", bound=BaseModel)


def _validated(model: type[M], items: Sequence[dict[str, Any]], field: str) -> list[M]:
    """The items as ``model``; the first invalid one a TaskFileError at its location."""
    try:
        return TypeAdapter(list[model]).validate_python(list(items))  # type: ignore[valid-type]
    except ValidationError as exc:
        raise TaskFileError(f"new task: {field}{first_error(exc)}") from None


def task_objects(
    demos: Sequence[Demonstration], scene_geometry: Mapping[str, Mapping[str, Any]]
) -> list[TaskObject]:
    """Every body of the recordings as a task object, in the first recording's order.

    Parameters
    ----------
    demos : sequence of Demonstration
    scene_geometry : mapping of str to mapping
        Task-object geometry fields per body from a 3rdHand scene file
        (:func:`~thirdhand.task.scene_file.scene_geometry`); they win over the
        recording's own.
    """
    demo = demos[0]
    geometry = object_geometry(demo)
    for name, fields in scene_geometry.items():
        geometry[name] = geometry.get(name, {}) | dict(fields)
    objects = [
        {"name": b.name, "kind": b.kind if b.kind in _KINDS else "other"} | geometry.get(b.name, {})
        for b in demo.bodies
    ]
    known = {o["name"] for o in objects}
    for d in demos[1:]:
        for b in d.bodies:
            if b.name not in known:
                objects.append(
                    {"name": b.name, "kind": b.kind} | dict(scene_geometry.get(b.name, {}))
                )
                known.add(b.name)
    return _validated(TaskObject, objects, "objects")


def task_constraints(learned: Learned) -> list[Constraint]:
    """One constraint per plan step: its slot's pose, frame, free DOFs and runner-up."""
    by_symbol = {s.name: s for s in learned.symbols}
    constraints = []
    for step in learned.plan.steps:
        s = by_symbol[step.symbol]
        first = s.members[0]
        constraints.append(
            {
                "id": s.name,
                "parent": step.parent,
                "child": step.child,
                "type": s.type,
                "pos": [float(v) for v in s.pos],
                "quat": [float(v) for v in s.quat],
                "frame": {
                    "pos": [float(v) for v in s.frame_pos],
                    "quat": [float(v) for v in s.frame_quat],
                },
                "free_dofs": {
                    n: (float(lo), float(hi))
                    for n, (lo, hi) in zip(DOF_NAMES, s.ranges, strict=True)
                },
                "symbol": s.name,
                "confidence": min(1.0, max(0.0, s.confidence)),
                "time": first.start,
                "demo": first.demo,
                "runner_up": _runner_up(s),
            }
        )
    return _validated(Constraint, constraints, "constraints")


def build_task(
    learned: Learned,
    *,
    objects: Sequence[TaskObject],
    constraints: Sequence[Constraint],
    inputs: Sequence[str | os.PathLike[str]] = (),
    scene: Path | None = None,
    primitives: PrimitivesBlock | None = None,
    reward: RewardBlock | None = None,
    grasps: GraspsBlock | None = None,
) -> TaskFile:
    """The task file: objects, one constraint per plan step, the plan, a block per stage.

    Parameters
    ----------
    learned : Learned
        The plan stage's results.
    objects, constraints
        From :func:`task_objects` and :func:`task_constraints`.
    inputs : sequence of path-like
        Files the demonstrations were read from (hashed into the provenance).
    scene : Path, optional
        The scene file the meshes came from (``stages.scene``).
    primitives, reward, grasps : optional
        The blocks of the stages that ran.

    Raises
    ------
    TaskFileError
        If the content is invalid (first error, with its location).
    """
    by_symbol = {s.name: s for s in learned.symbols}
    kf_by_demo = {
        n: {(k.parent, k.child): k for k in kfs}
        for n, kfs in zip(learned.names, learned.keyframes, strict=True)
    }
    plan = []
    for step in learned.plan.steps:
        kf = _keyframe(learned.names, by_symbol[step.symbol], kf_by_demo)
        plan.append(
            {
                "parent": step.parent,
                "child": step.child,
                "symbol": step.symbol,
                "constraint": step.symbol,
                "time": step.times[0] if step.times else None,
                "keyframe": {
                    n: {"pos": [float(v) for v in p], "quat": [float(v) for v in q]}
                    for n, (p, q) in (kf.poses.items() if kf else [])
                },
                "after": list(step.after),
            }
        )
    stages = Stages(
        constraints=_constraints_block(learned),
        plan=_plan_block(learned),
        scene=None if scene is None else SceneBlock(file=scene.as_posix()),
        primitives=primitives,
        reward=reward,
        grasps=grasps,
    )
    return TaskFile.new(
        objects=list(objects),
        constraints=list(constraints),
        plan=plan,
        stages=stages,
        inputs=list(inputs),
        parameters={"demos": list(learned.names)},
    )


def _constraints_block(learned: Learned) -> ConstraintsBlock:
    return ConstraintsBlock.model_validate(
        {
            "method": "two-state HMM per part pair, fixed-constraint observations, EM",
            "root": learned.plan.root,
            "demos": [
                {
                    "name": n,
                    "root": det.root,
                    "instances": [i.to_dict() for i in det.instances],
                    "hmm": {
                        "sigma_pos_m": det.params.sigma_pos,
                        "sigma_rot_deg": math.degrees(det.params.sigma_rot),
                        "transition": det.params.transition.tolist(),
                    },
                }
                for n, det in zip(learned.names, learned.detections, strict=True)
            ],
        }
    )


def _plan_block(learned: Learned) -> PlanBlock:
    plan = learned.plan
    return PlanBlock(
        n_demos=plan.n_demos,
        silent_demos=[learned.names[k] for k in plan.silent],
        support=[len(st.times) for st in plan.steps],
        left_out=dict(plan.left_out),
        steps=[str(s) for s in plan.steps],
        relational_trajectory=[sorted(s) for s in plan.relational_trajectory()],
        interchangeable=[list(p) for p in plan.interchangeable()],
    )


def _keyframe(
    names: Sequence[str],
    symbol: Symbol,
    kf_by_demo: dict[str, dict[tuple[str, str], Keyframe]],
) -> Keyframe | None:
    """A step's keyframe from the first demonstration (in order) that has the step."""
    for name in names:
        for m in symbol.members:
            if m.demo == name and (m.parent, m.child) in kf_by_demo.get(name, {}):
                return kf_by_demo[name][(m.parent, m.child)]
    return None


def _runner_up(slot: Symbol) -> dict[str, Any] | None:
    """The slot's most doubtful alternative: the most probable runner-up of its members
    of the slot's type (a joint chosen among types), or None."""
    alts = [m.runner_up for m in slot.members if m.type == slot.type and m.runner_up is not None]
    if not alts:
        return None
    return max(alts, key=lambda f: f.confidence).alternative()
