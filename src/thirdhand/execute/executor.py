"""The plan executor: pick and place every step of the assembly plan on the simulated arm.

Per step ``action(parent, child, c)``: **pick** (plan to above the grasp, move
in along the tool's approach, attach, lift), **transport** (plan, part
attached, to the pre-place pose, the goal backed off along the part's
insertion axis), **place** (straight in, or along the learned primitive),
**detach**, **retreat** (straight back along the approach). The goal is the
parent's current world pose times the constraint pose; when inverse
kinematics or planning fails there, goals sampled inside the constraint's free
DOFs are tried (``sample_free_dofs``). Every search is bounded: a motion query
by ``plan_time_limit``, a whole step by ``step_time_limit``; a step that finds
no feasible grasp and goal ends with a failure report saying what was tried.

Contacts that are allowed on purpose (the report's simplifications): the
gripper with the part it is grasping (from the final approach to the end of the
retreat), and a part with its parent from the start of its insertion on (a leg
seated in its slot touches the seat).

Offline mode plans every step first (in a model of the world updated as if the
plan ran) and then executes the plan; online mode observes the world before
each step, detects which constraints already hold (:func:`detect_done`),
plans the next step not yet done and executes it, so a person may do steps and
a part that slipped out is put back.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from thirdhand import se3
from thirdhand.demonstration import Demonstration
from thirdhand.execute import grasps as grasp_mod
from thirdhand.execute.goals import (
    POS_TOL_M,
    ROT_TOL_RAD,
    constraint_holds,
    invert,
    sample_goals,
)
from thirdhand.execute.layout import Workcell
from thirdhand.execute.planner import plan_motion
from thirdhand.execute.primitive_motion import (
    find_primitive,
    follow_tool_path,
    linear_motion,
    primitive_tool_path,
)
from thirdhand.execute.robot import Robot
from thirdhand.execute.scene import GRIPPER, CollisionScene
from thirdhand.task.constraint import Constraint
from thirdhand.task.meshes import resolve_mesh
from thirdhand.task.model import TaskFile, TaskStep

FloatArray = NDArray[np.float64]


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
    pos_tol, rot_tol : float
        Tolerances of constraint detection, metres and radians.
    """

    sample_free_dofs: bool = True
    n_goal_samples: int = 16
    max_grasps: int = 24
    plan_time_limit: float = 5.0
    step_time_limit: float = 60.0
    approach_m: float = 0.08
    lift_m: float = 0.08
    insert_m: float = 0.05
    retreat_m: float = 0.08
    planner: str = "rrtconnect"
    use_primitives: bool = True
    pos_tol: float = POS_TOL_M
    rot_tol: float = ROT_TOL_RAD


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
    goal_dofs : list of float or None
        The goal's displacement inside the free DOFs (tx ty tz rx ry rz).
    tried : dict
        Counts of what the search tried (grasps, goals, IK and planning outcomes).
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
    goal_dofs: list[float] | None = None
    tried: dict[str, int] = field(default_factory=dict)


@dataclass
class StepPlan:
    """The motions of one step, or None-free failure details in the report."""

    report: StepReport
    segments: list[Segment] = field(default_factory=list)
    final_pose: FloatArray | None = None


def _trans(v: Sequence[float] | FloatArray) -> FloatArray:
    t = np.eye(4)
    t[:3, 3] = v
    return t


class SimWorld:
    """The simulated world: a collision scene plus every part's body pose.

    The scene holds mesh parts at their mesh frame (``T_world_body · mesh_to_body``);
    this class converts, so callers only see body poses (4, 4), world frame.
    """

    def __init__(
        self,
        robot: Robot,
        task: TaskFile,
        cell: Workcell,
        poses: Mapping[str, FloatArray],
        *,
        task_path: str | os.PathLike[str] | None = None,
        search: Sequence[str | os.PathLike[str]] = (),
    ) -> None:
        self.robot = robot
        self.scene = CollisionScene(robot)
        self.scene.add_table(height=cell.table_z, size=cell.table_size, center=cell.table_center)
        for name, pose, size in cell.fixtures:
            self.scene.add_box(name, se3.matrix_to_pose(pose), size)
            self.scene.allow(name, cell.base)
        self.offset: dict[str, FloatArray] = {}
        objs = {o.name: o for o in task.objects}
        for name, pose in poses.items():
            obj = objs[name]
            path = resolve_mesh(obj, task_path, search)
            if path is not None:
                m = obj.mesh_to_body.matrix() if obj.mesh_to_body is not None else np.eye(4)
                self.offset[name] = m
                scale = obj.scale if obj.scale is not None else 1.0
                self.scene.add_object(
                    name, se3.matrix_to_pose(pose @ m), mesh_path=path, scale=scale
                )
            elif obj.bbox_min is not None and obj.bbox_max is not None:
                lo, hi = np.asarray(obj.bbox_min), np.asarray(obj.bbox_max)
                self.offset[name] = np.eye(4)
                self.scene.add_object(
                    name,
                    se3.matrix_to_pose(pose),
                    size=np.maximum(hi - lo, 1e-3),
                    box_center=(lo + hi) / 2.0,
                )
            else:
                from thirdhand.execute.layout import LayoutError

                raise LayoutError(f"object {name!r}: no mesh and no bounding box to simulate")

    def pose(self, name: str, q: FloatArray | None = None) -> FloatArray:
        """``T_world_body`` of a part (a grasped one needs the arm's ``q``)."""
        t = se3.pose_to_matrix(*self.scene.object_pose(name, q))
        return np.asarray(t @ invert(self.offset[name]), dtype=np.float64)

    def set_pose(self, name: str, pose: FloatArray) -> None:
        """Move a free part to ``T_world_body``."""
        self.scene.set_object_pose(name, se3.matrix_to_pose(pose @ self.offset[name]))

    def poses(self) -> dict[str, FloatArray]:
        """Every free part's body pose."""
        return {n: self.pose(n) for n in self.offset if n != self.scene.attached}

    def apply(self, change: tuple[str, ...], q: FloatArray) -> None:
        """Apply one world change of a :class:`Segment` at configuration ``q``."""
        kind = change[0]
        if kind == "allow":
            self.scene.allow(change[1], change[2])
        elif kind == "disallow":
            self.scene.disallow(change[1], change[2])
        elif kind == "attach":
            self.scene.attach(change[1], q)
        elif kind == "detach":
            self.scene.detach(change[1], q)


def insertion_axis(task: TaskFile, constraint: Constraint) -> FloatArray:
    """Unit vector (3,), child frame: the direction the child backs out of its parent.

    Of the child's body axes (±x, ±y, ±z), the one along which the shortest move
    separates the child's bounding box from the parent's (the parent's box taken
    at the goal and bounded in the child frame) — a leg backs out of its slot
    along its own axis, the chair's back out of its groove along its length.
    """
    objs = {o.name: o for o in task.objects}

    def box(name: str) -> tuple[FloatArray, FloatArray]:
        o = objs[name]
        if o.bbox_min is None or o.bbox_max is None:
            return np.zeros(3), np.zeros(3)
        return np.asarray(o.bbox_min, dtype=np.float64), np.asarray(o.bbox_max, dtype=np.float64)

    c_lo, c_hi = box(constraint.child)
    p_lo, p_hi = box(constraint.parent)
    corners = np.array([[(p_hi if (i >> k) & 1 else p_lo)[k] for k in range(3)] for i in range(8)])
    t_cp = invert(constraint.pose.matrix())
    pc = corners @ t_cp[:3, :3].T + t_cp[:3, 3]
    lo, hi = pc.min(axis=0), pc.max(axis=0)
    moves = np.concatenate([hi - c_lo, c_hi - lo])  # +x +y +z, then -x -y -z
    k = int(np.argmin(moves))
    axis = np.zeros(3)
    axis[k % 3] = 1.0 if k < 3 else -1.0
    return axis


def detect_done(
    world: SimWorld,
    task: TaskFile,
    *,
    pos_tol: float = POS_TOL_M,
    rot_tol: float = ROT_TOL_RAD,
) -> dict[str, bool]:
    """Which constraints hold in the world now (constraint id → bool), from part poses only."""
    poses = world.poses()
    out = {}
    for c in task.constraints:
        if c.parent not in poses or c.child not in poses:
            out[c.id] = False
            continue
        rel = invert(poses[c.parent]) @ poses[c.child]
        out[c.id] = constraint_holds(rel, c, pos_tol=pos_tol, rot_tol=rot_tol)
    return out


def _candidate_grasps(
    task: TaskFile,
    constraint: Constraint,
    hints: Mapping[str, Sequence[grasp_mod.Grasp]],
    part_pose: FloatArray,
    max_grasps: int,
) -> list[grasp_mod.Grasp]:
    """Grasps worth trying on the part where it lies, best first.

    Grasps approaching from below are dropped (the hand would go through the
    table); the rest are ranked demonstrated first, then by how steeply they
    come from above plus how far they hold from where the part meets its parent.
    """
    obj = next(o for o in task.objects if o.name == constraint.child)
    cands = list(hints.get(constraint.child, ()))
    if obj.bbox_min is not None and obj.bbox_max is not None:
        cands += grasp_mod.shape_grasps(obj.bbox_min, obj.bbox_max)
    avoid = invert(constraint.pose.matrix())[:3, 3]
    rot = part_pose[:3, :3]
    scored: list[tuple[bool, float, int, grasp_mod.Grasp]] = []
    for g in cands:
        down = -float((rot @ g.pose[:3, 2])[2])
        if down < -0.1:
            continue
        far = float(np.linalg.norm(g.pose[:3, 3] - avoid))
        scored.append((g.source != "demo", -(down + 2.0 * far), len(scored), g))
    scored.sort(key=lambda s: s[:3])
    return [s[3] for s in scored[:max_grasps]]


class _Search:
    """The search of one step: grasps × goals, each stage bounded by the step's deadline.

    The scene is left as found: the child free at its current pose, nothing
    attached, the same pairs allowed.
    """

    def __init__(
        self,
        world: SimWorld,
        task: TaskFile,
        constraint: Constraint,
        options: ExecutionOptions,
        *,
        seed: int,
        deadline: float,
        primitive: Any | None,
        hints: Mapping[str, Sequence[grasp_mod.Grasp]],
    ) -> None:
        self.world = world
        self.scene = world.scene
        self.robot = world.robot
        self.task = task
        self.c = constraint
        self.opt = options
        self.seed = seed
        self.deadline = deadline
        self.primitive = primitive
        self.hints = hints
        self.tried = {"grasps": 0, "grasps_reachable": 0, "goals": 0, "place_reachable": 0,
                      "plans": 0, "plans_failed": 0}  # fmt: skip

    def left(self) -> float:
        return self.deadline - time.perf_counter()

    def _ik(self, target: FloatArray, q_seed: FloatArray, salt: int) -> FloatArray | None:
        return self.robot.ik(
            se3.matrix_to_pose(target),
            q_seed,
            seed=self.seed * 7919 + salt,
            n_restarts=24,
            accept=self.scene.is_valid,
        )

    def _line(self, q_a: FloatArray, t_b: FloatArray) -> FloatArray | None:
        path = linear_motion(self.robot, q_a, t_b)
        if path is None or not self.scene.check_path(path):
            return None
        return path

    def _plan(self, q_a: FloatArray, q_b: FloatArray) -> FloatArray | None:
        limit = min(self.opt.plan_time_limit, self.left())
        if limit <= 0.05:
            return None
        self.tried["plans"] += 1
        res = plan_motion(
            self.robot,
            self.scene,
            q_a,
            q_b,
            planner=self.opt.planner,
            time_limit=limit,
            seed=self.seed + self.tried["plans"],
        )
        if not res.success or res.path is None:
            self.tried["plans_failed"] += 1
            return None
        return res.path

    def _insertion(
        self, q_place: FloatArray, t_preplace_tool: FloatArray, parent_pose: FloatArray,
        goal: FloatArray, g: grasp_mod.Grasp,
    ) -> FloatArray | None:  # fmt: skip
        """Joint path pre-place → place (part attached): the primitive's, else a straight line."""
        name, parent = self.c.child, self.c.parent
        if self.primitive is not None:
            start = t_preplace_tool @ invert(g.pose)
            tools = primitive_tool_path(
                self.primitive, parent_world=parent_pose, child_start=start, child_goal=goal,
                grasp=g.pose,
            )  # fmt: skip
            q0 = self._ik(tools[0], q_place, 77)
            path = None if q0 is None else follow_tool_path(self.robot, q0, tools)
            if path is not None and self.scene.is_valid(path[0]):
                self.scene.allow(name, parent)
                ok = self.scene.check_path(path)
                self.scene.disallow(name, parent)
                if ok:
                    return path
        self.scene.allow(name, parent)
        try:
            back = self._line(q_place, t_preplace_tool)
        finally:
            self.scene.disallow(name, parent)
        # the pre-place pose itself must be clear of the parent
        if back is None or not self.scene.is_valid(back[-1]):
            return None
        return back[::-1].copy()

    def run(self, q_start: FloatArray, rng: np.random.Generator) -> StepPlan:
        c, opt, name, scene = self.c, self.opt, self.c.child, self.scene
        report = StepReport(0, c.parent, c.child, c.id, False, "")
        part_pose = self.world.pose(name)
        parent_pose = self.world.pose(c.parent)
        n_goals = opt.n_goal_samples if opt.sample_free_dofs else 1
        goals, dofs = sample_goals(parent_pose, c, n_goals, rng)
        axis = insertion_axis(self.task, c)
        grasps = _candidate_grasps(self.task, c, self.hints, part_pose, opt.max_grasps)
        for k, g in enumerate(grasps):
            if self.left() <= 0:
                report.status = f"step time limit ({opt.step_time_limit:g} s) reached"
                break
            self.tried["grasps"] += 1
            t_grasp = part_pose @ g.pose
            scene.allow(GRIPPER, name)
            try:
                q_grasp = self._ik(t_grasp, q_start, k)
                back = None if q_grasp is None else self._line(
                    q_grasp, t_grasp @ _trans([0.0, 0.0, -opt.approach_m])
                )  # fmt: skip
            finally:
                scene.disallow(GRIPPER, name)
            if q_grasp is None or back is None or not scene.is_valid(back[-1]):
                continue
            self.tried["grasps_reachable"] += 1
            found = self._with_grasp(q_grasp, g, goals, dofs, axis, parent_pose, part_pose)
            if found is None:
                continue
            j, lift, transport, insert, retreat = found
            approach = self._plan(q_start, back[-1])
            if approach is None:
                continue
            report.success = True
            report.status = "planned"
            report.grasp = g.label
            report.goal_dofs = [float(v) for v in dofs[j]]
            report.tried = dict(self.tried)
            segs = [
                Segment("approach", approach),
                Segment("grasp", back[::-1].copy(), before=[("allow", GRIPPER, name)],
                        after=[("attach", name)]),
                Segment("lift", lift),
                Segment("transport", transport),
                Segment("insert", insert, before=[("allow", name, c.parent)],
                        after=[("detach", name)]),
                Segment("retreat", retreat, after=[("disallow", GRIPPER, name)]),
            ]  # fmt: skip
            return StepPlan(report, segs, goals[j])
        report.tried = dict(self.tried)
        if not report.status:
            t = self.tried
            report.status = (
                f"no reachable goal: {t['grasps']} grasps tried ({t['grasps_reachable']} "
                f"reachable), {t['goals']} goal poses tried ({t['place_reachable']} reachable, "
                f"free DOFs {'sampled' if opt.sample_free_dofs else 'not sampled'}), "
                f"{t['plans_failed']} of {t['plans']} planning queries failed"
            )
        return StepPlan(report)

    def _with_grasp(
        self, q_grasp: FloatArray, g: grasp_mod.Grasp, goals: FloatArray, dofs: FloatArray,
        axis: FloatArray, parent_pose: FloatArray, part_pose: FloatArray,
    ) -> tuple[int, FloatArray, FloatArray, FloatArray, FloatArray] | None:  # fmt: skip
        """For one grasp: the first goal with lift, insertion, retreat and transport feasible."""
        c, opt, name, scene = self.c, self.opt, self.c.child, self.scene
        t_grasp = self.robot.tool_transforms(q_grasp[None])[0]
        scene.attach(name, q_grasp)
        try:
            lift = self._line(q_grasp, _trans([0.0, 0.0, opt.lift_m]) @ t_grasp)
            if lift is None:
                return None
            q_lift = lift[-1]
            for j, goal in enumerate(goals):
                if self.left() <= 0:
                    return None
                self.tried["goals"] += 1
                t_place = goal @ g.pose
                scene.allow(name, c.parent)
                q_place = self._ik(t_place, q_lift, 1000 + j)
                scene.disallow(name, c.parent)
                if q_place is None:
                    continue
                self.tried["place_reachable"] += 1
                t_pre = goal @ _trans(opt.insert_m * axis) @ g.pose
                insert = self._insertion(q_place, t_pre, parent_pose, goal, g)
                if insert is None:
                    continue
                retreat = self._retreat(q_grasp, q_place, t_place, goal)
                if retreat is None:
                    continue
                transport = self._plan(q_lift, insert[0])
                if transport is None:
                    continue
                return j, lift, transport, insert, retreat
            return None
        finally:
            scene.detach(name, q_grasp)

    def _retreat(
        self, q_grasp: FloatArray, q_place: FloatArray, t_place: FloatArray, goal: FloatArray
    ) -> FloatArray | None:
        """Straight back from the placed part, checked with the part left at its goal."""
        name, parent, scene = self.c.child, self.c.parent, self.scene
        scene.detach(name, q_grasp)
        part_pose = self.world.pose(name)
        self.world.set_pose(name, goal)
        scene.allow(name, parent)
        scene.allow(GRIPPER, name)
        try:
            return self._line(q_place, t_place @ _trans([0.0, 0.0, -self.opt.retreat_m]))
        finally:
            scene.disallow(GRIPPER, name)
            scene.disallow(name, parent)
            self.world.set_pose(name, part_pose)
            scene.attach(name, q_grasp)


#: A world event of online mode: called with the world between two robot steps.
WorldEvent = Callable[[SimWorld], str]


@dataclass
class ExecutionResult:
    """Outcome of a run.

    Attributes
    ----------
    steps : list of StepReport
        One per attempted step, in execution order (online: also the steps a
        person did or that already held).
    success : bool
        Every constraint of the plan holds at the end.
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


class Executor:
    """Runs a task's plan on the simulated arm, offline or online.

    Parameters
    ----------
    robot : Robot
    task : TaskFile
    cell : Workcell
    start : dict of str to ndarray (4, 4)
        Every part's start pose (:func:`thirdhand.execute.layout.start_layout`).
    options : ExecutionOptions, optional
    task_path, search
        Where to find meshes.
    demo : Demonstration, optional
        A demonstration of the task: grasps are taken from its fingers.
    """

    def __init__(
        self,
        robot: Robot,
        task: TaskFile,
        cell: Workcell,
        start: Mapping[str, FloatArray],
        options: ExecutionOptions | None = None,
        *,
        task_path: str | os.PathLike[str] | None = None,
        search: Sequence[str | os.PathLike[str]] = (),
        demo: Demonstration | None = None,
    ) -> None:
        self.robot = robot
        self.task = task
        self.cell = cell
        self.start = {k: np.array(v, dtype=np.float64) for k, v in start.items()}
        self.options = options or ExecutionOptions()
        self._where = {"task_path": task_path, "search": tuple(search)}
        self.constraints = {c.id: c for c in task.constraints}
        self.hints: dict[str, list[grasp_mod.Grasp]] = {}
        if demo is not None:
            for c in task.constraints:
                if c.time is None:
                    continue
                obj = next(o for o in task.objects if o.name == c.child)
                box = None
                if obj.bbox_min is not None and obj.bbox_max is not None:
                    box = (np.asarray(obj.bbox_min), np.asarray(obj.bbox_max))
                self.hints[c.child] = grasp_mod.demo_grasps(demo, c.child, c.time, bbox=box)
        self.primitives = task.stages.get("primitives") if self.options.use_primitives else None

    def new_world(self, poses: Mapping[str, FloatArray] | None = None) -> SimWorld:
        """A world with the parts at ``poses`` (the start layout by default)."""
        return SimWorld(
            self.robot, self.task, self.cell, self.start if poses is None else poses,
            **self._where,  # type: ignore[arg-type]
        )  # fmt: skip

    def _steps(self) -> list[tuple[int, TaskStep, Constraint]]:
        out = []
        for i, s in enumerate(self.task.plan):
            cid = s.constraint or next(
                (
                    c.id
                    for c in self.task.constraints
                    if c.parent == s.parent and c.child == s.child
                ),
                None,
            )
            if cid is not None:
                out.append((i, s, self.constraints[cid]))
        return out

    def plan_step(
        self, world: SimWorld, index: int, constraint: Constraint, q_start: FloatArray, seed: int
    ) -> StepPlan:
        """Search and plan one step in ``world`` (left unchanged) from ``q_start``."""
        t0 = time.perf_counter()
        prim = find_primitive(self.primitives, constraint.parent, constraint.child)
        search = _Search(
            world, self.task, constraint, self.options, seed=seed,
            deadline=t0 + self.options.step_time_limit, primitive=prim, hints=self.hints,
        )  # fmt: skip
        plan = search.run(q_start, np.random.default_rng([seed, index]))
        plan.report.index = index
        plan.report.planning_time_s = time.perf_counter() - t0
        return plan

    def _execute(
        self, world: SimWorld, plan: StepPlan, q: FloatArray, trajectory: list[dict[str, Any]]
    ) -> FloatArray:
        """Run a step's segments in ``world``, densely checking each; returns the final ``q``."""
        rep = plan.report
        for seg in plan.segments:
            for ch in seg.before:
                world.apply(ch, seg.path[0])
            dense = world.scene.interpolate(seg.path)
            ok = world.scene.valid_mask(dense)
            rep.n_dense += int(dense.shape[0])
            rep.n_collisions += int(np.count_nonzero(~ok))
            rep.joint_length_rad += float(np.sum(np.linalg.norm(np.diff(seg.path, axis=0), axis=1)))
            pos, _ = self.robot.fk_batch(dense)
            rep.tool_length_m += float(np.sum(np.linalg.norm(np.diff(pos, axis=0), axis=1)))
            attached = world.scene.attached
            trajectory.append(
                {
                    "step": rep.index,
                    "segment": seg.name,
                    "path": seg.path.copy(),
                    "attached": attached,
                    "t_tool_part": None if attached is None else invert(
                        self.robot.tool_transforms(seg.path[:1])[0]
                    ) @ world.pose(attached, seg.path[0]),
                    "static": world.poses(),
                }
            )  # fmt: skip
            for ch in seg.after:
                world.apply(ch, seg.path[-1])
            q = seg.path[-1]
        return q

    def _go_home(
        self, world: SimWorld, q: FloatArray, seed: int, trajectory: list[dict[str, Any]]
    ) -> FloatArray:
        """Plan and execute a motion back to the home configuration; the final ``q``."""
        if np.allclose(q, self.robot.home):
            return q
        res = plan_motion(
            self.robot, world.scene, q, self.robot.home, planner=self.options.planner,
            time_limit=self.options.plan_time_limit, seed=seed,
        )  # fmt: skip
        if res.success and res.path is not None:
            rep = StepReport(-1, "", "", "", True, "home")
            return self._execute(world, StepPlan(rep, [Segment("home", res.path)]), q, trajectory)
        return q

    def run_offline(self, seed: int = 0) -> ExecutionResult:
        """Plan every step first (in a model of the world), then execute the plan."""
        model = self.new_world()
        q = self.robot.home
        plans: list[StepPlan] = []
        for index, _, c in self._steps():
            plan = self.plan_step(model, index, c, q, seed)
            plans.append(plan)
            if plan.report.success:
                # advance the model as if the step ran
                q = self._execute(model, plan, q, [])
        world = self.new_world()
        q = self.robot.home
        trajectory: list[dict[str, Any]] = []
        reports = []
        for plan in plans:
            rep = plan.report
            rep.n_dense = rep.n_collisions = 0
            rep.joint_length_rad = rep.tool_length_m = 0.0
            if rep.success:
                q = self._execute(world, plan, q, trajectory)
                rep.status = "done"
            reports.append(rep)
        self._go_home(world, q, seed, trajectory)
        return self._result(world, reports, trajectory, [])

    def run_online(
        self, seed: int = 0, events: Mapping[int, Sequence[WorldEvent]] | None = None
    ) -> ExecutionResult:
        """Observe, detect what holds, plan and execute the next step; repeat.

        Parameters
        ----------
        seed : int
        events : dict of int to list of callables, optional
            ``events[k]`` run after the robot's ``k``-th executed step (0: before the
            first); each returns a description (a person doing a step, a part slipping).
        """
        world = self.new_world()
        q = self.robot.home
        trajectory: list[dict[str, Any]] = []
        reports: list[StepReport] = []
        log: list[str] = []
        failed: set[str] = set()
        n_done = 0
        pending_events = {k: list(v) for k, v in (events or {}).items()}
        steps = self._steps()
        for _ in range(4 * len(steps) + 4):
            for ev in pending_events.pop(n_done, []):
                log.append(ev(world))
            holds = detect_done(world, self.task, pos_tol=self.options.pos_tol,
                                rot_tol=self.options.rot_tol)  # fmt: skip
            self._sync_contacts(world, holds)
            for index, _, c in steps:
                if holds[c.id] and not any(r.constraint == c.id for r in reports):
                    by = "done by person" if any(c.child in e for e in log) else "already holds"
                    reports.append(StepReport(index, c.parent, c.child, c.id, True, by))
            todo = [
                (i, c) for i, _, c in steps
                if not holds[c.id] and c.id not in failed
                and self._parent_ready(c, holds)
            ]  # fmt: skip
            if not todo:
                if not pending_events:
                    break
                n_done = min(pending_events)
                continue
            index, c = todo[0]
            plan = self.plan_step(world, index, c, q, seed + n_done)
            reports = [r for r in reports if r.constraint != c.id]
            reports.append(plan.report)
            if not plan.report.success:
                failed.add(c.id)
                continue
            q = self._execute(world, plan, q, trajectory)
            plan.report.status = "done"
            n_done += 1
            # leave the shared workspace to the person before looking again
            q = self._go_home(world, q, seed, trajectory)
        self._go_home(world, q, seed, trajectory)
        order = {c.id: k for k, (_, _, c) in enumerate(steps)}
        reports.sort(key=lambda r: order.get(r.constraint, -1))
        return self._result(world, reports, trajectory, log)

    def _parent_ready(self, c: Constraint, holds: Mapping[str, bool]) -> bool:
        """The parent is the base, or its own constraint holds."""
        if c.parent == self.cell.base:
            return True
        cid = next((p.id for p in self.task.constraints if p.child == c.parent), None)
        return cid is None or holds[cid]

    def _sync_contacts(self, world: SimWorld, holds: Mapping[str, bool]) -> None:
        """A part touches its parent exactly while its constraint holds."""
        for c in self.task.constraints:
            if holds[c.id]:
                world.scene.allow(c.child, c.parent)
            else:
                world.scene.disallow(c.child, c.parent)

    def _result(
        self, world: SimWorld, reports: list[StepReport], trajectory: list[dict[str, Any]],
        log: list[str],
    ) -> ExecutionResult:  # fmt: skip
        holds = detect_done(world, self.task, pos_tol=self.options.pos_tol,
                            rot_tol=self.options.rot_tol)  # fmt: skip
        ok = all(holds[c.id] for _, _, c in self._steps())
        return ExecutionResult(reports, ok, trajectory, log, world.poses())


def person_does(task: TaskFile, constraint_id: str, seed: int = 0) -> WorldEvent:
    """A world event: a simulated person puts the constraint's child at its goal.

    The goal is drawn inside the constraint's free DOFs (a person turns a leg
    however it comes).
    """
    c = next(c for c in task.constraints if c.id == constraint_id)

    def event(world: SimWorld) -> str:
        parent = world.pose(c.parent)
        goals, _ = sample_goals(parent, c, 2, seed, include_nominal=False)
        world.set_pose(c.child, goals[0])
        world.scene.allow(c.child, c.parent)
        return f"person: {c.child} onto {c.parent} ({c.id})"

    return event


def slip(task: TaskFile, constraint_id: str, distance: float = 0.04) -> WorldEvent:
    """A world event: the constraint's child slips ``distance`` metres out of its parent."""
    c = next(c for c in task.constraints if c.id == constraint_id)
    axis = insertion_axis(task, c)

    def event(world: SimWorld) -> str:
        moved: FloatArray = world.pose(c.child) @ _trans(distance * axis)
        world.set_pose(c.child, moved)
        world.scene.disallow(c.child, c.parent)
        return f"slip: {c.child} out of {c.parent} by {distance:g} m ({c.id})"

    return event
