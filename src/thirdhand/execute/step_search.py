"""The search of one plan step: grasps × goals, every stage bounded by the step's deadline.

For each grasp (best ranked first, :func:`candidate_grasps`): reach it (IK, a
straight move in along the tool's approach), lift the part, and for each goal
(the nominal one first, then goals sampled inside the free DOFs) find the place
configuration, the insertion (the learned primitive or a straight line), the
retreat and the transport; finally the approach from the start configuration.
The first combination that works becomes the step's :class:`StepPlan`; when
none does, the report says what was tried.
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from thirdhand.arrays import FloatArray
from thirdhand.execute import grasps as grasp_mod
from thirdhand.execute.goals import invert, sample_goals
from thirdhand.execute.planner import plan_motion
from thirdhand.execute.primitive_motion import (
    MAX_JUMP_RAD,
    follow_tool_path,
    linear_motion,
    primitive_place_path,
)
from thirdhand.execute.robot import Robot
from thirdhand.execute.scene import GRIPPER, CollisionScene
from thirdhand.execute.step_plan import (
    ExecutionOptions,
    SearchCounts,
    Segment,
    StepPlan,
    StepReport,
)
from thirdhand.execute.world import SimWorld, insertion_axis
from thirdhand.execute.world import trans as _trans
from thirdhand.task.constraint import Constraint
from thirdhand.task.model import TaskFile

#: Steps in which a wide plate's grasps are ranked by their distance from its centre of
#: mass, metres (:func:`candidate_grasps`).
LEVER_STEP_M = 0.05
#: A transport's joint path (n, dof) and how it was made (``straight`` or ``planner``).
Carried = tuple[FloatArray, str]

#: IK targets solved together (grasps, goals): 4 × 25 starts cost about one target's time.
IK_BLOCK = 4


def first_valid_ik(
    robot: Robot,
    scene: CollisionScene,
    targets: FloatArray,
    q_seed: FloatArray,
    *,
    seed: int,
    n_restarts: int = 24,
    why: dict[str, Any] | None = None,
) -> list[FloatArray | None]:
    """For each target, the collision-free IK solution nearest ``q_seed``, all solved at once.

    Every target is solved from ``q_seed`` and ``n_restarts`` random starts in one
    batched damped-least-squares solve (:meth:`Robot.ik_batch`); the converged
    solutions are then checked nearest first, one candidate per unresolved target
    per batched collision check (:meth:`CollisionScene.valid_mask`).

    Parameters
    ----------
    robot : Robot
    scene : CollisionScene
    targets : ndarray, shape (k, 4, 4)
        ``T_world_tool`` to reach.
    q_seed : ndarray, shape (dof,)
        Preferred start, radians.
    seed : int
        Seed of the random starts.
    n_restarts : int
        Random starts per target.
    why : dict, optional
        Receives why targets got no solution: ``why["ik_failed"]`` (no start
        converged) and ``why["in_collision"]`` (every converged solution collides)
        are incremented, and ``why["pairs"]`` (a :class:`collections.Counter`) counts
        the colliding pairs of the nearest colliding solution of each such target.

    Returns
    -------
    list of (ndarray (dof,) or None)
        One per target; None when no start converges to a valid configuration.
    """
    k, dof, m = len(targets), robot.dof, 1 + n_restarts
    rng = np.random.default_rng(seed)
    starts = np.empty((k, m, dof))
    starts[:, 0] = q_seed
    starts[:, 1:] = robot.random_q(rng, k * n_restarts).reshape(k, n_restarts, dof)
    q, ok = robot.ik_batch(np.repeat(targets, m, axis=0), starts.reshape(k * m, dof))
    q, ok = q.reshape(k, m, dof), ok.reshape(k, m)
    dist = np.where(ok, np.linalg.norm(q - q_seed, axis=2), np.inf)
    order = np.argsort(dist, axis=1, kind="stable")
    out: list[FloatArray | None] = [None] * k
    for r in range(m):
        rows = [i for i in range(k) if out[i] is None and np.isfinite(dist[i, order[i, r]])]
        if not rows:
            break
        cand = q[rows, order[rows, r]]
        for i, qi, valid in zip(rows, cand, scene.valid_mask(cand), strict=True):
            if valid:
                out[i] = qi.copy()
    if why is not None:
        pairs = why.setdefault("pairs", Counter())
        for i in range(k):
            if out[i] is not None:
                continue
            if not np.isfinite(dist[i, order[i, 0]]):
                why["ik_failed"] = why.get("ik_failed", 0) + 1
                continue
            why["in_collision"] = why.get("in_collision", 0) + 1
            pairs.update(scene.collisions(q[i, order[i, 0]]))
    return out


def candidate_grasps(
    task: TaskFile,
    constraint: Constraint,
    hints: Mapping[str, Sequence[grasp_mod.Grasp]],
    part_pose: FloatArray,
    max_grasps: int,
    *,
    fit: bool = False,
    triangles: FloatArray | None = None,
    plate_grasps: Sequence[grasp_mod.Grasp] = (),
) -> list[grasp_mod.Grasp]:
    """Grasps worth trying on the part where it lies, best first.

    Grasps approaching from below are dropped (the hand would go through the
    table), and 180° roll twins go last (:func:`drop_twins`: the two fingers are
    alike, so a grasp turned half a turn about its approach holds the part the same
    way; only the wrist's limits tell them apart); the rest are ranked demonstrated
    first (exact, then turned about a rod's axis), then by how steeply they come from
    above plus how far they hold from where the part meets its parent. With
    ``ExecutionOptions.rank_by_reach``, :meth:`StepSearch.run` then ranks them by
    whether the arm can reach them both where the part lies and at its goal
    (:func:`rank_by_reach`). With ``fit``, only the shape grasps that a parallel
    gripper closes on are kept, centred between the fingers
    (:func:`~thirdhand.execute.grasps.between_fingers`), and given the part's mesh
    ``triangles`` (body frame), only the grasps whose pads close on material
    (:func:`~thirdhand.execute.grasps.on_material`); a wide plate's pinch grasps
    (``plate_grasps``, :meth:`~thirdhand.execute.world.SimWorld.plate_grasps`) are then
    added and every grasp of the plate ranked first by how near its centre of mass it
    holds (in 5 cm steps): held far from it, a heavy plate turns out of the fingers.
    """
    obj = next(o for o in task.objects if o.name == constraint.child)
    cands = list(hints.get(constraint.child, ()))
    if obj.bbox_min is not None and obj.bbox_max is not None:
        shape = grasp_mod.shape_grasps(obj.bbox_min, obj.bbox_max)
        if fit:
            shape = grasp_mod.between_fingers(shape, obj.bbox_min, obj.bbox_max)
        cands += shape
    com = None
    if fit and triangles is not None:
        cands = grasp_mod.on_material(cands, triangles)
        if plate_grasps:
            cands += list(plate_grasps)
            com = grasp_mod.mesh_centroid(triangles)
    avoid = invert(constraint.pose.matrix())[:3, 3]
    rot = part_pose[:3, :3]
    scored: list[tuple[int, bool, bool, float, int, grasp_mod.Grasp]] = []
    for g in cands:
        down = -float((rot @ g.pose[:3, 2])[2])
        if down < -0.1:
            continue
        far = float(np.linalg.norm(g.pose[:3, 3] - avoid))
        turned = "@" in g.label  # a demonstrated grasp turned about a rod's axis
        lever = 0 if com is None else int(np.linalg.norm(g.pose[:3, 3] - com) / LEVER_STEP_M)
        scored.append((lever, g.source != "demo", turned, -(down + 2.0 * far), len(scored), g))
    scored.sort(key=lambda s: s[:5])
    ranked = [s[5] for s in scored]
    kept = drop_twins(ranked)
    ids = {id(g) for g in kept}
    return (kept + [g for g in ranked if id(g) not in ids])[:max_grasps]


def world_grasps(
    world: SimWorld,
    task: TaskFile,
    constraint: Constraint,
    hints: Mapping[str, Sequence[grasp_mod.Grasp]],
    part_pose: FloatArray,
    max_grasps: int,
    *,
    fit: bool = False,
) -> list[grasp_mod.Grasp]:
    """:func:`candidate_grasps` given the part's mesh from ``world``, and with ``fit``
    (planning for physics) a wide plate's pinch grasps
    (:meth:`~thirdhand.execute.world.SimWorld.plate_grasps`)."""
    part = constraint.child
    return candidate_grasps(
        task, constraint, hints, part_pose, max_grasps, fit=fit,
        triangles=world.triangles(part), plate_grasps=world.plate_grasps(part) if fit else (),
    )  # fmt: skip


def drop_twins(grasps: Sequence[grasp_mod.Grasp]) -> list[grasp_mod.Grasp]:
    """``grasps`` without the later of every pair turned 180° about the approach of each other.

    Twins: origins within 1 mm, approach directions within about 2.5°, closing
    directions opposite within the same angle.
    """
    kept: list[grasp_mod.Grasp] = []
    for g in grasps:
        p, z, y = g.pose[:3, 3], g.pose[:3, 2], g.pose[:3, 1]
        if not any(
            np.linalg.norm(k.pose[:3, 3] - p) < 1e-3
            and float(k.pose[:3, 2] @ z) > 0.999
            and float(k.pose[:3, 1] @ y) < -0.999
            for k in kept
        ):
            kept.append(g)
    return kept


def rank_by_reach(
    robot: Robot,
    scene: CollisionScene,
    grasps: Sequence[grasp_mod.Grasp],
    part: str,
    part_pose: FloatArray,
    goals: FloatArray,
    q_seed: FloatArray,
    *,
    seed: int,
    n_restarts: int = 3,
) -> tuple[list[grasp_mod.Grasp], int]:
    """Grasps reachable both where the part lies and at one of ``goals`` first.

    A quick batched IK check of every grasp (``n_restarts`` random starts besides
    ``q_seed``): at the pick (the gripper may touch the part) and at each goal (the
    arm alone against the world: placed parts, fixture, table). Grasps reachable
    at both come first (with the demonstrated ones reachable at the pick: a quick
    check with few starts does not overrule the person), then those reachable at
    the pick only, then the rest; the order is kept within each group.

    Returns
    -------
    grasps : list of Grasp
    n_both : int
        How many are reachable at the pick and at a goal.
    """
    if not grasps:
        return [], 0
    pick_t = np.stack([part_pose @ g.pose for g in grasps])
    scene.allow(GRIPPER, part)
    try:
        pick = first_valid_ik(robot, scene, pick_t, q_seed, seed=seed, n_restarts=n_restarts)
    finally:
        scene.disallow(GRIPPER, part)
    ok_pick = np.array([q is not None for q in pick])
    ok_place = np.zeros(len(grasps), dtype=bool)
    rows = np.flatnonzero(ok_pick)
    for goal in goals:
        todo = rows[~ok_place[rows]]
        if todo.size == 0:
            break
        place_t = np.stack([goal @ grasps[i].pose for i in todo])
        sols = first_valid_ik(robot, scene, place_t, q_seed, seed=seed + 1, n_restarts=n_restarts)
        ok_place[todo] = [q is not None for q in sols]
    demo = np.array([g.source == "demo" for g in grasps])
    group = np.where(ok_pick & (ok_place | demo), 0, np.where(ok_pick, 1, 2))
    order = np.argsort(group, kind="stable")
    return [grasps[i] for i in order], int(np.count_nonzero(ok_pick & ok_place))


class StepSearch:
    """The search of one step: grasps × goals, each stage bounded by the step's deadline.

    The scene is left as found: the child free at its current pose, nothing
    attached, the same pairs allowed.

    With ``put_down`` (world poses, shape (n, 4, 4)) the part is put down on the
    table instead (a regrasp's first half, :mod:`~thirdhand.execute.regrasp`): those
    poses are the goals, tried in their order, each reached straight down from
    ``insert_m`` above; the part touches nothing on purpose (the table is lowered by
    the scene's tolerance, so a part resting on it clears it). ``grasps`` replaces the
    ranked candidates (:func:`candidate_grasps`), tried in its order; ``first_goals``
    (world goals (k, 4, 4) and their displacements (k, 6) inside the free DOFs,
    :func:`~thirdhand.execute.goals.sample_goals`) are tried before the sampled goals.
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
        put_down: FloatArray | None = None,
        grasps: Sequence[grasp_mod.Grasp] | None = None,
        first_goals: tuple[FloatArray, FloatArray] | None = None,
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
        self.put_down = put_down
        self.grasps = None if grasps is None else list(grasps)
        self.first_goals = first_goals
        #: The part the child may touch while it is placed (none when put down).
        self.contact: str | None = None if put_down is not None else constraint.parent
        self.tried = {"grasps": 0, "grasps_reachable": 0, "goals": 0, "place_reachable": 0,
                      "plans": 0, "plans_failed": 0, "primitive_rejected": 0,
                      "grasp_ik_failed": 0, "grasp_in_collision": 0, "place_ik_failed": 0,
                      "place_in_collision": 0, "straight_failed": 0}  # fmt: skip
        #: The grasps reached where the part lies (IK and the straight approach), in order.
        self.reached: list[grasp_mod.Grasp] = []
        #: Why IK found no valid configuration, per kind (``"grasp"``, ``"place"``).
        self.why: dict[str, dict[str, Any]] = {"grasp": {}, "place": {}}

    def left(self) -> float:
        return self.deadline - time.perf_counter()

    def _touch(self, on: bool) -> None:
        """Allow (``on``) or forbid again the child's contact with its parent."""
        if self.contact is not None:
            (self.scene.allow if on else self.scene.disallow)(self.c.child, self.contact)

    def _ik_blocks(
        self, targets: Callable[[int], FloatArray], n: int, q_seed: FloatArray, salt: int,
        kind: str,
    ) -> Callable[[int], FloatArray | None]:  # fmt: skip
        """Lazy IK of ``n`` targets (``targets(i)`` → (4, 4)), solved :data:`IK_BLOCK` at a time.

        The scene must be in the same state at every call of the returned function.
        Why targets got no solution is added to ``self.why[kind]``.
        """
        cache: dict[int, FloatArray | None] = {}

        def get(i: int) -> FloatArray | None:
            if i not in cache:
                block = list(range(i, min(i + IK_BLOCK, n)))
                sols = first_valid_ik(
                    self.robot, self.scene, np.stack([targets(b) for b in block]), q_seed,
                    seed=self.seed * 7919 + salt + i, why=self.why[kind],
                )  # fmt: skip
                cache.update(zip(block, sols, strict=True))
            return cache[i]

        return get

    def _line(self, q_a: FloatArray, t_b: FloatArray) -> FloatArray | None:
        path = linear_motion(self.robot, q_a, t_b)
        if path is None or not self.scene.check_path(path):
            self.tried["straight_failed"] += 1
            return None
        return path

    def _carry(self, q_a: FloatArray, q_b: FloatArray) -> Carried | None:
        """The transport from ``q_a`` to ``q_b`` and how it was made, or None.

        With ``straight_carry``, first the tool's straight line to where it is at ``q_b``
        (orientation slerped), joined to ``q_b`` when the line ends within
        :data:`MAX_JUMP_RAD` of it on every joint (``"straight"``); otherwise, or when that
        is blocked, a joint-space plan (``"planner"``).
        """
        if self.opt.straight_carry:
            t_b = self.robot.tool_transforms(q_b[None])[0]
            line = linear_motion(self.robot, q_a, t_b)
            if line is not None and float(np.max(np.abs(line[-1] - q_b))) <= MAX_JUMP_RAD:
                path = np.vstack([line, q_b[None]])
                if self.scene.check_path(path):
                    return path, "straight"
            self.tried["straight_failed"] += 1
        planned = self._plan(q_a, q_b)
        return None if planned is None else (planned, "planner")

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
    ) -> tuple[str, FloatArray] | None:  # fmt: skip
        """Joint path pre-place → place (part attached) and its kind.

        The end of the learned primitive (``"primitive"``) when it is reachable
        and collision-free (its first pose clear of the parent, the rest checked
        densely with the part allowed to touch its parent); otherwise the
        straight line in from ``t_preplace_tool`` (``"straight"``).
        """
        if self.primitive is not None and self.put_down is None:
            tools = primitive_place_path(
                self.primitive, parent_world=parent_pose, child_goal=goal, grasp=g.pose,
                length_m=self.opt.primitive_m, constraint=self.c,
                straight_m=self.opt.straight_entry_m, axis=insertion_axis(self.task, self.c),
            )  # fmt: skip
            # followed backwards from the place configuration: no IK restarts needed
            back = None if tools is None else follow_tool_path(self.robot, q_place, tools[::-1])
            if back is not None and self.scene.is_valid(back[-1]):
                self._touch(True)
                ok = self.scene.check_path(back)
                self._touch(False)
                if ok:
                    return "primitive", back[::-1].copy()
            self.tried["primitive_rejected"] += 1
        self._touch(True)
        try:
            line = self._line(q_place, t_preplace_tool)
        finally:
            self._touch(False)
        # the pre-place pose itself must be clear of the parent
        if line is None or not self.scene.is_valid(line[-1]):
            return None
        return "straight", line[::-1].copy()

    def run(self, q_start: FloatArray, rng: np.random.Generator) -> StepPlan:
        c, opt, name, scene = self.c, self.opt, self.c.child, self.scene
        report = StepReport(0, c.parent, c.child, c.id, False, "")
        part_pose = self.world.pose(name)
        parent_pose = self.world.pose(c.parent)
        if self.put_down is None:
            n_goals = opt.n_goal_samples if opt.sample_free_dofs else 1
            goals, dofs = sample_goals(parent_pose, c, n_goals, rng, stratified=True)
            if self.first_goals is not None:
                goals = np.concatenate([self.first_goals[0], goals])
                dofs = np.concatenate([self.first_goals[1], dofs])
            axes = np.repeat(insertion_axis(self.task, c)[None], len(goals), axis=0)
        else:  # straight down onto the table: world up in the part's frame
            goals = np.asarray(self.put_down, dtype=np.float64)
            dofs = np.zeros((len(goals), 6))
            axes = goals[:, 2, :3].copy()
        if self.grasps is None:
            grasps = world_grasps(
                self.world, self.task, c, self.hints, part_pose, 10**6,
                fit=opt.fit_grasps_to_fingers,
            )  # fmt: skip
        else:
            grasps = self.grasps
        if opt.rank_by_reach:
            grasps, n_both = rank_by_reach(
                self.robot, scene, grasps, name, part_pose, goals[: opt.n_rank_goals], q_start,
                seed=self.seed * 7919 + 5000,
            )  # fmt: skip
            self.tried["grasps_reach_both"] = n_both
        grasps = grasps[: opt.max_grasps]
        grasp_ik = self._ik_blocks(
            lambda i: part_pose @ grasps[i].pose, len(grasps), q_start, 0, "grasp"
        )
        for k, g in enumerate(grasps):
            if self.left() <= 0:
                report.status = f"step time limit ({opt.step_time_limit:g} s) reached"
                break
            self.tried["grasps"] += 1
            t_grasp = part_pose @ g.pose
            scene.allow(GRIPPER, name)
            try:
                q_grasp = grasp_ik(k)
                back = None if q_grasp is None else self._line(
                    q_grasp, t_grasp @ _trans([0.0, 0.0, -opt.approach_m])
                )  # fmt: skip
            finally:
                scene.disallow(GRIPPER, name)
            if q_grasp is None or back is None or not scene.is_valid(back[-1]):
                continue
            self.tried["grasps_reachable"] += 1
            self.reached.append(g)
            found = self._with_grasp(q_grasp, g, goals, dofs, axes, parent_pose, part_pose)
            if found is None:
                continue
            j, lift, (transport, carry_kind), insert, retreat, kind = found
            approach = self._plan(q_start, back[-1])
            if approach is None:
                continue
            report.success = True
            report.status = "planned"
            report.grasp = g.label
            report.grasp_source = g.source
            report.place_motion = kind
            report.motions = {
                "approach": "planner",
                "grasp": "straight",
                "lift": "straight",
                "transport": carry_kind,
                "insert": kind,
                "retreat": "straight",
            }
            report.goal_dofs = [float(v) for v in dofs[j]]
            self._count_why()
            report.tried = SearchCounts.from_counts(self.tried)
            report.collision_pairs = self.top_pairs()
            segs = [
                Segment("approach", approach),
                Segment("grasp", back[::-1].copy(), before=[("allow", GRIPPER, name)],
                        after=[("attach", name)]),
                Segment("lift", lift),
                Segment("transport", transport),
                Segment("insert", insert,
                        before=[] if self.contact is None else [("allow", name, self.contact)],
                        after=[("detach", name)]),
                Segment("retreat", retreat, after=[("disallow", GRIPPER, name)]),
            ]  # fmt: skip
            return StepPlan(report, segs, goals[j])
        self._count_why()
        report.tried = SearchCounts.from_counts(self.tried)
        report.collision_pairs = self.top_pairs()
        if not report.status:
            t = self.tried
            report.status = (
                f"no reachable goal: {t['grasps']} grasps tried ({t['grasps_reachable']} "
                f"reachable), {t['goals']} goal poses tried ({t['place_reachable']} reachable, "
                f"free DOFs {'sampled' if opt.sample_free_dofs else 'not sampled'}), "
                f"{t['plans_failed']} of {t['plans']} planning queries failed"
            )
        report.status += self.explain()
        return StepPlan(report)

    def _count_why(self) -> None:
        for kind in ("grasp", "place"):
            for what in ("ik_failed", "in_collision"):
                self.tried[f"{kind}_{what}"] = int(self.why[kind].get(what, 0))

    def top_pairs(self, n: int = 3) -> list[tuple[str, str, int]]:
        """The ``n`` pairs most often colliding where IK converged (grasp, place), with counts."""
        total: Counter[tuple[str, str]] = Counter()
        for kind in ("grasp", "place"):
            total.update(self.why[kind].get("pairs", Counter()))
        return [(a, b, int(k)) for (a, b), k in total.most_common(n)]

    def explain(self) -> str:
        """Why the search failed, in words: IK failures vs collisions, the top colliding pair."""
        t = self.tried
        parts = []
        for kind, word in (("grasp", "grasp"), ("place", "place")):
            ik, col = t[f"{kind}_ik_failed"], t[f"{kind}_in_collision"]
            if ik or col:
                parts.append(f"{word} IK: {ik} unreachable, {col} only in collision")
        if t["straight_failed"]:
            parts.append(f"{t['straight_failed']} straight moves blocked")
        top = self.top_pairs(1)
        if top:
            a, b, k = top[0]
            parts.append(f"most often colliding: {a}–{b} ({k})")
        return "; " + "; ".join(parts) if parts else ""

    def _with_grasp(
        self, q_grasp: FloatArray, g: grasp_mod.Grasp, goals: FloatArray, dofs: FloatArray,
        axes: FloatArray, parent_pose: FloatArray, part_pose: FloatArray,
    ) -> tuple[int, FloatArray, Carried, FloatArray, FloatArray, str] | None:  # fmt: skip
        """For one grasp: the first goal with lift, insertion, retreat and transport feasible."""
        opt, name, scene = self.opt, self.c.child, self.scene
        t_grasp = self.robot.tool_transforms(q_grasp[None])[0]
        scene.attach(name, q_grasp)
        try:
            lift = self._line(q_grasp, _trans([0.0, 0.0, opt.lift_m]) @ t_grasp)
            if lift is None:
                return None
            q_lift = lift[-1]
            place_ik = self._ik_blocks(
                lambda i: goals[i] @ g.pose, len(goals), q_lift, 1000, "place"
            )
            for j, goal in enumerate(goals):
                if self.left() <= 0:
                    return None
                self.tried["goals"] += 1
                t_place = goal @ g.pose
                self._touch(True)
                q_place = place_ik(j)
                self._touch(False)
                if q_place is None:
                    continue
                self.tried["place_reachable"] += 1
                t_pre = goal @ _trans(opt.insert_m * axes[j]) @ g.pose
                found = self._insertion(q_place, t_pre, parent_pose, goal, g)
                if found is None:
                    continue
                kind, insert = found
                retreat = self._retreat(q_grasp, q_place, t_place, goal)
                if retreat is None:
                    continue
                carried = self._carry(q_lift, insert[0])
                if carried is None:
                    continue
                return j, lift, carried, insert, retreat, kind
            return None
        finally:
            scene.detach(name, q_grasp)

    def _retreat(
        self, q_grasp: FloatArray, q_place: FloatArray, t_place: FloatArray, goal: FloatArray
    ) -> FloatArray | None:
        """Straight back from the placed part, checked with the part left at its goal."""
        name, scene = self.c.child, self.scene
        scene.detach(name, q_grasp)
        part_pose = self.world.pose(name)
        self.world.set_pose(name, goal)
        self._touch(True)
        scene.allow(GRIPPER, name)
        try:
            return self._line(q_place, t_place @ _trans([0.0, 0.0, -self.opt.retreat_m]))
        finally:
            scene.disallow(GRIPPER, name)
            self._touch(False)
            self.world.set_pose(name, part_pose)
            scene.attach(name, q_grasp)
