"""A scripted "user": the fewest corrections that turn a task into a reference task.

Given a learned (or transferred) task and the ground truth
(:func:`thirdhand.synth.task.truth_task`), :func:`scripted_corrections` lists the
edits a careful person would make in the review GUI, applies them with
:func:`~thirdhand.review.edits.apply_edit`, and counts the corrected parameters
in the 3rdHand report's unit: per constraint, its parent and the six values of
the child's pose in the parent frame (x y z, roll pitch yaw), 7 in all
(``research/notes/review.md`` discusses the report's 30 and 28).

A value is corrected only when it is off by more than the tolerance (1 cm, 5°
by default); a DOF range only when its class differs (locked, noise, limited,
full: :func:`~thirdhand.review.dofs.classify_dof`), counted apart. The pose is
compared with the nearest equivalent reference pose: moving the child along the
reference's own free DOFs (a leg screwed into its slot may stop at any turn)
does not make it wrong.

Constraints are matched by their child object. A reference constraint without a
learned one cannot be made by these edits and is reported as missing; a learned
constraint whose child the reference does not constrain is reported as extra.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from thirdhand.review.dofs import classify_dof, move_along, quat_distance
from thirdhand.review.edits import (
    Edit,
    SetDofRange,
    SetParent,
    SetPoseValue,
    apply_edit,
    pose_values,
)
from thirdhand.se3 import quat_rotate
from thirdhand.task.constraint import Constraint
from thirdhand.task.geometry import DOF_NAMES
from thirdhand.task.model import TaskFile

#: Position tolerance, metres.
TOL_POS = 0.01
#: Orientation tolerance per roll/pitch/yaw value, radians.
TOL_ROT = math.radians(5.0)
#: Parameters per constraint in the report's unit: parent + 3 position + 3 orientation.
PARAMS_PER_CONSTRAINT = 7


@dataclass(frozen=True)
class ScriptedResult:
    """What the scripted user did.

    Attributes
    ----------
    edits : list of Edit
        In the order applied.
    corrected : list of str
        Corrected parameters, ``<child>.parent`` / ``.x`` ... ``.yaw``.
    ranges : list of str
        Corrected DOF ranges, ``<child>.range.<dof>``.
    n_parameters : int
        Total parameters in the report's unit: 7 per reference constraint.
    missing, extra : list of str
        Children constrained only in the reference / only in the task.
    task : TaskFile
        The corrected task.
    """

    edits: list[Edit]
    corrected: list[str]
    ranges: list[str]
    n_parameters: int
    missing: list[str]
    extra: list[str]
    task: TaskFile

    @property
    def n_corrected(self) -> int:
        """Corrected parameters in the report's unit (parent and pose values)."""
        return len(self.corrected)

    @property
    def n_missing_parameters(self) -> int:
        """Parameters of missing constraints, all of which a person would have to set."""
        return PARAMS_PER_CONSTRAINT * len(self.missing)


def _moved(reference: Constraint, amounts: dict[str, float]) -> Constraint:
    ref = reference
    for dof, amount in amounts.items():
        if amount:
            pose = move_along(ref, dof, amount)
            ref = ref.model_copy(update={"pos": pose.pos, "quat": pose.quat})
    return ref


def nearest_equivalent(reference: Constraint, pos: np.ndarray, quat: np.ndarray) -> Constraint:
    """The reference moved along its free DOFs (within their ranges) closest to a pose.

    Coordinate descent over the free DOFs (exact for one free DOF): a translation
    by projection onto its axis, a rotation on a grid of 721 angles refined once.

    Parameters
    ----------
    reference : Constraint
    pos : ndarray, shape (3,), metres, parent frame
    quat : ndarray, shape (4,), x y z w

    Returns
    -------
    Constraint
        ``reference`` with the child's pose replaced by the nearest equivalent one.
    """
    free = [d for d in DOF_NAMES if reference.free_dofs[d][0] != reference.free_dofs[d][1]]
    amounts = {d: float(np.clip(0.0, *reference.free_dofs[d])) for d in free}
    for _ in range(2 if len(free) > 1 else 1):
        for dof in free:
            lo, hi = reference.free_dofs[dof]
            others = {d: a for d, a in amounts.items() if d != dof}

            def at(a: float, dof: str = dof, others: dict[str, float] = others) -> Constraint:
                return _moved(reference, {**others, dof: a})

            if dof.startswith("t"):
                base = at(0.0)
                axis = np.zeros(3)
                axis[DOF_NAMES.index(dof)] = 1.0
                direction = quat_rotate(base.quat, quat_rotate(base.frame.quat, axis))
                amounts[dof] = float(np.clip(np.dot(direction, pos - np.asarray(base.pos)), lo, hi))
                continue
            grid = np.linspace(lo, hi, 721)
            errs = [quat_distance(at(float(a)).quat, tuple(quat)) for a in grid]
            best = float(grid[int(np.argmin(errs))])
            step = (hi - lo) / 720
            fine = np.clip(np.linspace(best - step, best + step, 41), lo, hi)
            errs = [quat_distance(at(float(a)).quat, tuple(quat)) for a in fine]
            amounts[dof] = float(fine[int(np.argmin(errs))])
    return _moved(reference, amounts)


def _angle_diff(a: float, b: float) -> float:
    return abs(math.remainder(a - b, 2.0 * math.pi))


def _class(c: Constraint, dof: str) -> str:
    lo, hi = c.free_dofs[dof]
    return classify_dof(lo, hi, dof)


def _pick(task: TaskFile, child: str) -> Constraint | None:
    ids = {c.id: c for c in task.constraints if c.child == child}
    for s in task.plan:
        if s.constraint in ids:
            return ids[s.constraint]
    return next(iter(ids.values()), None)


def scripted_corrections(
    task: TaskFile,
    truth: TaskFile,
    *,
    tol_pos: float = TOL_POS,
    tol_rot: float = TOL_ROT,
    who: str = "scripted user",
) -> ScriptedResult:
    """The minimal corrections turning ``task`` into ``truth`` within tolerances.

    Per reference constraint: the parent (:class:`SetParent`, the world pose
    kept), then each pose value off by more than ``tol_pos`` / ``tol_rot`` from
    the nearest equivalent reference pose (:class:`SetPoseValue`), then each DOF
    range of another class (:class:`SetDofRange`).

    Returns
    -------
    ScriptedResult
    """
    edits: list[Edit] = []
    corrected: list[str] = []
    ranges: list[str] = []
    missing: list[str] = []
    current = task

    def do(edit: Edit) -> None:
        nonlocal current
        current = apply_edit(current, edit, who=who)
        edits.append(edit)

    ref_children = {c.child for c in truth.constraints}
    for ref in truth.constraints:
        c = _pick(current, ref.child)
        if c is None:
            missing.append(ref.child)
            continue
        if c.parent != ref.parent:
            do(SetParent(ref.child, ref.parent))
            corrected.append(f"{ref.child}.parent")
            c = current.constraint_by_id(c.id)
        near = nearest_equivalent(ref, np.asarray(c.pos), np.asarray(c.quat))
        want, have = pose_values(near), pose_values(c)
        for name in ("x", "y", "z"):
            if abs(want[name] - have[name]) > tol_pos:
                do(SetPoseValue(c.id, name, want[name]))
                corrected.append(f"{ref.child}.{name}")
        for name in ("roll", "pitch", "yaw"):
            if _angle_diff(want[name], have[name]) > tol_rot:
                do(SetPoseValue(c.id, name, want[name]))
                corrected.append(f"{ref.child}.{name}")
        for dof in DOF_NAMES:
            lo, hi = ref.free_dofs[dof]
            if _class(c, dof) != classify_dof(lo, hi, dof):
                do(SetDofRange(c.id, dof, lo, hi))
                ranges.append(f"{ref.child}.range.{dof}")
                c = current.constraint_by_id(c.id)
    extra = sorted({c.child for c in current.constraints if c.child not in ref_children})
    return ScriptedResult(
        edits=edits,
        corrected=corrected,
        ranges=ranges,
        n_parameters=PARAMS_PER_CONSTRAINT * len(truth.constraints),
        missing=missing,
        extra=extra,
        task=current,
    )


def residuals(task: TaskFile, truth: TaskFile) -> dict[str, dict[str, float | bool]]:
    """Per reference child: parent match, position error (m), angle error (rad), class match.

    Errors are against the nearest equivalent reference pose; children the task
    does not constrain are left out.
    """
    out: dict[str, dict[str, float | bool]] = {}
    for ref in truth.constraints:
        c = _pick(task, ref.child)
        if c is None:
            continue
        near = nearest_equivalent(ref, np.asarray(c.pos), np.asarray(c.quat))
        out[ref.child] = {
            "parent": c.parent == ref.parent,
            "position": float(np.max(np.abs(np.subtract(c.pos, near.pos)))),
            "angle": quat_distance(c.quat, near.quat),
            "classes": all(_class(c, d) == _class(ref, d) for d in DOF_NAMES),
        }
    return out


def effort_table(
    seeds: tuple[int, ...] = (0, 1, 2), noise: tuple[float, ...] = (1.0, 6.0)
) -> list[str]:
    """Markdown rows: corrections of the learned chair, and of its transfer to the bench.

    For each sensor noise (position noise in mm, rotation noise ``noise / 2`` degrees)
    and seed: learn the chair from one synthetic demonstration
    (:func:`thirdhand.learn.run.learn_task` with the later stages off), count the
    scripted user's corrections against the chair's ground truth, then transfer the
    learned task onto the bench and count against the bench's ground truth.

    Run with ``python -m research.scripted_user``.
    """
    from thirdhand.learn.run import learn_task
    from thirdhand.review.transfer import transfer
    from thirdhand.synth import make_scene
    from thirdhand.synth.sensor import SensorModel
    from thirdhand.synth.task import truth_task

    bench = truth_task(make_scene("bench", seed=0, sensor=None))
    rows = [
        "| sensor noise | seed | chair: corrected / total | chair: ranges, missing | "
        "bench (transfer): corrected / total | bench: ranges |",
        "|---|---|---|---|---|---|",
    ]
    for mm in noise:
        sensor = SensorModel(pos_noise=mm * 1e-3, rot_noise=math.radians(mm / 2))
        for seed in seeds:
            demo = make_scene("chair", seed=seed, sensor=sensor)
            learned = learn_task([demo], primitives=False, reward=False, grasps=False).task
            chair = scripted_corrections(learned, truth_task(demo))
            moved = scripted_corrections(transfer(learned, "bench").task, bench)
            miss = f", missing {'+'.join(chair.missing)}" if chair.missing else ""
            rows.append(
                f"| {mm:g} mm, {mm / 2:g}° | {seed} | {chair.n_corrected} / {chair.n_parameters} "
                f"| {len(chair.ranges)}{miss} | {moved.n_corrected} / {moved.n_parameters} "
                f"| {len(moved.ranges)} |"
            )
    return rows


if __name__ == "__main__":
    from pathlib import Path

    for row in effort_table():
        print(row)
    study_path = (
        Path(__file__).resolve().parents[1].parent / "shared/data/3rdhand/iros15_user_study.yaml"
    )
    if study_path.is_file():
        from thirdhand.io.iros15 import read_user_study
        from thirdhand.review.effort import study_effort

        print("\n| IROS'15 scene, condition | attempts | parameters touched | operations |", end="")
        print(" per object |")
        print("|---|---|---|---|---|")
        for (scene, cond), v in study_effort(read_user_study(study_path)).items():
            print(
                f"| {scene} {cond} | {v['attempts']:.0f} | {v['parameters']:.2f} "
                f"| {v['operations']:.1f} | {v['per_object']:.1f} |"
            )
