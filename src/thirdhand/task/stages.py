"""The typed stage blocks of a task file (``TaskFile.stages``).

Each pipeline stage writes one block; each block is a model validated when the
task file is loaded, so a later stage (execution, the review GUI) reads typed
records and never walks dicts. A block keeps fields it does not know (every
model here allows extra fields, like the rest of the task file), and
:class:`Stages` keeps whole blocks it does not know (``transfer``, ``iros15``,
``truth``, a newer thirdhand's) as plain JSON: nothing is silently dropped.

Blocks
------
``constraints``
    :class:`ConstraintsBlock`: how the constraints were detected, per recording.
``plan``
    :class:`PlanBlock`: how the plan was voted from the recordings.
``primitives``
    :class:`PrimitivesBlock`: a :class:`PrimitiveRecord` per constraint (pose DMP
    and ProMP parameters) and the optional skill library.
``reward``
    :class:`RewardBlock`: the relational reward and the plans it makes.
``review``
    :class:`ReviewBlock`: the GUI effort log and the confirmed constraints.
``perception``
    :class:`PerceptionBlock`: pointing and attention events.
``scene``
    :class:`SceneBlock`: the scene file the meshes came from.
``grasps``
    :class:`GraspsBlock`: per constraint, where the person's hands held the
    child when they picked it up.
``transfer``
    :class:`TransferBlock`: where a transferred task came from.
``execution``
    :class:`ExecutionDefaults`: the robot and the options execution uses when
    told nothing else.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import (
    ConfigDict,
    Field,
    JsonValue,
    SerializationInfo,
    SerializerFunctionWrapHandler,
    model_serializer,
    model_validator,
)

from thirdhand.task.constraint import RunnerUp, drop_empty_runner_up
from thirdhand.task.geometry import Pose, Quat, TaskModel, Vec3


class Block(TaskModel):
    """Base of the stage blocks: unknown fields kept, no NaN or infinity.

    A field is written when it was given or differs from its default, so a
    block read from a file is written back as it was read (no defaults added).
    """

    @model_serializer(mode="wrap")
    def _given_fields(
        self, handler: SerializerFunctionWrapHandler, info: SerializationInfo
    ) -> dict[str, object]:
        # ``object``, not JsonValue: the handler's output is serialised as it is
        data: dict[str, object] = handler(self)
        for name, f in type(self).model_fields.items():
            key = f.alias if info.by_alias and f.alias else name
            if key not in data or name in self.model_fields_set:
                continue
            default = f.get_default(call_default_factory=True)
            if getattr(self, name) == default:
                del data[key]
        return data


# --- constraints -------------------------------------------------------------


class DofRanges(TaskModel):
    """A ``[lo, hi]`` range per DOF name (tx, ty, tz, rx, ry, rz), metres or radians."""

    model_config = ConfigDict(extra="allow")

    tx: tuple[float, float]
    ty: tuple[float, float]
    tz: tuple[float, float]
    rx: tuple[float, float]
    ry: tuple[float, float]
    rz: tuple[float, float]


class ConstraintInstanceRecord(TaskModel):
    """One constraint a recording created (a ``ConstraintInstance``).

    Attributes
    ----------
    parent, child, type : str
    start, end : float
        Seconds on the recording's clock.
    pos, quat
        The child's pose in the parent frame, metres and x y z w.
    frame : Pose
        The constraint frame in the parent frame.
    ranges : DofRanges
    confidence : float
    spin_deg : float
    symbol : str or None
    runner_up : RunnerUp or None
        The next most probable type of a joint, with its geometry.
    """

    parent: str
    child: str
    type: str
    start: float
    end: float | None = None
    pos: Vec3
    quat: Quat
    frame: Pose
    ranges: DofRanges
    confidence: float
    spin_deg: float | None = None
    symbol: str | None = None
    runner_up: RunnerUp | None = None

    @model_serializer(mode="wrap")
    def _no_empty_runner_up(self, handler: SerializerFunctionWrapHandler) -> dict[str, object]:
        return drop_empty_runner_up(handler(self))


class HmmParameters(TaskModel):
    """The constraint HMM's parameters after EM."""

    sigma_pos_m: float
    sigma_rot_deg: float
    transition: list[list[float]]


class RecordingConstraints(TaskModel):
    """The constraints one recording created."""

    name: str
    root: str | None = None
    instances: list[ConstraintInstanceRecord] = Field(default_factory=list)
    hmm: HmmParameters | None = None


class ConstraintsBlock(Block):
    """``stages.constraints``: the detection method and each recording's constraints."""

    method: str = ""
    root: str | None = None
    demos: list[RecordingConstraints] = Field(default_factory=list)


# --- plan --------------------------------------------------------------------


class PlanBlock(Block):
    """``stages.plan``: the vote of the recordings on the plan's steps.

    Attributes
    ----------
    n_demos : int
        Recordings the plan was learned from (execution keeps the plan's order
        when there are two or more).
    silent_demos : list of str
        Recordings without any constraint (no vote).
    support : list of int
        Per step, the recordings that show it.
    left_out : dict of str to int
        Slots seen too rarely to be steps, and in how many recordings.
    steps : list of str
    relational_trajectory : list of list of str
        The ground atoms after each step.
    interchangeable : list of list of int
        Pairs of step indices with no order between them.
    """

    n_demos: int = Field(default=1, ge=0)
    silent_demos: list[str] = Field(default_factory=list)
    support: list[int] = Field(default_factory=list)
    left_out: dict[str, int] = Field(default_factory=dict)
    steps: list[str] = Field(default_factory=list)
    relational_trajectory: list[list[str]] = Field(default_factory=list)
    interchangeable: list[list[int]] = Field(default_factory=list)


# --- primitives ----------------------------------------------------------------


class DmpParameters(TaskModel):
    """A fitted position or quaternion DMP (:func:`thirdhand.primitives.serialize.dmp_to_dict`)."""

    kind: Literal["dmp", "quaternion_dmp"]
    n_weights: int = Field(ge=1)
    alpha: float
    alpha_x: float
    tau: float = Field(gt=0)
    dt: float = Field(gt=0)
    start: list[float]
    goal: list[float]
    start_velocity: list[float]
    weights: list[list[float]]

    @model_validator(mode="after")
    def _check_weights(self) -> DmpParameters:
        if len(self.weights) != self.n_weights:
            raise ValueError(
                f"weights: expected {self.n_weights} rows (n_weights), got {len(self.weights)}"
            )
        return self


class PoseDmpParameters(TaskModel):
    """A fitted pose DMP: a position DMP and an orientation DMP."""

    kind: Literal["pose_dmp"] = "pose_dmp"
    orientation: Literal["quaternion", "seven"] = "quaternion"
    time_convention: str | None = None
    position: DmpParameters
    rotation: DmpParameters


class ProMPParameters(TaskModel):
    """A ProMP: weight mean and the packed lower Cholesky factor of its covariance."""

    kind: Literal["promp"] = "promp"
    n_weights: int = Field(ge=1)
    dims: int = Field(ge=1)
    duration: float = Field(gt=0)
    noise: float = Field(gt=0)
    mean: list[float]
    cov_cholesky_lower: list[float]

    @model_validator(mode="after")
    def _check_sizes(self) -> ProMPParameters:
        f = self.n_weights * self.dims
        if len(self.mean) != f:
            raise ValueError(f"mean: expected n_weights × dims = {f} numbers, got {len(self.mean)}")
        packed = f * (f + 1) // 2
        if len(self.cov_cholesky_lower) != packed:
            raise ValueError(
                f"cov_cholesky_lower: expected {packed} numbers, got {len(self.cov_cholesky_lower)}"
            )
        return self


class ImitationError(TaskModel):
    """Largest error of a DMP's rollout against what it was fit to."""

    pos_m: float
    rot_deg: float


class SkillStep(TaskModel):
    """One step of an explained motion: a library skill over ``[start, end]`` seconds."""

    skill: int = Field(ge=0)
    start: float
    end: float


class ExplainedMotion(TaskModel):
    """A demonstrated motion explained as a sequence of library skills, in time order."""

    source: str
    steps: list[SkillStep]

    @model_validator(mode="after")
    def _check_order(self) -> ExplainedMotion:
        prev_end = None
        for k, st in enumerate(self.steps):
            if st.end < st.start:
                raise ValueError(f"steps[{k}]: end {st.end} s is before start {st.start} s")
            if prev_end is not None and st.start < prev_end - 1e-9:
                raise ValueError(
                    f"steps[{k}].start: {st.start} s is before the previous step's end "
                    f"{prev_end} s (steps are in time order)"
                )
            prev_end = st.end
        return self


class PrimitiveEdit(TaskModel):
    """A key point of a primitive a person moved in the review GUI (parent frame, metres)."""

    index: int = Field(ge=0)
    time_s: float
    from_: Vec3 = Field(alias="from")
    to: Vec3


class PrimitiveRecord(TaskModel):
    """One constraint's learned motion, child pose in the parent frame.

    The task-file form of :class:`thirdhand.primitives.stage.ConstraintPrimitive`:
    parameters, never pickles; :meth:`pose_dmp` and :meth:`promp_model` rebuild
    the fitted objects exactly.

    Attributes
    ----------
    parent, child, type : str
    frame : str
        Always ``"parent"``.
    goal : Pose
        The constraint pose, parent frame.
    n_examples : int
    imitation_error, raw_error : ImitationError
    dmp : PoseDmpParameters
    promp : ProMPParameters
    skills : list of ExplainedMotion or None
        Per example, the motion as library skills (with a skill library).
    source : str or None
        ``"corrected"`` once a person moved a key point.
    edits : list of PrimitiveEdit
    """

    parent: str
    child: str
    type: str
    frame: Literal["parent"] = "parent"
    goal: Pose
    n_examples: int = Field(ge=1)
    imitation_error: ImitationError
    raw_error: ImitationError
    dmp: PoseDmpParameters
    promp: ProMPParameters
    skills: list[ExplainedMotion] | None = Field(default=None, exclude_if=lambda v: v is None)
    source: str | None = Field(default=None, exclude_if=lambda v: v is None)
    edits: list[PrimitiveEdit] = Field(default_factory=list, exclude_if=lambda v: not v)


class HsmmSkills(TaskModel):
    """The parameters of a skill library's hidden semi-Markov model, K skills over C channels.

    ``log_*`` are log-probabilities, null where a move is impossible.
    """

    means: list[list[float]]
    covs: list[list[list[float]]]
    duration_log_mean: list[float]
    duration_log_sd: list[float]
    max_duration: int = Field(ge=1)
    log_trans: list[list[float | None]]
    log_init: list[float | None]
    log_final: list[float | None]


class SkillSummary(TaskModel):
    """What a skill does, for a reader: typical speed and angular rate, share of the motions."""

    id: int = Field(ge=0)
    typical_speed_m_s: float = Field(ge=0)
    typical_angular_speed_rad_s: float = Field(ge=0)
    share: float = Field(ge=0, le=1)
    n_steps: int = Field(ge=0)
    mean_step_s: float = Field(ge=0)


def _shape(value: Any) -> tuple[int, ...]:
    """The shape of a nested list, () for a number; -1 where rows differ in length."""
    if not isinstance(value, list):
        return ()
    if not value:
        return (0,)
    inner = {_shape(v) for v in value}
    return (len(value), *inner.pop()) if len(inner) == 1 else (len(value), -1)


class SkillLibraryRecord(TaskModel):
    """The skill library that explains the constraint motions (``thirdhand.skill-library/1``).

    The document :meth:`thirdhand.primitives.skill_library.SkillLibrary.to_dict`
    writes, with the method, the frame and a per-skill ``summary`` beside it;
    :meth:`fitted` rebuilds the library that parses new motions.
    """

    schema_: Literal["thirdhand.skill-library/1"] = Field(alias="schema")
    parser: Literal["hsmm"] = "hsmm"
    method: str = ""
    frame: str = "child pose in the parent part's frame"
    n_skills: int = Field(ge=1)
    ends: bool
    channels: list[str] = Field(min_length=1)
    rate_hz: float = Field(gt=0)
    window: int = Field(ge=1)
    seed: int
    skills: HsmmSkills
    summary: list[SkillSummary] = Field(default_factory=list)

    @model_validator(mode="before")
    @classmethod
    def _older(cls, data: Any) -> Any:
        if isinstance(data, dict) and "schema" not in data and isinstance(data.get("skills"), list):
            raise ValueError(
                "a library of ProMP skills written by an earlier thirdhand; run "
                "`thirdhand learn` again to explain the motions with today's skill library"
            )
        return data

    @model_validator(mode="after")
    def _check_shapes(self) -> SkillLibraryRecord:
        k, c = self.n_skills, len(self.channels)
        want = {
            "means": (k, c),
            "covs": (k, c, c),
            "duration_log_mean": (k,),
            "duration_log_sd": (k,),
            "log_trans": (k, k),
            "log_init": (k,),
            "log_final": (k,),
        }
        for name, shape in want.items():
            got = _shape(getattr(self.skills, name))
            if got != shape:
                dims = " × ".join(str(d) for d in shape)
                raise ValueError(
                    f"skills.{name}: expected {dims} numbers (n_skills {k}, {c} channels)"
                )
        from thirdhand.task.skill_model import skill_model_problem

        sk = self.skills
        problem = skill_model_problem(
            channels=self.channels, rate_hz=self.rate_hz, window=self.window, means=sk.means,
            covs=sk.covs, duration_log_mean=sk.duration_log_mean,
            duration_log_sd=sk.duration_log_sd, max_duration=sk.max_duration,
            log_trans=sk.log_trans, log_init=sk.log_init, log_final=sk.log_final,
        )  # fmt: skip
        if problem is not None:
            raise ValueError(problem)
        for i, s in enumerate(self.summary):
            if s.id != i:
                raise ValueError(f"summary[{i}].id: expected {i} (skills in order), got {s.id}")
        if self.summary and len(self.summary) != k:
            raise ValueError(f"summary: expected {k} skills (n_skills), got {len(self.summary)}")
        return self


class PrimitivesBlock(Block):
    """``stages.primitives``: a learned motion per constraint, and the skill library.

    Attributes
    ----------
    schema_ : str
        ``"thirdhand.primitives/1"`` (JSON key ``schema``).
    frame : str
    constraints : dict of str to PrimitiveRecord
        Keyed by the constraint's symbol.
    skill_library : SkillLibraryRecord or None
    skipped : list of str
        One line per constraint that has no primitive, saying why (no tracked
        approach motion to learn from).
    """

    schema_: str = Field(default="thirdhand.primitives/1", alias="schema")
    frame: str = "child pose in the parent part's frame"
    constraints: dict[str, PrimitiveRecord] = Field(default_factory=dict)
    skill_library: SkillLibraryRecord | None = Field(default=None, exclude_if=lambda v: v is None)
    skipped: list[str] = Field(default_factory=list, exclude_if=lambda v: not v)

    @model_validator(mode="after")
    def _check_skills(self) -> PrimitivesBlock:
        explained = [k for k, c in self.constraints.items() if c.skills is not None]
        if self.skill_library is None:
            if explained:
                raise ValueError(
                    f"constraints.{explained[0]}.skills: refers to skills, but "
                    "skill_library is missing"
                )
            return self
        n = self.skill_library.n_skills
        for key in explained:
            for j, ex in enumerate(self.constraints[key].skills or []):
                for k, st in enumerate(ex.steps):
                    if st.skill >= n:
                        raise ValueError(
                            f"constraints.{key}.skills[{j}].steps[{k}].skill: unknown skill "
                            f"{st.skill} (the library has skills 0..{n - 1})"
                        )
        return self

    def find(self, parent: str, child: str) -> tuple[str, PrimitiveRecord] | None:
        """The key and the record of ``child``'s motion onto ``parent``, or None."""
        for key, rec in self.constraints.items():
            if (rec.parent, rec.child) == (parent, child):
                return key, rec
        return None


# --- reward --------------------------------------------------------------------


class RewardPlanRecord(TaskModel):
    """The plan the learned reward makes for one part set."""

    parts: list[str]
    complete: bool
    perf: float
    steps: list[str]


class RewardBlock(Block):
    """``stages.reward``: the relational reward (RCSI) and the plans it makes."""

    method: str = ""
    reward_tree: str = ""
    plans: dict[str, RewardPlanRecord] = Field(default_factory=dict)


# --- review --------------------------------------------------------------------


class EffortRecord(TaskModel):
    """GUI operations per object, and the parameters a person changed."""

    operations: dict[str, dict[str, int]] = Field(default_factory=dict)
    total_operations: int = Field(default=0, ge=0)
    changed_parameters: list[str] | None = Field(default=None, exclude_if=lambda v: v is None)
    n_changed_parameters: int | None = Field(default=None, exclude_if=lambda v: v is None)


class ReviewBlock(Block):
    """``stages.review``: the effort log and what a person confirmed.

    Attributes
    ----------
    effort : EffortRecord or None
    confirmed : dict of str to list of str
        Constraint id to ``"constraint"`` and/or DOF names.
    """

    effort: EffortRecord | None = Field(default=None, exclude_if=lambda v: v is None)
    confirmed: dict[str, list[str]] = Field(default_factory=dict, exclude_if=lambda v: not v)


# --- perception ----------------------------------------------------------------


class PointingRecord(TaskModel):
    """A pointing gesture: which hand, at which object (None: at nothing), when."""

    hand: str
    object: str | None = None
    t0: float
    t1: float
    angle_deg: float | None = None
    ray: str | None = None


class AttentionRecord(TaskModel):
    """An interval a person looked at one object."""

    object: str
    t0: float
    t1: float
    angle_deg: float | None = None
    source: str | None = None


class PerceptionBlock(Block):
    """``stages.perception``: pointing and attention events, seconds on the recording's clock."""

    pointing: list[PointingRecord] = Field(default_factory=list)
    attention: list[AttentionRecord] = Field(default_factory=list)
    source: str | None = None
    parameters: dict[str, float | int | str | bool | None] = Field(default_factory=dict)


# --- scene and grasps ------------------------------------------------------------


class SceneBlock(Block):
    """``stages.scene``: where the parts' meshes came from.

    The meshes themselves are on the objects (``objects[i].mesh``, ``scale``,
    ``mesh_to_body``), their paths relative to the task file where possible.

    Attributes
    ----------
    file : str or None
        The 3rdHand scene file (``scene_*.json``) read, relative to the task file
        where possible.
    """

    file: str | None = None


class DemoGraspRecord(TaskModel):
    """Where a person's hand held a part when they picked it up.

    Attributes
    ----------
    hand : str
        The hand (``"demo:rh"``-style label of :func:`thirdhand.execute.grasps.demo_grasps`).
    pose : Pose
        ``T_part_tool``: the tool frame (origin between the fingertips, z the
        approach, y the closing direction) in the part's body frame.
    demo : str or None
        The recording it was seen in.
    time : float or None
        Seconds on that recording's clock: the constraint's appearance the
        grasp preceded.
    """

    hand: str
    pose: Pose
    demo: str | None = None
    time: float | None = None


class GraspsBlock(Block):
    """``stages.grasps``: per constraint id, the demonstrated grasps of its child."""

    method: str = "last fingertip centroid within 3 cm of the part, 3 s before the constraint"
    constraints: dict[str, list[DemoGraspRecord]] = Field(default_factory=dict)


# --- transfer --------------------------------------------------------------------


class TransferBlock(Block):
    """``stages.transfer``: the task this one was transferred from, onto which object set.

    Attributes
    ----------
    to : str
        The target object set.
    mapping : dict of str to str
        Source part to target part.
    notes : list of str
    """

    to: str
    mapping: dict[str, str] = Field(default_factory=dict)
    notes: list[str] = Field(default_factory=list)


# --- execution -------------------------------------------------------------------


class ExecutionDefaults(Block):
    """``stages.execution``: what ``execute`` uses when told nothing else.

    Attributes
    ----------
    robot : str or None
        ``"panda"`` or ``"baxter"``.
    assembly_xy : (float, float) or None
        World x, y where the assembly is built, metres.
    """

    robot: Literal["panda", "baxter"] | None = None
    assembly_xy: tuple[float, float] | None = None


# --- all of them ---------------------------------------------------------------


class Stages(TaskModel):
    """The stage blocks of a task file; each None until its stage ran.

    Blocks this version does not know are kept as they are (``model_extra``).
    """

    model_config = ConfigDict(extra="allow")
    __pydantic_extra__: dict[str, JsonValue] = Field(init=False)

    constraints: ConstraintsBlock | None = Field(default=None, exclude_if=lambda v: v is None)
    plan: PlanBlock | None = Field(default=None, exclude_if=lambda v: v is None)
    primitives: PrimitivesBlock | None = Field(default=None, exclude_if=lambda v: v is None)
    reward: RewardBlock | None = Field(default=None, exclude_if=lambda v: v is None)
    review: ReviewBlock | None = Field(default=None, exclude_if=lambda v: v is None)
    perception: PerceptionBlock | None = Field(default=None, exclude_if=lambda v: v is None)
    scene: SceneBlock | None = Field(default=None, exclude_if=lambda v: v is None)
    grasps: GraspsBlock | None = Field(default=None, exclude_if=lambda v: v is None)
    transfer: TransferBlock | None = Field(default=None, exclude_if=lambda v: v is None)
    execution: ExecutionDefaults | None = Field(default=None, exclude_if=lambda v: v is None)

    def names(self) -> list[str]:
        """The blocks present, known ones in schema order, then the others."""
        known = [n for n in type(self).model_fields if getattr(self, n) is not None]
        return known + list(self.model_extra or {})

    def other(self, name: str) -> JsonValue:
        """A block this version does not know (``transfer``, ``iros15``...), or None."""
        return (self.model_extra or {}).get(name)

    def set_other(self, name: str, block: JsonValue) -> None:
        """Store a block this version does not type (kept as plain JSON)."""
        if name in type(self).model_fields:
            raise ValueError(f"stages.{name} is a typed block; set the attribute instead")
        extra = self.__pydantic_extra__
        assert extra is not None  # extra="allow"
        extra[name] = block

    def ensure_review(self) -> ReviewBlock:
        """The review block, created empty when missing."""
        if self.review is None:
            self.review = ReviewBlock()
        return self.review
