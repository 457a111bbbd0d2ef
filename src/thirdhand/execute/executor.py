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

The modules doing the work: :mod:`~thirdhand.execute.world` (the simulated
world, detection, world events), :mod:`~thirdhand.execute.step_search` (the
search of one step), :mod:`~thirdhand.execute.step_plan` (options, segments,
reports).

Offline mode plans every step first (in a model of the world updated as if the
plan ran) and then executes the plan; online mode observes the world before
each step, detects which constraints already hold (:func:`detect_done`),
plans the next step not yet done and executes it, so a person may do steps and
a part that slipped out is put back.
"""

from __future__ import annotations

import os
import time
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from thirdhand.arrays import FloatArray
from thirdhand.demonstration import Demonstration
from thirdhand.execute import grasps as grasp_mod
from thirdhand.execute.goals import invert
from thirdhand.execute.layout import (
    ASSEMBLY_XY,
    Workcell,
    make_workcell,
    part_vertices,
    start_layout,
)
from thirdhand.execute.planner import plan_motion
from thirdhand.execute.primitive_motion import find_primitive
from thirdhand.execute.robot import Robot
from thirdhand.execute.scene import SceneError
from thirdhand.execute.step_order import (
    identical_parts,
    plan_binds_order,
    predecessors,
    slot_difficulty,
)
from thirdhand.execute.step_plan import (
    ExecutionOptions,
    ExecutionResult,
    Segment,
    StepPlan,
    StepReport,
)
from thirdhand.execute.step_search import StepSearch
from thirdhand.execute.timing import time_parametrize
from thirdhand.execute.world import (
    SimWorld,
    WorldEvent,
    detect_done,
    insertion_axis,
    person_does,
    slip,
)
from thirdhand.task.constraint import Constraint
from thirdhand.task.model import TaskFile, TaskStep

#: How :meth:`Executor.for_task` stands the base (``ExecutionOptions.placement``).
PLACEMENTS = ("auto", "geometry", "reach")

#: ``start_grasps`` used when the automatic placement falls back to reach
#: (research/notes/execution.md).
AUTO_START_GRASPS = 4


__all__ = [
    "ExecutionOptions",
    "ExecutionResult",
    "Executor",
    "Segment",
    "SimWorld",
    "StepPlan",
    "StepReport",
    "WorldEvent",
    "detect_done",
    "insertion_axis",
    "person_does",
    "slip",
]


def task_defaults(
    task: TaskFile,
    robot: str | None = None,
    assembly_xy: tuple[float, float] | None = None,
) -> tuple[str, tuple[float, float] | None]:
    """The robot and assembly spot to use: what was asked, else the task's, else the default.

    ``stages.execution`` of the task file (:class:`~thirdhand.task.stages.ExecutionDefaults`)
    says what a task is executed with when the command line and ``--config`` say nothing:
    an explicit ``robot`` or ``assembly_xy`` wins, then the task's, then Panda and the
    robot's own assembly spot (``None``).
    """
    block = task.stages.execution
    if robot is None:
        robot = (block.robot if block is not None else None) or "panda"
    if assembly_xy is None and block is not None:
        assembly_xy = block.assembly_xy
    return robot, assembly_xy


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
        A demonstration of the task: grasps are taken from its fingers. Without
        it, the grasps the task recorded (``stages.grasps``) are used.
    """

    @classmethod
    def for_task(
        cls,
        task: TaskFile,
        robot_name: str = "panda",
        *,
        seed: int = 0,
        options: ExecutionOptions | None = None,
        task_path: str | os.PathLike[str] | None = None,
        search: Sequence[str | os.PathLike[str]] = (),
        demo: Demonstration | None = None,
        assembly_xy: tuple[float, float] | None = None,
    ) -> Executor:
        """The work cell of ``task`` for ``robot_name``, the arm mounted in it, a seeded start.

        Parameters
        ----------
        task : TaskFile
        robot_name : {"panda", "baxter"}
        seed : int
            Seed of the start layout.
        options, task_path, search, demo
            As for the constructor.
        assembly_xy : (float, float), optional
            World x, y where the assembly is built, metres (the robot's default otherwise).
        """
        cell = make_workcell(
            task, robot_name, assembly_xy=assembly_xy, task_path=task_path, search=search
        )
        arm = Robot.load(
            robot_name, base_pose=(cell.robot_base[:3, 3], np.array([0.0, 0.0, 0.0, 1.0]))
        )
        opts = options or ExecutionOptions()
        if opts.placement not in PLACEMENTS:
            raise SceneError(
                f"placement {opts.placement!r}: expected one of {', '.join(PLACEMENTS)}"
            )
        notes: list[str] = []
        start_grasps = opts.start_grasps
        if opts.placement in ("auto", "reach"):
            from thirdhand.execute.placement import choose_placement, score_placement

            by_reach = opts.placement == "reach"
            if not by_reach:
                score = score_placement(
                    arm, task, cell, seed=seed, task_path=task_path, search=search
                )
                short = sorted(c for c, (a, _) in score.reached.items() if a == 0)
                if short:
                    by_reach = True
                    start_grasps = start_grasps or AUTO_START_GRASPS
                    notes.append(
                        f"placement: {', '.join(short)} reached no goal at the geometric "
                        f"placement; stood by reach, start spots within reach "
                        f"(start_grasps {start_grasps})"
                    )
            if by_reach:
                xy = ASSEMBLY_XY[robot_name] if assembly_xy is None else assembly_xy
                cell, _ = choose_placement(
                    arm, task, cell, xy, seed=seed, task_path=task_path, search=search
                )
        accept = None
        if start_grasps > 0:
            from thirdhand.execute.placement import reach_check

            accept = reach_check(arm, task, cell, start_grasps, seed=seed)
        start = start_layout(
            task, cell, seed, task_path=task_path, search=search, accept=accept,
            stand_plates=opts.fit_grasps_to_fingers,
        )  # fmt: skip
        ex = cls(arm, task, cell, start, options, task_path=task_path, search=search, demo=demo)
        ex.notes = notes
        return ex

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
        from thirdhand.execute.collision_check import warm_up

        warm_up()  # compile the kernels now, not inside a step's time limit
        self.robot = robot
        self.task = task
        self.cell = cell
        #: How the work cell was made (said first in the result's events).
        self.notes: list[str] = []
        self.start = {k: np.array(v, dtype=np.float64) for k, v in start.items()}
        self.options = options or ExecutionOptions()
        self._where = {"task_path": task_path, "search": tuple(search)}
        self.constraints = {c.id: c for c in task.constraints}
        self.hints: dict[str, list[grasp_mod.Grasp]] = {}
        recorded = task.stages.grasps
        for c in task.constraints:
            if demo is None and recorded is None:
                break
            obj = next(o for o in task.objects if o.name == c.child)
            box = None
            if obj.bbox_min is not None and obj.bbox_max is not None:
                box = (np.asarray(obj.bbox_min), np.asarray(obj.bbox_max))
            if demo is not None:  # a recording given: its fingers, as now
                if c.time is None:
                    continue
                found = grasp_mod.demo_grasps(demo, c.child, c.time, bbox=box)
            else:  # the grasps the task recorded when it was learned
                assert recorded is not None
                found = [
                    grasp_mod.Grasp(g.pose.matrix(), "demo", g.hand)
                    for g in recorded.constraints.get(c.id, [])
                ]
                if not found:
                    continue
            if box is not None:
                found = grasp_mod.rod_turns(grasp_mod.square_to_box(found), *box)
                if self.options.fit_grasps_to_fingers:
                    found = grasp_mod.within_fingers(found, *box)
            self.hints[c.child] = found
        self.primitives = task.stages.primitives if self.options.use_primitives else None
        #: Constraint id → the part put into its slot (offline; identical parts swap).
        self.bind: dict[str, str] = {}
        self._verts: dict[str, FloatArray] | None = None

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
        self, world: SimWorld, index: int, constraint: Constraint, q_start: FloatArray, seed: int,
        part: str | None = None,
    ) -> StepPlan:  # fmt: skip
        """Search and plan one step in ``world`` (left unchanged) from ``q_start``.

        ``part`` puts that part (one identical to the constraint's child,
        :func:`~thirdhand.execute.step_order.identical_parts`) into the slot instead;
        the slot's learned primitive and demonstrated grasps are used for it.
        """
        t0 = time.perf_counter()
        prim = find_primitive(self.primitives, constraint.parent, constraint.child)
        hints: Mapping[str, Sequence[grasp_mod.Grasp]] = self.hints
        if part is not None and part != constraint.child:
            hints = {**self.hints, part: self.hints.get(constraint.child, [])}
            constraint = constraint.model_copy(update={"child": part})
        search = StepSearch(
            world, self.task, constraint, self.options, seed=seed,
            deadline=t0 + self.options.step_time_limit, primitive=prim, hints=hints,
        )  # fmt: skip
        plan = search.run(q_start, np.random.default_rng([seed, index]))
        plan.report.index = index
        if (
            not plan.report.success
            and self.options.regrasp
            and not plan.report.status.startswith("step time limit")
        ):
            plan = self._regrasp(world, index, constraint, q_start, seed, plan, search.reached,
                                 prim, hints)  # fmt: skip
            plan.report.index = index
        plan.report.planning_time_s = time.perf_counter() - t0
        return plan

    def _regrasp(
        self, world: SimWorld, index: int, constraint: Constraint, q_start: FloatArray,
        seed: int, plain: StepPlan, reached: Sequence[grasp_mod.Grasp], prim: Any,
        hints: Mapping[str, Sequence[grasp_mod.Grasp]],
    ) -> StepPlan:  # fmt: skip
        """The step through an intermediate placement (:mod:`~thirdhand.execute.regrasp`).

        Returns the joined plan, or ``plain`` with why no regrasp was found added to
        its status.
        """
        from thirdhand.execute.regrasp import plan_regrasp

        def search(
            w: SimWorld, c: Constraint, q: FloatArray, deadline: float,
            put_down: FloatArray | None, grasps: Sequence[grasp_mod.Grasp],
            first_goals: tuple[FloatArray, FloatArray] | None,
        ) -> StepPlan:  # fmt: skip
            s = StepSearch(
                w, self.task, c, self.options, seed=seed + 1, deadline=deadline,
                primitive=prim if put_down is None else None, hints=hints, put_down=put_down,
                grasps=grasps, first_goals=first_goals,
            )  # fmt: skip
            return s.run(q, np.random.default_rng([seed, index, 1]))

        plan, why = plan_regrasp(
            world, self.task, constraint, self.options, plain, reached, search,
            verts=self._vertices(), cell=self.cell, hints=hints, q_start=q_start, seed=seed,
        )  # fmt: skip
        if plan is None:
            plain.report.status += f"; {why}"
            return plain
        return plan

    def _vertices(self) -> dict[str, FloatArray]:
        """Body-frame vertices (n, 3) of every part laid out, metres (computed once)."""
        if self._verts is None:
            objs = {o.name: o for o in self.task.objects}
            self._verts = {
                n: part_vertices(objs[n], **self._where)  # type: ignore[arg-type]
                for n in self.start
            }
        return self._verts

    def _execute(
        self, world: SimWorld, plan: StepPlan, q: FloatArray, trajectory: list[dict[str, Any]]
    ) -> FloatArray:
        """Run a step's segments in ``world``, densely checking each; returns the final ``q``."""
        rep = plan.report
        for seg in plan.segments:
            for ch in seg.before:
                world.apply(ch, seg.path[0])
            dense = world.scene.interpolate(seg.path)
            ok = world.scene.valid_mask(dense, exact=True)  # coal alone: the independent verdict
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
                    "motion": rep.motions.get(seg.name, "planner"),
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
        """Plan every step first (in a model of the world), then execute the plan.

        The order and the parts are chosen while planning
        (:mod:`~thirdhand.execute.step_order`): among the steps allowed next, the
        hardest slot first, each slot filled by the first of its interchangeable
        parts whose step succeeds; when a step fails, it is moved to the front
        (as early as its predecessors allow) and the plan is made again, at most
        once per step. Every re-planning is said in the result's events.
        """
        steps = self._steps()
        pre = predecessors(steps, use_plan=plan_binds_order(self.task, self.options.order))
        first: list[str] = []
        log: list[str] = []
        cache: dict[tuple[tuple[str, str], ...], StepPlan] = {}
        while True:
            plans, failed, done = self._plan_in_order(steps, pre, first, seed, cache)
            if failed is None or not self.options.reorder or failed in first:
                break
            # was anything it need not follow planned before it?
            ahead = [cid for cid in done if cid not in pre[failed]]
            if not ahead:
                break
            log.append(
                f"re-plan: {failed} failed after {', '.join(ahead)}; planned again with "
                f"{failed} first"
            )
            first.insert(0, failed)
        self.bind = {p.report.constraint: p.report.child for p in plans if p.report.success}
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
        return self._result(world, reports, trajectory, log)

    def _plan_in_order(
        self, steps: Sequence[tuple[int, TaskStep, Constraint]], pre: Mapping[str, set[str]],
        first: Sequence[str], seed: int,
        cache: dict[tuple[tuple[str, str], ...], StepPlan],
    ) -> tuple[list[StepPlan], str | None, list[str]]:  # fmt: skip
        """Plan every step in a model of the world, choosing the order and the parts.

        Returns the plans (in execution order, failed ones included), the first
        step that failed (None if none did) and the steps planned before it.
        ``cache`` holds the plans made, keyed by the (constraint, part) steps before
        them and their own.
        """
        model = self.new_world()
        q = self.robot.home
        same = identical_parts(self.task)
        by_id = {c.id: (i, c) for i, _, c in steps}
        free = {c.child for _, _, c in steps}
        done: list[str] = []
        key: tuple[tuple[str, str], ...] = ()
        plans: list[StepPlan] = []
        failed: set[str] = set()
        first_failed: str | None = None
        done_before: list[str] = []
        while len(done) + len(failed) < len(steps):
            ready = [
                c for _, _, c in steps
                if c.id not in failed and c.id not in done and pre[c.id] <= set(done)
            ]  # fmt: skip
            if not ready:
                for _, _, c in steps:  # their predecessors failed
                    if c.id not in failed and c.id not in done:
                        failed.add(c.id)
                        miss = sorted(pre[c.id] - set(done))
                        plans.append(StepPlan(StepReport(
                            by_id[c.id][0], c.parent, c.child, c.id, False,
                            f"not attempted: needs {', '.join(miss)} first, which failed",
                        )))  # fmt: skip
                break
            c = min(ready, key=lambda c: self._rank(model, c, first))
            index = by_id[c.id][0]
            parts = [p for p in same.get(c.child, [c.child]) if p in free]
            parts.sort(key=lambda p: (p != c.child, self._distance(model, p, c)))
            plan = None
            for part in parts[: max(1, self.options.max_parts)]:
                # the model is in the state the steps of ``key`` leave: a plan made
                # in an earlier round after the same steps holds here too
                plan = cache.get((*key, (c.id, part)))
                if plan is None:
                    plan = self.plan_step(model, index, c, q, seed, part=part)
                    cache[(*key, (c.id, part))] = plan
                if plan.report.success:
                    q = self._execute(model, plan, q, [])  # advance the model as if it ran
                    break
                t = plan.report.tried
                if t.grasps_reachable > 0 and t.place_reachable == 0:
                    break  # the goal is out of reach with every grasp: so for any twin part
            assert plan is not None
            plans.append(plan)
            if plan.report.success:
                done.append(c.id)
                free.discard(plan.report.child)
                key = (*key, (c.id, plan.report.child))
            else:
                failed.add(c.id)
                if first_failed is None:
                    first_failed, done_before = c.id, list(done)
        return plans, first_failed, done_before

    def _rank(self, world: SimWorld, c: Constraint, first: Sequence[str]) -> tuple[int, float]:
        """Sort key of a step that may run next: moved to the front first, then hardest first."""
        pos = first.index(c.id) if c.id in first else len(first)
        goal = world.pose(c.parent) @ c.pose.matrix()
        return pos, -slot_difficulty(goal, self.cell.arm_xy, self.cell.table_z)

    @staticmethod
    def _distance(world: SimWorld, part: str, c: Constraint) -> float:
        """How far ``part`` lies from the slot of ``c``, metres."""
        goal = world.pose(c.parent) @ c.pose.matrix()
        return float(np.linalg.norm(world.pose(part)[:3, 3] - goal[:3, 3]))

    def run_online(
        self, seed: int = 0, events: Mapping[int, Sequence[WorldEvent]] | None = None
    ) -> ExecutionResult:
        """Observe, detect what holds, plan and execute the next step; repeat.

        With a perception block in the task (``stages.perception``, see
        :mod:`thirdhand.perception.events`) and ``options.use_perception``, the part
        a person points at (:func:`~thirdhand.perception.events.focus_object` on the
        run's clock: seconds of executed motion and waiting since the start) is
        theirs: its step is left to them while the pointing lasts (and
        ``lookback`` seconds after), the robot does another one meanwhile or waits
        (``options.wait_s`` at a time); once the claim lapses, a step the person
        did not do is the robot's again.

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
        clock = 0.0
        pointed: set[str] = set()
        for _ in range(4 * len(steps) + 4 + int(20.0 / max(self.options.wait_s, 0.1))):
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
            theirs = self._pointed_at(clock)
            if theirs is not None and any(c.child == theirs for _, c in todo):
                if theirs not in pointed:
                    pointed.add(theirs)
                    log.append(f"pointing: the person points at {theirs} (t = {clock:.1f} s): "
                               "its step is theirs")  # fmt: skip
                mine = [(i, c) for i, c in todo if c.child != theirs]
                if not mine:  # only the person's step is left: wait for them
                    if pending_events:
                        n_done = min(pending_events)
                    else:
                        clock += self.options.wait_s
                        log.append(f"wait: {self.options.wait_s:g} s for the person ({theirs})")
                    continue
                todo = mine
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
            n_before = len(trajectory)
            q = self._execute(world, plan, q, trajectory)
            plan.report.status = "done"
            n_done += 1
            # leave the shared workspace to the person before looking again
            q = self._go_home(world, q, seed, trajectory)
            clock += self._duration(trajectory[n_before:])
        self._go_home(world, q, seed, trajectory)
        order = {c.id: k for k, (_, _, c) in enumerate(steps)}
        reports.sort(key=lambda r: order.get(r.constraint, -1))
        return self._result(world, reports, trajectory, log)

    def _pointed_at(self, clock: float) -> str | None:
        """The part the person singles out at ``clock`` (run's seconds), or None."""
        block = self.task.stages.perception if self.options.use_perception else None
        if not block:
            return None
        from thirdhand.perception.events import focus_object

        return focus_object(block, clock, lookback=self.options.pointing_lookback_s)

    def _duration(self, segments: Sequence[dict[str, Any]]) -> float:
        """Seconds the executed segments take (time-parametrised as when recorded)."""
        return float(
            sum(
                time_parametrize(
                    seg["path"], self.robot.velocity_limits, self.robot.acceleration_limits
                ).duration_s
                for seg in segments
            )
        )

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
        holds = detect_done(world, self.bound_task(), pos_tol=self.options.pos_tol,
                            rot_tol=self.options.rot_tol)  # fmt: skip
        steps = self._steps()
        ok = bool(steps) and all(holds[c.id] for _, _, c in steps)  # nothing done is no success
        return ExecutionResult(reports, ok, trajectory, [*self.notes, *log], world.poses())

    def bound_task(self) -> TaskFile:
        """The task with each slot's child the part put into it (:attr:`bind`)."""
        if all(self.bind.get(c.id, c.child) == c.child for c in self.task.constraints):
            return self.task
        cons = [c.model_copy(update={"child": self.bind.get(c.id, c.child)})
                for c in self.task.constraints]  # fmt: skip
        return self.task.model_copy(update={"constraints": cons})
