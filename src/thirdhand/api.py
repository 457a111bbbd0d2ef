"""One verb per stage, for a notebook or a script: ``import thirdhand as th``.

Each verb takes and returns the stages' typed records (no file paths, no
dicts between stages) and imports its stage only when called, so
``import thirdhand`` stays light::

    demo = th.io.load("chair.parquet")
    phases = th.segment_phases(demo)
    detection = th.detect_constraints(demo, phases=phases)
    plan = th.plan_assembly([detection])
    learned = th.learn_task([demo])          # every stage above, plus primitives, reward, grasps
    result = th.execute_task(learned.task, robot="panda")

(The verbs of segmentation and execution are ``segment_phases`` and ``execute_task``:
``thirdhand.segment`` and ``thirdhand.execute`` are the stages' packages.)
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Literal

from thirdhand.demonstration import ConstraintEvent, Demonstration
from thirdhand.errors import ThirdhandError

if TYPE_CHECKING:
    from thirdhand.constraints.detect_types import DetectionResult
    from thirdhand.execute.step_plan import ExecutionResult
    from thirdhand.plan.assembly import AssemblyPlan
    from thirdhand.primitives.pose_channels import PoseTrack
    from thirdhand.primitives.skill_library import SkillLibrary, SkillParserOptions
    from thirdhand.relational.assembly import AssemblyModel
    from thirdhand.segment.model import SegmentModel
    from thirdhand.segment.pipeline import SegmentationResult
    from thirdhand.task.model import TaskFile
    from thirdhand.task.stages import PrimitivesBlock

#: Robots :func:`execute` can drive.
ROBOTS = ("panda", "baxter")


def segment_phases(demo: Demonstration, model: SegmentModel | None = None) -> SegmentationResult:
    """Interaction phases of every body pair and every hand (linear-chain CRF).

    Parameters
    ----------
    demo : Demonstration
    model : SegmentModel, optional
        Default: the shipped model (``thirdhand.segment.model.builtin_model("default")``).
    """
    from thirdhand.segment import segment_demonstration

    return segment_demonstration(demo, model)


def detect_constraints(
    demo: Demonstration, *, phases: SegmentationResult | None = None, name: str | None = None
) -> DetectionResult:
    """The kinematic constraints created between the parts of a recording, over time.

    Parameters
    ----------
    demo : Demonstration
    phases : SegmentationResult, optional
        From :func:`segment_phases` of the same recording (its hand-holding supports
        the approach of each constraint).
    name : str, optional
        The recording's name, kept on each constraint found.
    """
    from thirdhand.constraints.detect import detect_constraints as detect

    return detect(demo, phases=phases, demo_name=name)


def plan_assembly(
    detections: Sequence[DetectionResult], *, min_support: float = 0.5
) -> AssemblyPlan:
    """The assembly plan of one or several recordings' detections (symbols assigned).

    Parameters
    ----------
    detections : sequence of DetectionResult
        One per recording of the same task, from :func:`detect_constraints`.
    min_support : float
        A slot becomes a step when more than this fraction of the recordings that
        show any constraint have it, in [0, 1) (0.5: a strict majority).
    """
    from thirdhand.plan.assembly import assemble

    if not detections:
        raise ThirdhandError("plan_assembly: no detection given")
    return assemble(detections, min_support=min_support)[1]


def fit_primitives(
    demos: Sequence[Demonstration],
    constraints: Sequence[Sequence[ConstraintEvent]],
    *,
    skills: int | None = None,
    names: Sequence[str] | None = None,
    seed: int = 0,
    skill_library: SkillLibrary | None = None,
) -> PrimitivesBlock:
    """A quaternion DMP and a ProMP per constraint, from the motions that created it.

    Parameters
    ----------
    demos : sequence of Demonstration
    constraints : sequence of sequences of ConstraintEvent
        Per recording, its constraints (e.g.
        :func:`thirdhand.learn.stages.learned_events` of a learned task).
    skills : int, optional
        Also learn a library of this many skills and explain each motion by them.
    names : sequence of str, optional
        A name per recording (the source of its explained motions).
    seed : int
        Seeds the skill library's restarts.
    skill_library : SkillLibrary, optional
        A library learned before (a task file's, rebuilt by
        :func:`~thirdhand.primitives.skill_library.skill_library_from_record`) that
        explains the motions instead of a new one.

    Returns
    -------
    PrimitivesBlock
        The task file's ``stages.primitives``: a
        :class:`~thirdhand.task.stages.PrimitiveRecord` per constraint symbol
        (``pose_dmp_from_record(record)`` rebuilds the fitted DMP).
    """
    from thirdhand.primitives.stage import primitives_stage

    if len(constraints) != len(demos):
        raise ThirdhandError(
            f"fit_primitives: {len(constraints)} constraint lists for {len(demos)} recordings"
        )
    return primitives_stage(
        demos,
        events=constraints,
        skills=skills,
        names=names,
        seed=seed,
        skill_library=skill_library,
    )


def learn_skills(
    tracks: Sequence[PoseTrack], options: SkillParserOptions | None = None
) -> SkillLibrary:
    """A library of skills learned from unlabelled tracks (the ``primitives library`` parser).

    ``lib.parse(track)`` then gives any track's runs of skills; ``lib.to_dict()``
    is the saveable document (``thirdhand.skill-library/1``).

    Parameters
    ----------
    tracks : sequence of PoseTrack
        One body's poses each (forces and other bodies when known).
    options : SkillParserOptions, optional
        Defaults: the HSMM, K by BIC, entry and exit skills when K ≥ 3.
    """
    from thirdhand.primitives.skill_library import SkillLibrary

    return SkillLibrary(options).fit(tracks)


def learn_reward(plans: Sequence[AssemblyPlan | TaskFile], *, seed: int = 0) -> AssemblyModel:
    """The relational reward (RCSI) of demonstrated plans.

    Parameters
    ----------
    plans : sequence of AssemblyPlan or TaskFile
        Plans from :func:`plan_assembly`, or the plans of task files.
    seed : int
        Seeds the random trajectories of the reward's training.

    Returns
    -------
    AssemblyModel
        The reward; plan other part sets with it by
        :func:`thirdhand.relational.assembly.plan_with_reward`.
    """
    from thirdhand.relational.assembly import learn_assembly
    from thirdhand.relational.domains.plans import trajectory_from_plan
    from thirdhand.task.model import TaskFile

    if not plans:
        raise ThirdhandError("learn_reward: no task given (expected at least one plan)")
    steps = [p.plan if isinstance(p, TaskFile) else p.steps for p in plans]
    empty = [i for i, s in enumerate(steps) if not s]
    if empty:
        raise ThirdhandError(f"learn_reward: task {empty[0]} has no plan")
    trajectories = [trajectory_from_plan(s, source=f"task {i}") for i, s in enumerate(steps)]
    return learn_assembly(trajectories, seed=seed)


def execute_task(
    task: TaskFile,
    *,
    robot: str | None = None,
    mode: Literal["offline", "online"] = "offline",
    seed: int = 0,
) -> ExecutionResult:
    """Execute a task's plan on a simulated robot arm with a motion planner.

    Parameters
    ----------
    task : TaskFile
        E.g. ``learn_task(...).task`` or ``thirdhand.taskfile.load_task(path)``.
    robot : {"panda", "baxter"}, optional
        The task's ``stages.execution.robot`` when not given, else Panda.
    mode : {"offline", "online"}
        Plan every step first, or observe–plan–act step by step.
    seed : int
        Seed of the start layout and the planner.
    """
    from thirdhand.execute.executor import Executor, task_defaults

    if robot is not None and robot not in ROBOTS:
        raise ThirdhandError(f"execute: robot {robot!r} unknown (expected one of {ROBOTS})")
    if mode not in ("offline", "online"):
        raise ThirdhandError(f"execute: mode {mode!r} unknown (expected 'offline' or 'online')")
    robot, assembly_xy = task_defaults(task, robot)
    executor = Executor.for_task(task, robot, seed=seed, assembly_xy=assembly_xy)
    return executor.run_offline(seed=seed) if mode == "offline" else executor.run_online(seed=seed)
