"""Recordings to a task file: segmentation, constraint detection, symbols, plan.

:class:`Learned` bundles what the first stages of
:func:`thirdhand.task_learning.learn_task` found; :meth:`Learned.task` is the
``thirdhand.task/2`` document (written by the caller: ``thirdhand learn``, the
demo). :func:`learn` is a shortcut for those stages.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from thirdhand.constraints.detect import ConstraintInstance, DetectionResult
from thirdhand.demonstration import DOF_NAMES, Demonstration
from thirdhand.plan.assembly import AssemblyPlan
from thirdhand.plan.keyframes import Keyframe
from thirdhand.plan.symbols import Symbol
from thirdhand.task.meshes import object_geometry
from thirdhand.task.stages import ConstraintsBlock, PlanBlock, Stages
from thirdhand.taskfile import TaskFile

if TYPE_CHECKING:
    from thirdhand.segment.pipeline import SegmentationResult

_KINDS = {"part", "tool", "finger", "hand", "head"}


@dataclass
class Learned:
    """Everything the pipeline found.

    Attributes
    ----------
    demos : list of Demonstration
    names : list of str
        A name per demonstration (file name or ``demo1``...).
    phases : list
        Segmentation results (``thirdhand.segment.SegmentationResult``), or None each
        when segmentation was skipped.
    detections : list of DetectionResult
    symbols : list of Symbol
    plan : AssemblyPlan
    keyframes : list of list of Keyframe
        Per demonstration.
    inputs : list of path-like
        Files the demonstrations were read from (hashed into the provenance).
    scene_geometry : dict of str to dict
        Task-object geometry fields per body from a 3rdHand scene file
        (:func:`~thirdhand.task.scene_file.scene_geometry`); they win over the
        recording's own.
    """

    demos: list[Demonstration]
    names: list[str]
    phases: list[SegmentationResult | None]
    detections: list[DetectionResult]
    symbols: list[Symbol]
    plan: AssemblyPlan
    keyframes: list[list[Keyframe]]
    inputs: list[str | os.PathLike[str]] = field(default_factory=list)
    scene_geometry: dict[str, dict[str, Any]] = field(default_factory=dict)

    @property
    def instances(self) -> list[list[ConstraintInstance]]:
        """Each demonstration's constraint instances."""
        return [d.instances for d in self.detections]

    def task(self) -> TaskFile:
        """The task file: objects, one constraint per symbol, the plan, stage blocks."""
        demo = self.demos[0]
        geometry = object_geometry(demo)
        for name, fields in self.scene_geometry.items():
            geometry[name] = geometry.get(name, {}) | fields
        objects = [
            {"name": b.name, "kind": b.kind if b.kind in _KINDS else "other"}
            | geometry.get(b.name, {})
            for b in demo.bodies
        ]
        known = {o["name"] for o in objects}
        for d in self.demos[1:]:
            for b in d.bodies:
                if b.name not in known:
                    objects.append(
                        {"name": b.name, "kind": b.kind} | self.scene_geometry.get(b.name, {})
                    )
                    known.add(b.name)
        by_symbol = {s.name: s for s in self.symbols}
        constraints = []
        for step in self.plan.steps:
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
        plan = []
        kf_by_demo = {
            n: {(k.parent, k.child): k for k in kfs}
            for n, kfs in zip(self.names, self.keyframes, strict=True)
        }
        for step in self.plan.steps:
            kf = self._keyframe(by_symbol[step.symbol], kf_by_demo)
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
        constraints_block = ConstraintsBlock.model_validate(
            {
                "method": "two-state HMM per part pair, fixed-constraint observations, EM",
                "root": self.plan.root,
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
                    for n, det in zip(self.names, self.detections, strict=True)
                ],
            }
        )
        plan_block = PlanBlock(
            n_demos=self.plan.n_demos,
            silent_demos=[self.names[k] for k in self.plan.silent],
            support=[len(st.times) for st in self.plan.steps],
            left_out=dict(self.plan.left_out),
            steps=[str(s) for s in self.plan.steps],
            relational_trajectory=[sorted(s) for s in self.plan.relational_trajectory()],
            interchangeable=[list(p) for p in self.plan.interchangeable()],
        )
        stages = Stages(constraints=constraints_block, plan=plan_block)
        return TaskFile.new(
            objects=objects,
            constraints=constraints,
            plan=plan,
            stages=stages,
            inputs=list(self.inputs),
            parameters={"demos": self.names},
        )

    def _keyframe(
        self, symbol: Symbol, kf_by_demo: dict[str, dict[tuple[str, str], Keyframe]]
    ) -> Keyframe | None:
        """A step's keyframe from the first demonstration (in order) that has the step."""
        for name in self.names:
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


def learn(
    demos: Sequence[Demonstration],
    *,
    names: Sequence[str] | None = None,
    segment: bool = True,
    min_support: float = 0.5,
    scene: str | os.PathLike[str] | None = None,
) -> Learned:
    """Constraints, symbols, plan and keyframes of one or several demonstrations.

    A shortcut for the first stages of :func:`thirdhand.task_learning.learn_task`
    (no primitives, reward or grasps); see it for the parameters.
    """
    from thirdhand.task_learning import learn_task

    return learn_task(
        demos, names=names, segment=segment, primitives=False, reward=False, grasps=False,
        min_support=min_support, scene=scene,
    ).learned  # fmt: skip


def plan_figures(result: Learned) -> tuple[dict[str, Any], str]:
    """The plan stage's figures for a summary: a JSON-able block and one line.

    The block has the root, the steps and the first demonstration's constraints,
    and, when that demonstration has ground-truth constraints (a synthetic scene),
    the mean pose error of the learned ones (``pos_error_cm``, ``rot_error_deg``).
    """
    block: dict[str, Any] = {
        "root": result.plan.root,
        "steps": [str(s) for s in result.plan.steps],
        "constraints": [
            {
                "child": i.child,
                "parent": i.parent,
                "type": i.type,
                "start": i.start,
                "symbol": i.symbol,
            }
            for i in result.instances[0]
        ],
    }
    truth = result.demos[0].labels.constraints
    if truth:
        from thirdhand.metrics import pose_errors

        errs = pose_errors(result.instances[0], truth)
        if errs:
            block["pos_error_cm"] = 100 * float(sum(e[0] for e in errs) / len(errs))
            block["rot_error_deg"] = float(sum(e[1] for e in errs) / len(errs))
    line = f"plan: {len(result.plan.steps)} steps " + ", ".join(block["steps"])
    if "pos_error_cm" in block:
        line += f" (pose error {block['pos_error_cm']:.2f} cm, {block['rot_error_deg']:.2f}°)"
    return block, line
