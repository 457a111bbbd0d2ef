"""The learning stages after the plan, each a verb from typed results to a task-file block.

- :func:`fit_task_primitives`: the motor primitives of every *learned* constraint
  (never the recording's ground-truth labels);
- :func:`learn_task_reward`: the relational reward of the plan and the plans it
  makes for other part sets, written by :func:`reward_block`;
- :func:`demonstrated_grasps`: per constraint, where the person's hands held the
  child when they picked it up (so ``execute`` needs no ``--demo``);
- :func:`find_task_scene`: the scene file that gives the parts' meshes.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from thirdhand.demonstration import ConstraintEvent, Demonstration, FreeDofs
from thirdhand.learn.results import Learned, RewardResult

if TYPE_CHECKING:
    from thirdhand.plan.assembly import AssemblyPlan
    from thirdhand.primitives.skill_library import SkillLibrary
    from thirdhand.task.constraint import Constraint
    from thirdhand.task.model import TaskObject
    from thirdhand.task.stages import GraspsBlock, PrimitivesBlock, RewardBlock

#: Skills of the library that explains the constraint motions (transport,
#: approach, screwing turn, rest in the synthetic chair), unless told otherwise.
DEFAULT_SKILLS = 4


def learned_events(learned: Learned) -> list[tuple[ConstraintEvent, ...]]:
    """Per demonstration, its learned constraints as events on its own clock.

    Each event takes its slot's pose and DOF ranges (the symbol, averaged over
    the demonstrations) and the time at which that demonstration created it.

    Returns
    -------
    list of tuple of ConstraintEvent
        One tuple per demonstration (in ``learned.demos`` order), sorted by time.
    """
    per_demo: dict[str, list[ConstraintEvent]] = {n: [] for n in learned.names}
    for s in learned.symbols:
        for m in s.members:
            if m.demo not in per_demo:
                continue
            per_demo[m.demo].append(
                ConstraintEvent(
                    time=float(m.start),
                    parent=m.parent,
                    child=m.child,
                    type=s.type,
                    pos=(float(s.pos[0]), float(s.pos[1]), float(s.pos[2])),
                    quat=(float(s.quat[0]), float(s.quat[1]), float(s.quat[2]), float(s.quat[3])),
                    free_dofs=FreeDofs.from_array(s.ranges),
                    symbol=s.name,
                )
            )
    return [tuple(sorted(per_demo[n], key=lambda e: e.time)) for n in learned.names]


def fit_task_primitives(
    learned: Learned,
    *,
    skills: int | None = DEFAULT_SKILLS,
    seed: int = 0,
    skill_library: SkillLibrary | None = None,
) -> PrimitivesBlock | None:
    """Motor primitives (quaternion DMP + ProMP) of every learned constraint.

    Parameters
    ----------
    learned : Learned
    skills : int, optional
        Skills of the library learned over all constraint motions, each motion
        explained as a sequence of them (None: no library).
    seed : int
        Seeds the library's restarts.
    skill_library : SkillLibrary, optional
        A library learned before that explains the motions instead of a new one.

    Returns
    -------
    PrimitivesBlock or None
        The ``stages.primitives`` block; None when no constraint was learned.
    """
    from thirdhand.primitives.stage import primitives_stage

    events = learned_events(learned)
    used = [(d, e, n) for d, e, n in zip(learned.demos, events, learned.names, strict=True) if e]
    if not used:
        return None
    return primitives_stage(
        [d for d, _, _ in used],
        events=[e for _, e, _ in used],
        skills=skills,
        names=[n for _, _, n in used],
        seed=seed,
        skill_library=skill_library,
    )


def _numbered(type_name: str, count: int) -> list[str]:
    return [f"{type_name}{i + 1}" for i in range(count)]


def reward_targets(parts: Sequence[str]) -> dict[str, list[str]]:
    """Part sets to plan for with a reward learned on ``parts``.

    The demonstrated set itself, and for every part type present more than once
    (``leg1``…``leg4``, :func:`~thirdhand.relational.domains.plans.counted_parts`), the set
    with one part of that type fewer and one more, when it keeps at least two parts.

    Parameters
    ----------
    parts : sequence of str
        The demonstrated plan's part names.

    Returns
    -------
    dict of str to list of str
        Label (``"as demonstrated"``, ``"3 leg"``…) to part names.
    """
    from thirdhand.relational.domains.plans import counted_parts, type_of

    targets = {"as demonstrated": list(parts)}
    for t, names in counted_parts(parts).items():
        others = [p for p in parts if type_of(p) != t]
        for m in (len(names) - 1, len(names) + 1):
            if len(others) + m >= 2:  # one part alone is not an assembly
                targets[f"{m} {t}"] = others + _numbered(t, m)
    return targets


def learn_task_reward(
    plan: AssemblyPlan,
    *,
    targets: Mapping[str, Sequence[str]] | None = None,
    seed: int = 0,
) -> RewardResult:
    """Relational IRL (RCSI) on an assembly plan, and plans for other part sets.

    Parameters
    ----------
    plan : AssemblyPlan
        With at least one step.
    targets : mapping of str to sequence of str, optional
        Label to part names; default :func:`reward_targets` of the plan's parts.
    seed : int

    Raises
    ------
    RelationalError
        If the plan is empty.
    """
    from thirdhand.relational.assembly import learn_assembly, plan_with_reward
    from thirdhand.relational.domains.plans import parts_of, trajectory_from_plan
    from thirdhand.relational.logic import RelationalError

    if not plan.steps:
        raise RelationalError("reward: the task has no plan (expected at least one step)")
    model = learn_assembly([trajectory_from_plan(plan.steps, source="task 0")], seed=seed)
    parts = parts_of(trajectory_from_plan(plan.steps, source="task plan"))
    goal = reward_targets(parts) if targets is None else targets
    plans = {label: plan_with_reward(model, list(p)) for label, p in goal.items()}
    return RewardResult(model, plans)


def reward_block(result: RewardResult) -> RewardBlock:
    """The task file's ``stages.reward`` block."""
    from thirdhand.task.stages import RewardBlock, RewardPlanRecord

    return RewardBlock(
        method="RCSI (relational cascaded supervised IRL) on the learned plan",
        reward_tree=str(result.model.rcsi.reward),
        plans={
            label: RewardPlanRecord(
                parts=list(p.parts), complete=p.complete, perf=p.perf, steps=list(p.steps)
            )
            for label, p in result.plans.items()
        },
    )


def demonstrated_grasps(
    constraints: Sequence[Constraint],
    objects: Mapping[str, TaskObject],
    demos: Sequence[Demonstration],
    names: Sequence[str],
) -> GraspsBlock | None:
    """Per constraint, where the person's hands held its child just before it was made.

    The recording of each constraint is the one it was learned from
    (``Constraint.demo``); :func:`thirdhand.execute.grasps.demo_grasps` finds the
    hands (the same grasps ``execute --demo RECORDING`` takes).

    Parameters
    ----------
    constraints : sequence of Constraint
        The task's constraints.
    objects : mapping of str to TaskObject
        The task's objects by name (their boxes bound the grasps).
    demos, names : sequence
        The recordings and their names.

    Returns
    -------
    GraspsBlock or None
        None when no recording shows a hand holding a part.
    """
    if not any(b.kind == "finger" for d in demos for b in d.bodies):
        return None
    import numpy as np

    from thirdhand.execute.grasps import demo_grasps
    from thirdhand.se3 import pose_from_matrix
    from thirdhand.task.geometry import Pose
    from thirdhand.task.stages import DemoGraspRecord, GraspsBlock

    by_name = dict(zip(names, demos, strict=True))
    found: dict[str, list[DemoGraspRecord]] = {}
    for c in constraints:
        demo = by_name.get(c.demo) if c.demo is not None else demos[0]
        if c.time is None or demo is None or c.child not in objects:
            continue
        obj = objects[c.child]
        box = None
        if obj.bbox_min is not None and obj.bbox_max is not None:
            box = (np.asarray(obj.bbox_min), np.asarray(obj.bbox_max))
        records = []
        for g in demo_grasps(demo, c.child, c.time, bbox=box):
            pos, quat = pose_from_matrix(g.pose)
            pose = Pose.model_validate({"pos": pos.tolist(), "quat": quat.tolist()})
            records.append(DemoGraspRecord(hand=g.label, pose=pose, demo=c.demo, time=c.time))
        if records:
            found[c.id] = records
    return GraspsBlock(constraints=found) if found else None


def find_task_scene(demos: Sequence[Demonstration]) -> Path | None:
    """The scene file along ``THIRDHAND_MESH_PATH`` that lists every part of the recordings."""
    from thirdhand.task.scene_file import find_scene

    parts = sorted({b.name for d in demos for b in d.bodies if b.kind == "part"})
    return find_scene(parts)
