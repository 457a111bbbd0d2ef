"""The pipeline: every stage that needs no robot, from recordings to one task file.

:func:`learn_task` is a plain sequence of the stage verbs (:mod:`thirdhand.api`),
each consuming the previous one's typed objects in memory:

1. per recording (:func:`recording_stages`, the unit ``learn --jobs/--scheduler``
   runs in a process or on a cluster): interaction phases
   (:func:`~thirdhand.api.segment_phases`) and constraints
   (:func:`~thirdhand.api.detect_constraints`);
2. symbols and the assembly plan (:func:`~thirdhand.plan.assembly.assemble`, the
   stage of :func:`~thirdhand.api.plan_assembly`) and the keyframes;
3. the task file, with the parts' meshes from a 3rdHand scene file;
4. the motor primitives of every *learned* constraint (never the recording's
   ground-truth labels, :func:`~thirdhand.api.fit_primitives`);
5. the relational reward of the :class:`~thirdhand.plan.assembly.AssemblyPlan`
   (:func:`~thirdhand.api.learn_reward`) and the plans it makes for other part sets;
6. the person's grasps: per constraint, where their hand held the child when
   they picked it up (so ``execute`` needs no ``--demo``).

This is the only place the stages are chained: ``thirdhand learn``, ``thirdhand
demo`` and :func:`thirdhand.plan.learn.learn` call :func:`learn_task`.
Precomputed results of a recording (its phases, its detection, or both) come in
one way, as a :class:`RecordingStages` per recording.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Literal

from thirdhand.demonstration import ConstraintEvent, Demonstration, FreeDofs
from thirdhand.errors import ThirdhandError

if TYPE_CHECKING:
    from thirdhand.constraints.detect import DetectionResult
    from thirdhand.plan.assembly import AssemblyPlan
    from thirdhand.plan.learn import Learned
    from thirdhand.primitives.skill_library import SkillLibrary
    from thirdhand.relational.assembly import AssemblyModel, RewardPlan
    from thirdhand.segment.model import SegmentModel
    from thirdhand.segment.pipeline import SegmentationResult
    from thirdhand.task.model import TaskFile
    from thirdhand.task.stages import GraspsBlock, PrimitivesBlock, RewardBlock

#: The stages :func:`learn_task` can skip, in the order they run.
OPTIONAL_STAGES = ("segment", "primitives", "reward", "grasps")

#: Skills of the library that explains the constraint motions (transport,
#: approach, screwing turn, rest in the synthetic chair), unless told otherwise.
DEFAULT_SKILLS = 4


@dataclass(frozen=True)
class RecordingStages:
    """What the per-recording stages found (or were given) for one recording.

    Attributes
    ----------
    phases : SegmentationResult or None
        Its interaction phases (None: not segmented, or to be computed).
    detection : DetectionResult or None
        Its constraints over time (None: to be computed, with ``phases``).
    """

    phases: SegmentationResult | None = None
    detection: DetectionResult | None = None


@dataclass(frozen=True)
class RecordingUnit:
    """One independent unit of ``learn --jobs/--scheduler``: one recording's own stages.

    Attributes
    ----------
    demo : Demonstration
    name : str
        The recording's name (its file name).
    segment : bool
        Run the interaction segmentation when ``known.phases`` is None.
    model : SegmentModel or None
        The segmentation model (None: the shipped one).
    known : RecordingStages
        What is already computed.
    """

    demo: Demonstration
    name: str
    segment: bool = True
    model: SegmentModel | None = None
    known: RecordingStages = RecordingStages()


def recording_stages(unit: RecordingUnit) -> RecordingStages:
    """Segment one recording (unless told not to, or given) and detect its constraints.

    Deterministic, so the task file is the same serially, in processes and on a
    cluster (:func:`thirdhand.batch.parallel_map`).
    """
    from thirdhand.api import detect_constraints, segment_phases

    phases = unit.known.phases
    if phases is None and unit.segment:
        phases = segment_phases(unit.demo, unit.model)
    detection = unit.known.detection
    if detection is None:
        detection = detect_constraints(unit.demo, phases=phases, name=unit.name)
    return RecordingStages(phases, detection)


@dataclass(frozen=True)
class RewardResult:
    """The relational reward learned from the plan, and the plans it makes.

    Attributes
    ----------
    model : AssemblyModel
        Plan types and the RCSI model.
    plans : dict of str to RewardPlan
        Per target label (e.g. ``"bench"``), the plan for that part set.
    """

    model: AssemblyModel
    plans: dict[str, RewardPlan]

    def block(self) -> RewardBlock:
        """The task file's ``stages.reward`` block."""
        from thirdhand.task.stages import RewardBlock, RewardPlanRecord

        return RewardBlock(
            method="RCSI (relational cascaded supervised IRL) on the learned plan",
            reward_tree=str(self.model.rcsi.reward),
            plans={
                label: RewardPlanRecord(
                    parts=list(p.parts), complete=p.complete, perf=p.perf, steps=list(p.steps)
                )
                for label, p in self.plans.items()
            },
        )


@dataclass(frozen=True)
class LearnedTask:
    """What :func:`learn_task` found.

    Attributes
    ----------
    learned : Learned
        Phases, constraint detections, symbols, plan and keyframes.
    task : TaskFile
        The task file, with a block per stage that ran in ``task.stages``.
    primitives : PrimitivesBlock or None
        ``task.stages.primitives`` (None when skipped or no constraint was learned).
    reward : RewardResult or None
        None when skipped or the plan is empty.
    skipped : tuple of str
        Stages not run, each with its reason (``"reward: skipped by the user"``).
    """

    learned: Learned
    task: TaskFile
    primitives: PrimitivesBlock | None
    reward: RewardResult | None
    skipped: tuple[str, ...]


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
    from thirdhand.api import fit_primitives

    events = learned_events(learned)
    used = [(d, e, n) for d, e, n in zip(learned.demos, events, learned.names, strict=True) if e]
    if not used:
        return None
    return fit_primitives(
        [d for d, _, _ in used],
        [e for _, e, _ in used],
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
    (``leg1``…``leg4``), the set with one part of that type fewer and one more.

    Parameters
    ----------
    parts : sequence of str
        The demonstrated plan's part names.

    Returns
    -------
    dict of str to list of str
        Label (``"as demonstrated"``, ``"3 leg"``…) to part names.
    """
    from thirdhand.relational.domains.plans import type_of

    by_type: dict[str, list[str]] = {}
    for p in parts:
        by_type.setdefault(type_of(p), []).append(p)
    targets = {"as demonstrated": list(parts)}
    for t, names in by_type.items():
        n = len(names)
        if n < 2 or not all(re.fullmatch(rf"{re.escape(t)}\d+", x, re.I) for x in names):
            continue
        others = [p for p in parts if type_of(p) != t]
        for m in (n - 1, n + 1):
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
    from thirdhand.api import learn_reward
    from thirdhand.relational.assembly import plan_with_reward
    from thirdhand.relational.domains.plans import parts_of, trajectory_from_plan
    from thirdhand.relational.logic import RelationalError

    if not plan.steps:
        raise RelationalError("reward: the task has no plan (expected at least one step)")
    model = learn_reward([plan], seed=seed)
    parts = parts_of(trajectory_from_plan(plan.steps, source="task plan"))
    goal = reward_targets(parts) if targets is None else targets
    plans = {label: plan_with_reward(model, list(p)) for label, p in goal.items()}
    return RewardResult(model, plans)


def demonstrated_grasps(
    task: TaskFile, demos: Sequence[Demonstration], names: Sequence[str]
) -> GraspsBlock | None:
    """Per constraint, where the person's hands held its child just before it was made.

    The recording of each constraint is the one it was learned from
    (``Constraint.demo``); :func:`thirdhand.execute.grasps.demo_grasps` finds the
    hands (the same grasps ``execute --demo RECORDING`` takes).

    Returns
    -------
    GraspsBlock or None
        None when no recording shows a hand holding a part.
    """
    if not any(b.kind == "finger" for d in demos for b in d.bodies):
        return None
    import numpy as np

    from thirdhand.execute.grasps import demo_grasps
    from thirdhand.se3 import matrix_to_pose
    from thirdhand.task.geometry import Pose
    from thirdhand.task.stages import DemoGraspRecord, GraspsBlock

    by_name = dict(zip(names, demos, strict=True))
    objects = task.objects_by_name()
    found: dict[str, list[DemoGraspRecord]] = {}
    for c in task.constraints:
        demo = by_name.get(c.demo) if c.demo is not None else demos[0]
        if c.time is None or demo is None or c.child not in objects:
            continue
        obj = objects[c.child]
        box = None
        if obj.bbox_min is not None and obj.bbox_max is not None:
            box = (np.asarray(obj.bbox_min), np.asarray(obj.bbox_max))
        records = []
        for g in demo_grasps(demo, c.child, c.time, bbox=box):
            pos, quat = matrix_to_pose(g.pose)
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


def learn_task(
    demos: Sequence[Demonstration],
    *,
    names: Sequence[str] | None = None,
    recordings: Sequence[RecordingStages] | None = None,
    segment: bool = True,
    segment_model: SegmentModel | None = None,
    primitives: bool = True,
    skills: int | None = DEFAULT_SKILLS,
    skill_library: SkillLibrary | None = None,
    reward: bool = True,
    reward_plans: Mapping[str, Sequence[str]] | None = None,
    grasps: bool = True,
    seed: int = 0,
    inputs: Sequence[str | os.PathLike[str]] = (),
    progress: Callable[[str], None] | None = None,
    min_support: float = 0.5,
    scene: str | os.PathLike[str] | Literal["auto"] | None = None,
    jobs: int = 1,
    scheduler: str | None = None,
) -> LearnedTask:
    """Learn a task from demonstrations: every stage that needs no robot.

    Parameters
    ----------
    demos : sequence of Demonstration
        Demonstrations of one task (same part names).
    names : sequence of str, optional
        A name per demonstration (file names); default ``demo1``, ``demo2``…
    recordings : sequence of RecordingStages, optional
        Per demonstration, what is already computed (its phases, its detection);
        the rest is computed.
    segment : bool
        Run the interaction segmentation where no phases are given.
    segment_model : SegmentModel, optional
        The segmentation model (default: the shipped one).
    primitives, reward, grasps : bool
        Run the motor-primitive, the relational-reward and the demonstrated-grasp stages.
    skills : int, optional
        Skills of the library that explains the constraint motions in the
        primitives block (None: no library).
    skill_library : SkillLibrary, optional
        A library learned before (an earlier task's) that explains the motions instead
        of a new one.
    reward_plans : mapping of str to sequence of str, optional
        Part sets the learned reward plans for; default :func:`reward_targets`.
    seed : int
        Seed of the reward stage's random transitions and of the skill library.
    inputs : sequence of path-like
        Source files, hashed into the task's provenance.
    progress : callable, optional
        Called with the name of each stage as it starts.
    min_support : float
        A slot becomes a plan step when more than this fraction of the recordings
        that show any constraint have it, in [0, 1) (0.5: a strict majority; 0: every
        slot seen once).
    scene : path-like or "auto", optional
        A 3rdHand scene file (``scene_*.json``) giving the parts' meshes; ``"auto"``:
        the one along ``THIRDHAND_MESH_PATH`` that lists every part, if any.
    jobs, scheduler
        Run the per-recording stages in ``jobs`` local processes or as Dask tasks
        (:func:`thirdhand.batch.parallel_map`); the task is the same either way.

    Returns
    -------
    LearnedTask

    Raises
    ------
    ThirdhandError
        On an empty demonstration list or a stage's bad input (one line).
    """
    from thirdhand.plan.assembly import assemble
    from thirdhand.plan.keyframes import keyframes
    from thirdhand.plan.learn import Learned

    demo_list = list(demos)
    if not demo_list:
        raise ThirdhandError("learn: no demonstration given")
    nm = list(names) if names is not None else [f"demo{i + 1}" for i in range(len(demo_list))]
    known = list(recordings) if recordings is not None else [RecordingStages()] * len(demo_list)
    if len(nm) != len(demo_list) or len(known) != len(demo_list):
        raise ThirdhandError(
            f"learn: {len(demo_list)} demonstrations, {len(nm)} names and "
            f"{len(known)} precomputed recordings (expected one each)"
        )
    say = progress or (lambda _stage: None)
    skipped: list[str] = []
    units = [
        RecordingUnit(d, n, segment, segment_model, k)
        for d, n, k in zip(demo_list, nm, known, strict=True)
    ]
    if any(k.phases is None for k in known):
        if segment:
            say("segment")
        else:
            skipped.append("segment: skipped by the user")
    if jobs > 1 or scheduler is not None:
        from thirdhand.batch import parallel_map

        done = list(parallel_map(recording_stages, units, jobs=jobs, scheduler=scheduler))
    else:
        done = [recording_stages(u) for u in units]
    say("constraints and plan")
    detections = [r.detection for r in done if r.detection is not None]
    symbols, plan = assemble(detections, min_support=min_support)
    kfs = [keyframes(d, det.instances) for d, det in zip(demo_list, detections, strict=True)]
    scene_path = find_task_scene(demo_list) if scene == "auto" else scene
    scene_path = None if scene_path is None else Path(scene_path).resolve()
    geometry = {}
    if scene_path is not None:
        from thirdhand.task.scene_file import scene_geometry

        geometry = scene_geometry(
            scene_path, sorted({b for d in demo_list for b in d.body_names}),
            parts=sorted({b.name for d in demo_list for b in d.bodies if b.kind == "part"}),
        )  # fmt: skip
    learned = Learned(
        demo_list, nm, [r.phases for r in done], detections, symbols, plan, kfs, list(inputs),
        geometry,
    )  # fmt: skip
    task = learned.task()
    if scene_path is not None:
        from thirdhand.task.stages import SceneBlock

        task.stages.scene = SceneBlock(file=scene_path.as_posix())
    block = None
    if not primitives:
        skipped.append("primitives: skipped by the user")
    else:
        say("primitives")
        block = fit_task_primitives(learned, skills=skills, seed=seed, skill_library=skill_library)
        if block is None:
            skipped.append("primitives: no constraint was learned")
        task.stages.primitives = block
    result = None
    if not reward:
        skipped.append("reward: skipped by the user")
    elif not plan.steps:
        skipped.append("reward: the plan is empty")
    else:
        say("reward")
        result = learn_task_reward(plan, targets=reward_plans, seed=seed)
        task.stages.reward = result.block()
    if not grasps:
        skipped.append("grasps: skipped by the user")
    else:
        task.stages.grasps = demonstrated_grasps(task, demo_list, nm)
    return LearnedTask(learned, task, block, result, tuple(skipped))
