"""Learning a task: every stage that needs no robot, from recordings to one task file.

:func:`learn_task` reads as the sequence of the stage verbs, each returning its
typed result:

1. per recording (:func:`~thirdhand.learn.recordings.recording_stages`, the unit
   ``learn --jobs/--scheduler`` runs in a process or on a cluster): interaction
   phases and constraints;
2. symbols, the assembly plan (:func:`~thirdhand.api.plan_assembly`'s stage) and
   the keyframes;
3. the motor primitives of every learned constraint;
4. the relational reward of the plan and the plans it makes for other part sets;
5. the person's grasps;
6. the task file, built once from those results (:func:`~thirdhand.learn.build.build_task`),
   with the parts' meshes from a 3rdHand scene file.

``thirdhand learn`` and ``thirdhand demo`` call it; precomputed results of a
recording (its phases, its detection, or both) come in one way, as a
:class:`~thirdhand.learn.results.RecordingStages` per recording.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Literal

from thirdhand.demonstration import Demonstration
from thirdhand.errors import ThirdhandError
from thirdhand.learn.results import Learned, LearnedTask, RecordingStages
from thirdhand.learn.stages import DEFAULT_SKILLS

if TYPE_CHECKING:
    from thirdhand.primitives.skill_library import SkillLibrary
    from thirdhand.segment.model import SegmentModel

#: The stages :func:`learn_task` can skip, in the order they run.
OPTIONAL_STAGES = ("segment", "primitives", "reward", "grasps")


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
        Run the motor-primitive, the relational-reward and the demonstrated-grasp
        stages (all off: constraints, plan and keyframes only).
    skills : int, optional
        Skills of the library that explains the constraint motions in the
        primitives block (None: no library).
    skill_library : SkillLibrary, optional
        A library learned before (an earlier task's) that explains the motions instead
        of a new one.
    reward_plans : mapping of str to sequence of str, optional
        Part sets the learned reward plans for; default
        :func:`~thirdhand.learn.stages.reward_targets`.
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
    from thirdhand.learn.build import build_task, task_constraints, task_objects
    from thirdhand.learn.recordings import RecordingUnit, recording_stages
    from thirdhand.learn.stages import (
        demonstrated_grasps,
        find_task_scene,
        fit_task_primitives,
        learn_task_reward,
        reward_block,
    )
    from thirdhand.plan.assembly import assemble
    from thirdhand.plan.keyframes import keyframes

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

    # 1. Per recording: phases and constraints.
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

    # 2. Symbols, plan, keyframes.
    say("constraints and plan")
    detections = [r.detection for r in done if r.detection is not None]
    symbols, plan = assemble(detections, min_support=min_support)
    learned = Learned(
        demos=demo_list,
        names=nm,
        phases=[r.phases for r in done],
        detections=detections,
        symbols=symbols,
        plan=plan,
        keyframes=[
            keyframes(d, det.instances) for d, det in zip(demo_list, detections, strict=True)
        ],
    )
    scene_path = find_task_scene(demo_list) if scene == "auto" else scene
    scene_path = None if scene_path is None else Path(scene_path).resolve()
    geometry = {}
    if scene_path is not None:
        from thirdhand.task.scene_file import scene_geometry

        geometry = scene_geometry(
            scene_path,
            sorted({b for d in demo_list for b in d.body_names}),
            parts=sorted({b.name for d in demo_list for b in d.bodies if b.kind == "part"}),
        )
    objects = task_objects(demo_list, geometry)
    constraints = task_constraints(learned)

    # 3. Motor primitives.
    block = None
    if not primitives:
        skipped.append("primitives: skipped by the user")
    else:
        say("primitives")
        block = fit_task_primitives(learned, skills=skills, seed=seed, skill_library=skill_library)
        if block is None:
            skipped.append("primitives: no constraint was learned")
        else:
            skipped.extend(f"primitives: {why}" for why in block.skipped)

    # 4. Relational reward.
    result = None
    if not reward:
        skipped.append("reward: skipped by the user")
    elif not plan.steps:
        skipped.append("reward: the plan is empty")
    else:
        say("reward")
        result = learn_task_reward(plan, targets=reward_plans, seed=seed)

    # 5. The person's grasps.
    held = None
    if not grasps:
        skipped.append("grasps: skipped by the user")
    else:
        held = demonstrated_grasps(constraints, {o.name: o for o in objects}, demo_list, nm)

    # 6. The task file, once.
    task = build_task(
        learned,
        objects=objects,
        constraints=constraints,
        inputs=list(inputs),
        scene=scene_path,
        primitives=block,
        reward=None if result is None else reward_block(result),
        grasps=held,
    )
    return LearnedTask(learned, task, block, result, tuple(skipped))
