"""What one plan step becomes: the executor's options, the motions of a step and its report.

A planned step is a list of :class:`Segment` (joint-space waypoint paths, the
world changes before and after each: contacts allowed, the part attached or
detached) and a :class:`StepReport` saying what was found or why not.
Joint values are radians, distances metres, times seconds.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from thirdhand.arrays import FloatArray
from thirdhand.execute.goals import POS_TOL_M, ROT_TOL_RAD


@dataclass
class ExecutionOptions:
    """Knobs of the executor (distances in metres, times in seconds).

    Attributes
    ----------
    sample_free_dofs : bool
        Try goals sampled inside the constraint's free DOFs when the nominal one fails.
    n_goal_samples : int
        Goals tried per step (the nominal one first) when sampling.
    max_grasps : int
        Grasp candidates tried per step, best ranked first.
    rank_by_reach : bool
        Rank the grasps by a quick IK check at the pick and at the goals first
        (:func:`~thirdhand.execute.step_search.rank_by_reach`). Off by default: on the
        learned chair it changes the grasps so that no step follows its primitive, and
        with a demonstration it can prefer a shape grasp to the person's.
    n_rank_goals : int
        Goals (the nominal one first) that check uses.
    plan_time_limit : float
        Bound of each motion-planning query.
    step_time_limit : float
        Bound of the whole search of one step (grasps × goals × planning).
    approach_m, lift_m, insert_m, retreat_m : float
        Lengths of the straight moves.
    planner : str
        OMPL planner name (see :data:`thirdhand.execute.planner.PLANNERS`).
    use_primitives : bool
        Follow the learned approach primitive when the task has one.
    straight_entry_m : float
        The last metres of a primitive's insertion run straight in along the
        insertion axis, square to the slot
        (:func:`~thirdhand.execute.primitive_motion.straight_entry`); 0 follows the
        primitive to the end. ``thirdhand simulate`` plans with 0.02 (a part with a
        millimetre of clearance jams when it comes in at an angle).
    primitive_m : float
        Length of the primitive's final approach followed by the place motion.
    pos_tol, rot_tol : float
        Tolerances of constraint detection, metres and radians.
    use_perception : bool
        Online: leave the part a person points at to them (``stages.perception``).
    pointing_lookback_s : float
        How long a pointing gesture keeps its part the person's after it ends.
    wait_s : float
        Online: how long the robot waits at a time when only the person's step is left.
    order : {"auto", "plan", "parents"}
        What binds the order of the steps (:mod:`~thirdhand.execute.step_order`):
        the learned plan's order (``"plan"``), only parents before children
        (``"parents"``), or the plan's order when it was learned from several
        demonstrations (``"auto"``).
    reorder : bool
        Offline: when a step fails, move it to the front and plan again.
    max_parts : int
        Interchangeable parts tried per slot (1: the slot's own part first, then
        only when it is already used).
    placement : {"auto", "geometry", "reach"}
        How :meth:`Executor.for_task` stands the base: the geometric choice
        (:func:`~thirdhand.execute.layout.assembly_base_pose`) or, of the first
        geometric candidates, the one whose goals the arm reaches best
        (:func:`~thirdhand.execute.placement.choose_placement`). ``"auto"`` (the
        default): the geometric choice unless the arm reaches no goal of some child
        there (:func:`~thirdhand.execute.placement.score_placement`); then by reach,
        with start spots within reach (``start_grasps`` at least
        :data:`~thirdhand.execute.executor.AUTO_START_GRASPS`).
    start_grasps : int
        :meth:`Executor.for_task`: a start spot farther than 0.55 m from the arm is taken
        only if at least this many of the part's grasps have an IK solution there (0: any
        spot in the band; :func:`~thirdhand.execute.placement.reach_check`).
    regrasp : bool
        When no grasp reached where the part lies reaches its goal, put the part down
        near the arm and pick it again (:mod:`~thirdhand.execute.regrasp`); tried only
        after the plain search of the step failed.
    fit_grasps_to_fingers : bool
        Slide each demonstrated grasp back to within the gripper's finger reach and
        centre it between the faces it closes on
        (:func:`~thirdhand.execute.grasps.within_fingers`): a person's fingertips hold
        a board deeper than a parallel gripper can; and keep only the shape grasps the
        fingers close on, centred between them
        (:func:`~thirdhand.execute.grasps.between_fingers`). ``thirdhand simulate``
        plans with it (the friction grasp needs it); ``execute`` keeps the grasps as
        they are.
    straight_carry : bool
        Carry the part first along a straight line of the tool, its orientation turned
        evenly from the lift to the insertion (a joint-space plan only when that line is
        blocked or unreachable): a part held by friction far from its centre of mass
        turns out of the fingers when a joint-space path tilts it on the way.
        ``thirdhand simulate`` plans with it; ``execute`` plans in joint space.
    """

    sample_free_dofs: bool = True
    n_goal_samples: int = 24
    max_grasps: int = 24
    rank_by_reach: bool = False
    n_rank_goals: int = 3
    plan_time_limit: float = 5.0
    step_time_limit: float = 60.0
    approach_m: float = 0.08
    lift_m: float = 0.08
    insert_m: float = 0.05
    retreat_m: float = 0.08
    planner: str = "rrtconnect"
    use_primitives: bool = True
    primitive_m: float = 0.06
    straight_entry_m: float = 0.0
    pos_tol: float = POS_TOL_M
    rot_tol: float = ROT_TOL_RAD
    use_perception: bool = True
    pointing_lookback_s: float = 5.0
    wait_s: float = 1.0
    order: str = "auto"
    reorder: bool = True
    max_parts: int = 2
    placement: str = "auto"
    start_grasps: int = 0
    regrasp: bool = True
    fit_grasps_to_fingers: bool = False
    straight_carry: bool = False


@dataclass
class Segment:
    """One motion of the arm and what changes in the world before and after it.

    Attributes
    ----------
    name : str
        ``"approach"``, ``"grasp"``, ``"lift"``, ``"transport"``, ``"insert"``,
        ``"retreat"`` or ``"home"``.
    path : ndarray, shape (m, dof)
        Waypoints, radians; straight joint segments between them.
    before, after : list of tuple
        World changes: ``("allow" | "disallow", a, b)``, ``("attach" | "detach", part)``.
    """

    name: str
    path: FloatArray
    before: list[tuple[str, ...]] = field(default_factory=list)
    after: list[tuple[str, ...]] = field(default_factory=list)


@dataclass(frozen=True)
class RegraspReport:
    """How a step was done through an intermediate placement.

    Attributes
    ----------
    spot : tuple of 3 floats
        Where the part was put down: its body origin, world, metres.
    distance_m : float
        Horizontal distance of the part's centre (of its bounding box, world) there from
        the arm's first joint.
    face_down : bool
        Put down turned half a turn about a horizontal axis (else at its start
        resting orientation, turned about the vertical).
    put_down_grasp : str
        Label of the grasp that carried it to the spot.
    plain_status : str
        Why the step failed without the regrasp.
    spots : tuple of (int, int)
        Free spots drawn, of which feasible by the IK check.
    """

    spot: tuple[float, float, float]
    distance_m: float
    face_down: bool
    put_down_grasp: str
    plain_status: str
    spots: tuple[int, int]


@dataclass
class SearchCounts:
    """What the search of one step tried, and how it went.

    Attributes
    ----------
    grasps, grasps_reachable : int
        Grasp candidates tried, and those reached where the part lies.
    grasps_reach_both : int
        Grasps that reach both where the part lies and a goal (when counted).
    goals, place_reachable : int
        Goal poses tried, and those reached with some grasp.
    plans, plans_failed : int
        Planning queries, and those that failed.
    primitive_rejected : int
        Learned-primitive motions rejected (blocked or not followable).
    grasp_ik_failed, place_ik_failed : int
        No IK start converged.
    grasp_in_collision, place_in_collision : int
        IK converged, every solution collides.
    straight_failed : int
        Straight moves blocked or not solvable.
    """

    grasps: int = 0
    grasps_reachable: int = 0
    grasps_reach_both: int = 0
    goals: int = 0
    place_reachable: int = 0
    plans: int = 0
    plans_failed: int = 0
    primitive_rejected: int = 0
    grasp_ik_failed: int = 0
    grasp_in_collision: int = 0
    place_ik_failed: int = 0
    place_in_collision: int = 0
    straight_failed: int = 0

    @classmethod
    def from_counts(cls, counts: dict[str, int]) -> SearchCounts:
        """The record of the search's counters (names as the fields')."""
        return cls(**{k: int(v) for k, v in counts.items()})


@dataclass
class StepReport:
    """What happened to one plan step.

    Attributes
    ----------
    index : int
        Plan step index.
    parent, child, constraint : str
    success : bool
    status : str
        ``"done"``, ``"done by person"``, ``"already holds"``, or why it failed.
    planning_time_s : float
        Wall time of the step's search and planning.
    joint_length_rad, tool_length_m : float
        Length of the executed path (joint space, tool in the world).
    n_collisions : int
        Configurations in collision along the executed path, densely checked.
    n_dense : int
        Configurations checked.
    grasp : str or None
        Label of the grasp used.
    grasp_source : str or None
        Where the grasp came from: ``"demo"`` (the demonstrator's fingers) or ``"shape"``.
    place_motion : str
        How the part was brought onto its goal: ``"primitive"`` (the end of the
        learned primitive) or ``"straight"`` (in along the insertion axis); empty
        when the robot did not place it.
    motions : dict of str to str
        Per segment (``"approach"``, ``"grasp"``, ``"lift"``, ``"transport"``,
        ``"insert"``, ``"retreat"``): ``"planner"`` (:func:`~thirdhand.execute.planner.plan_motion`:
        its direct joint segment when free, else OMPL), ``"straight"`` (a straight
        line of the tool) or ``"primitive"`` (the learned primitive).
    goal_dofs : list of float or None
        The goal's displacement inside the free DOFs (tx ty tz rx ry rz).
    tried : SearchCounts
        What the search tried (grasps, goals, IK and planning outcomes).
    collision_pairs : list of (str, str, int)
        The pairs most often colliding where IK converged (at most three, most
        frequent first, with their counts): what to move when a step fails.
    regrasp : RegraspReport or None
        Set when the step was done through an intermediate placement (the part put
        down near the arm and picked again); ``grasp``, ``motions`` and ``tried``
        then describe the second pick (``motions`` also has the ``"regrasp ..."``
        segments of the put-down).
    """

    index: int
    parent: str
    child: str
    constraint: str
    success: bool
    status: str
    planning_time_s: float = 0.0
    joint_length_rad: float = 0.0
    tool_length_m: float = 0.0
    n_collisions: int = 0
    n_dense: int = 0
    grasp: str | None = None
    grasp_source: str | None = None
    place_motion: str = ""
    motions: dict[str, str] = field(default_factory=dict)
    goal_dofs: list[float] | None = None
    tried: SearchCounts = field(default_factory=SearchCounts)
    collision_pairs: list[tuple[str, str, int]] = field(default_factory=list)
    regrasp: RegraspReport | None = None


@dataclass
class StepPlan:
    """The motions of one step, or None-free failure details in the report."""

    report: StepReport
    segments: list[Segment] = field(default_factory=list)
    final_pose: FloatArray | None = None


@dataclass
class ExecutionResult:
    """Outcome of a run.

    Attributes
    ----------
    steps : list of StepReport
        One per attempted step, in execution order (online: also the steps a
        person did or that already held).
    success : bool
        Every constraint of the plan holds at the end (a plan of no step is no success).
    trajectory : list of (Segment, ExecutedSegment-like dict)
        Executed motions, for :mod:`thirdhand.execute.record`.
    events : list of str
        What the simulated people and slips did, in order.
    final_poses : dict of str to ndarray (4, 4)
        Every part's world pose at the end.
    """

    steps: list[StepReport]
    success: bool
    trajectory: list[dict[str, Any]]
    events: list[str]
    final_poses: dict[str, FloatArray]

    @property
    def n_collisions(self) -> int:
        """Configurations in collision along every executed path (dense check)."""
        return sum(s.n_collisions for s in self.steps)
