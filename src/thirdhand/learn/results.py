"""The typed results of the learning stages, passed from one stage to the next."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from thirdhand.demonstration import Demonstration

if TYPE_CHECKING:
    from thirdhand.constraints.detect import ConstraintInstance, DetectionResult
    from thirdhand.plan.assembly import AssemblyPlan
    from thirdhand.plan.keyframes import Keyframe
    from thirdhand.plan.symbols import Symbol
    from thirdhand.relational.assembly import AssemblyModel, RewardPlan
    from thirdhand.segment.pipeline import SegmentationResult
    from thirdhand.task.model import TaskFile
    from thirdhand.task.stages import PrimitivesBlock


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


@dataclass(frozen=True, kw_only=True)
class Learned:
    """What the per-recording stages and the plan stage found.

    Attributes
    ----------
    demos : list of Demonstration
    names : list of str
        A name per demonstration (file name or ``demo1``...).
    phases : list of SegmentationResult or None
        Per demonstration; None where segmentation was skipped.
    detections : list of DetectionResult
        Per demonstration, its constraints over time.
    symbols : list of Symbol
        Constraint instances clustered into slots across the demonstrations.
    plan : AssemblyPlan
    keyframes : list of list of Keyframe
        Per demonstration.
    """

    demos: list[Demonstration]
    names: list[str]
    phases: list[SegmentationResult | None]
    detections: list[DetectionResult]
    symbols: list[Symbol]
    plan: AssemblyPlan
    keyframes: list[list[Keyframe]]

    @property
    def instances(self) -> list[list[ConstraintInstance]]:
        """Each demonstration's constraint instances."""
        return [d.instances for d in self.detections]


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


@dataclass(frozen=True)
class LearnedTask:
    """What :func:`~thirdhand.learn.run.learn_task` found.

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
