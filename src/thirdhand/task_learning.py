"""Every stage that needs no robot, from recordings to one task file.

:func:`learn_task` runs, in memory and in order, the interaction phases (CRF),
the constraints, keyframes, symbols and assembly plan
(:func:`thirdhand.plan.learn.learn`), the motor primitives of every learned
constraint, and the relational reward of the plan with the plans it makes for
other part sets. Each stage consumes the previous stage's objects: nothing is
written or read back between stages, and the primitives are fed the *learned*
constraints (never the recording's ground-truth labels).
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from thirdhand.demonstration import ConstraintEvent, Demonstration, FreeDofs
from thirdhand.errors import ThirdhandError

if TYPE_CHECKING:
    from thirdhand.constraints.detect import DetectionResult
    from thirdhand.plan.learn import Learned
    from thirdhand.relational.assembly import AssemblyModel, RewardPlan
    from thirdhand.segment.model import SegmentModel
    from thirdhand.segment.pipeline import SegmentationResult
    from thirdhand.task.model import TaskFile

#: The stages :func:`learn_task` can skip, in the order they run.
OPTIONAL_STAGES = ("segment", "primitives", "reward")


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

    def block(self) -> dict[str, Any]:
        """The task file's ``stages.reward`` block (JSON-able)."""
        return {
            "method": "RCSI (relational cascaded supervised IRL) on the learned plan",
            "reward_tree": str(self.model.rcsi.reward),
            "plans": {
                label: {
                    "parts": list(p.parts),
                    "complete": p.complete,
                    "perf": p.perf,
                    "steps": list(p.steps),
                }
                for label, p in self.plans.items()
            },
        }


@dataclass(frozen=True)
class LearnedTask:
    """What :func:`learn_task` found.

    Attributes
    ----------
    learned : Learned
        Phases, constraint detections, symbols, plan and keyframes.
    task : TaskFile
        The task file, with a block per stage that ran in ``task.stages``.
    primitives : dict or None
        The ``stages.primitives`` block (None when skipped or no constraint was learned).
    reward : RewardResult or None
        None when skipped or the plan is empty.
    skipped : tuple of str
        Stages not run, each with its reason (``"reward: skipped by the user"``).
    """

    learned: Learned
    task: TaskFile
    primitives: dict[str, Any] | None
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


#: Skills of the library that explains the constraint motions (transport,
#: approach, screwing turn, rest in the synthetic chair), unless told otherwise.
DEFAULT_SKILLS = 4


def fit_task_primitives(
    learned: Learned, *, skills: int | None = DEFAULT_SKILLS, seed: int = 0
) -> dict[str, Any] | None:
    """Motor primitives (quaternion DMP + ProMP) of every learned constraint.

    Parameters
    ----------
    learned : Learned
    skills : int, optional
        Skills of the library learned over all constraint motions, each motion
        explained as a sequence of them (None: no library; see
        :func:`~thirdhand.primitives.stage.primitives_stage`).
    seed : int
        Seeds the library's restarts.

    Returns
    -------
    dict or None
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
    task: TaskFile,
    *,
    targets: Mapping[str, Sequence[str]] | None = None,
    seed: int = 0,
) -> RewardResult:
    """Relational IRL (RCSI) on a task's plan, and plans for other part sets.

    Parameters
    ----------
    task : TaskFile
        With a non-empty plan.
    targets : mapping of str to sequence of str, optional
        Label to part names; default :func:`reward_targets` of the plan's parts.
    seed : int

    Raises
    ------
    RelationalError
        If the plan is empty.
    """
    from thirdhand.relational.assembly import learn_assembly, plan_with_reward
    from thirdhand.relational.domains.plans import parts_of
    from thirdhand.relational.logic import RelationalError

    if not task.plan:
        raise RelationalError("reward: the task has no plan (expected at least one step)")
    from thirdhand.relational.domains.plans import trajectory_from_steps

    trajectory = trajectory_from_steps([s.model_dump() for s in task.plan], source="task plan")
    model = learn_assembly([trajectory], seed=seed)
    goal = reward_targets(parts_of(trajectory)) if targets is None else targets
    plans = {label: plan_with_reward(model, list(parts)) for label, parts in goal.items()}
    return RewardResult(model, plans)


def learn_task(
    demos: Sequence[Demonstration],
    *,
    names: Sequence[str] | None = None,
    phases: Sequence[SegmentationResult] | None = None,
    segment: bool = True,
    segment_model: SegmentModel | None = None,
    primitives: bool = True,
    skills: int | None = DEFAULT_SKILLS,
    reward: bool = True,
    reward_plans: Mapping[str, Sequence[str]] | None = None,
    seed: int = 0,
    inputs: Sequence[str | os.PathLike[str]] = (),
    progress: Callable[[str], None] | None = None,
    detections: Sequence[DetectionResult] | None = None,
    min_support: float = 0.5,
    scene: str | os.PathLike[str] | None = None,
) -> LearnedTask:
    """Learn a task from demonstrations: every stage that needs no robot.

    Parameters
    ----------
    demos : sequence of Demonstration
        Demonstrations of one task (same part names).
    names : sequence of str, optional
        A name per demonstration (file names); default ``demo1``, ``demo2``…
    phases : sequence of SegmentationResult, optional
        Segmentations already computed, one per demonstration.
    segment : bool
        Run the interaction segmentation (when ``phases`` is not given).
    segment_model : SegmentModel, optional
        The segmentation model (default: the shipped one).
    primitives, reward : bool
        Run the motor-primitive and the relational-reward stages.
    skills : int, optional
        Skills of the library that explains the constraint motions in the
        primitives block (None: no library).
    reward_plans : mapping of str to sequence of str, optional
        Part sets the learned reward plans for; default :func:`reward_targets`.
    seed : int
        Seed of the reward stage's random transitions and of the skill library.
    inputs : sequence of path-like
        Source files, hashed into the task's provenance.
    progress : callable, optional
        Called with the name of each stage as it starts.
    detections : sequence of DetectionResult, optional
        Constraint detections already computed per demonstration (with its
        ``phases``; ``learn --jobs/--scheduler`` runs segmentation and detection
        of each recording as one unit).
    min_support : float
        A slot becomes a plan step when more than this fraction of the recordings
        that show any constraint have it, in [0, 1) (0.5: a strict majority; 0: every
        slot seen once).
    scene : path-like, optional
        A 3rdHand scene file (``scene_*.json``) giving the parts' meshes.

    Returns
    -------
    LearnedTask

    Raises
    ------
    ThirdhandError
        On an empty demonstration list or a stage's bad input (one line).
    """
    from thirdhand.plan.learn import learn

    demo_list = list(demos)
    if not demo_list:
        raise ThirdhandError("learn: no demonstration given")
    say = progress or (lambda _stage: None)
    skipped: list[str] = []
    ph: list[SegmentationResult | None] | None = list(phases) if phases is not None else None
    if ph is None and segment:
        from thirdhand.segment import segment_demonstration

        say("segment")
        ph = [segment_demonstration(d, segment_model) for d in demo_list]
    elif ph is None:
        skipped.append("segment: skipped by the user")
    say("constraints and plan")
    learned = learn(
        demo_list,
        names=names,
        phases=ph,
        segment=False,
        inputs=inputs,
        detections=detections,
        min_support=min_support,
        scene=scene,
    )
    task = learned.task()
    block = None
    if not primitives:
        skipped.append("primitives: skipped by the user")
    else:
        say("primitives")
        block = fit_task_primitives(learned, skills=skills, seed=seed)
        if block is None:
            skipped.append("primitives: no constraint was learned")
        else:
            task.stages["primitives"] = block
    result = None
    if not reward:
        skipped.append("reward: skipped by the user")
    elif not task.plan:
        skipped.append("reward: the plan is empty")
    else:
        say("reward")
        result = learn_task_reward(task, targets=reward_plans, seed=seed)
        task.stages["reward"] = result.block()
    return LearnedTask(learned, task, block, result, tuple(skipped))
