"""Regrasp through an intermediate placement: put the part down near the arm, pick it again.

A step fails when no grasp serves both the pick where the part lies and the place
at its goal: a part lying far from the arm (Baxter's start spots reach 0.88 m from
the shoulder) has one or two reachable grasps, and none of them can place it.
:func:`plan_regrasp` then

1. draws free table spots near the arm (:func:`rest_spots`: nearer than
   :data:`NEAR_M`, the part at its start resting orientation or turned face down,
   about the vertical at random, its footprint clear of every other part, the
   fixture and the robot's base);
2. checks that a regrasp can help: some grasp the step's search reached where the
   part lies (to carry it), and some grasp at a spot that reaches a goal
   (:func:`place_reach`, IK only) and that the search has not already tried and
   seen fail; otherwise it is not tried, and the step's failure says why;
3. scores the spots by one batched IK check (:func:`score_spots`): a spot is feasible
   when a grasp reached where the part lies also reaches the spot (to put it down)
   and some of the grasps of step 2 reach it there (to place it from there);
   feasible spots are ranked by how many do;
4. puts the part down at the best feasible spot it can (the step search with
   ``put_down``: any grasp reachable at both, straight down onto the table), then
   searches the step again from there; when that fails, the next spot.

Each half (the put-down, the step from the spot) is bounded by the step time limit, the
spots tried together by twice that. Frames: world, metres, radians.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence

import numpy as np

from thirdhand.arrays import FloatArray
from thirdhand.execute import grasps as grasp_mod
from thirdhand.execute.goals import sample_goals
from thirdhand.execute.layout import (
    Workcell,
    _overlap,
    _transform,
    occupied_footprints,
    rot_z,
    table_spot,
)
from thirdhand.execute.robot import Robot
from thirdhand.execute.scene import GRIPPER, CollisionScene
from thirdhand.execute.step_plan import ExecutionOptions, RegraspReport, Segment, StepPlan
from thirdhand.execute.step_search import first_valid_ik, world_grasps
from thirdhand.execute.world import SimWorld
from thirdhand.task.constraint import Constraint
from thirdhand.task.model import TaskFile

#: Intermediate spots lie nearer than this to the arm's first joint (horizontally), metres.
NEAR_M = 0.55
#: Goals (the nominal one first, then spread over the free DOFs) of the IK checks.
N_GOALS = 6

#: ``search(world, constraint, q_start, deadline, put_down, grasps, first_goals)``: one step
#: search's plan (:class:`~thirdhand.execute.step_search.StepSearch` with those arguments).
Search = Callable[
    [
        SimWorld, Constraint, FloatArray, float, FloatArray | None,
        Sequence[grasp_mod.Grasp], tuple[FloatArray, FloatArray] | None,
    ],
    StepPlan,
]  # fmt: skip


def _key(g: grasp_mod.Grasp) -> tuple[str, str, bytes]:
    """Tells grasps apart (labels repeat: every shape grasp of a rod is ``"side"``)."""
    return g.source, g.label, np.round(g.pose, 6).tobytes()


def _rot_x_pi() -> FloatArray:
    return np.diag([1.0, -1.0, -1.0])


def rest_spots(
    part: str,
    part_pose: FloatArray,
    verts: Mapping[str, FloatArray],
    poses: Mapping[str, FloatArray],
    cell: Workcell,
    rng: np.random.Generator,
    *,
    n: int = 24,
    draws: int = 3000,
    margin: float = 0.06,
) -> list[tuple[FloatArray, bool]]:
    """Free table spots near the arm for ``part``: up to ``n`` of ``draws`` random ones.

    Parameters
    ----------
    part : str
    part_pose : ndarray, shape (4, 4)
        Where the part lies now (its resting orientation is kept, or turned face down).
    verts : dict of str to ndarray (m, 3)
        Body-frame vertices of every part (:func:`~thirdhand.execute.layout.part_vertices`).
    poses : dict of str to ndarray (4, 4)
        World poses of the other parts (any entry for ``part`` is ignored).
    cell : Workcell
    rng : numpy.random.Generator
    n, draws : int
        Spots kept, draws made.
    margin : float
        Free space kept around each footprint (room for the fingers), as in
        :func:`~thirdhand.execute.layout.start_layout`.

    Returns
    -------
    list of (ndarray (4, 4), bool)
        ``T_world_part`` at rest on the table, and whether it is face down; every other
        draw face down.
    """
    others = [_transform(p, verts[k]) for k, p in poses.items() if k != part and k in verts]
    taken = occupied_footprints(cell, others, margin)
    v = verts[part]
    out: list[tuple[FloatArray, bool]] = []
    for k in range(draws):
        face_down = k % 2 == 1
        rot = rot_z(rng.uniform(-np.pi, np.pi)) @ (
            _rot_x_pi() @ part_pose[:3, :3] if face_down else part_pose[:3, :3]
        )
        r = rng.uniform(cell.reach[0], max(NEAR_M, cell.reach[0] + 0.05))
        ang = rng.uniform(-np.pi * 0.85, np.pi * 0.85)
        t, fp = table_spot(v, rot, cell, r, ang, margin)
        if fp is not None and not any(_overlap(fp, o) for o in taken):
            out.append((t, face_down))
            if len(out) >= n:
                break
    return out


def _reached(
    robot: Robot, scene: CollisionScene, targets: list[FloatArray], q_seed: FloatArray,
    seed: int, n_restarts: int,
) -> list[bool]:  # fmt: skip
    if not targets:
        return []
    sols = first_valid_ik(robot, scene, np.stack(targets), q_seed, seed=seed, n_restarts=n_restarts)
    return [q is not None for q in sols]


def place_reach(
    robot: Robot,
    scene: CollisionScene,
    grasps: Sequence[grasp_mod.Grasp],
    goals: FloatArray,
    q_seed: FloatArray,
    *,
    seed: int,
    n_restarts: int = 8,
) -> list[int]:
    """Per grasp: the first of ``goals`` where the arm reaches it (IK, the arm alone), or -1."""
    at = [-1] * len(grasps)
    for j, goal in enumerate(goals):
        todo = [i for i in range(len(grasps)) if at[i] < 0]
        hit = _reached(
            robot, scene, [goal @ grasps[i].pose for i in todo], q_seed, seed + j, n_restarts
        )
        for i, h in zip(todo, hit, strict=True):
            if h:
                at[i] = j
    return at


def score_spots(
    robot: Robot,
    scene: CollisionScene,
    spots: Sequence[FloatArray],
    put_grasps: Sequence[grasp_mod.Grasp],
    spot_grasps: Sequence[Sequence[grasp_mod.Grasp]],
    q_seed: FloatArray,
    *,
    seed: int,
    n_restarts: int = 8,
) -> tuple[list[bool], list[int]]:
    """Which spots the part can be put down at, and how many grasps there reach a goal.

    Parameters
    ----------
    robot, scene
        The arm and the world (the part where it lies now).
    spots : list of ndarray (4, 4)
        Candidate ``T_world_part``.
    put_grasps : list of Grasp
        Grasps that hold the part where it lies now (reached by the step's search).
    spot_grasps : list of list of Grasp
        Per spot: the grasps there (not from below) that reach a goal.
    q_seed : ndarray, shape (dof,)
    seed, n_restarts
        Random IK starts.

    Returns
    -------
    put_ok : list of bool
        Per spot: some grasp of ``put_grasps`` reaches it (and is not from below there).
    n_place : list of int
        Per spot: grasps of ``spot_grasps`` reachable there.
    """
    put_t, put_at, place_t, place_at = [], [], [], []
    for s, (spot, gs) in enumerate(zip(spots, spot_grasps, strict=True)):
        for g in put_grasps:
            if -float((spot[:3, :3] @ g.pose[:3, 2])[2]) >= -0.1:
                put_t.append(spot @ g.pose)
                put_at.append(s)
        for g in gs:
            place_t.append(spot @ g.pose)
            place_at.append(s)
    hits = _reached(robot, scene, put_t + place_t, q_seed, seed, n_restarts)
    put_ok = [False] * len(spots)
    n_place = [0] * len(spots)
    for s, h in zip(put_at, hits[: len(put_t)], strict=True):
        put_ok[s] = put_ok[s] or h
    for s, h in zip(place_at, hits[len(put_t) :], strict=True):
        n_place[s] += int(h)
    return put_ok, n_place


def plan_regrasp(
    world: SimWorld,
    task: TaskFile,
    constraint: Constraint,
    options: ExecutionOptions,
    plain: StepPlan,
    reached: Sequence[grasp_mod.Grasp],
    search: Search,
    *,
    verts: Mapping[str, FloatArray],
    cell: Workcell,
    hints: Mapping[str, Sequence[grasp_mod.Grasp]],
    q_start: FloatArray,
    seed: int,
) -> tuple[StepPlan | None, str]:
    """A step done through an intermediate placement (see the module notes), or why not.

    Parameters
    ----------
    world : SimWorld
        Left as found.
    task, constraint, options
        The step (``constraint.child`` is the part moved).
    plain : StepPlan
        The failed plain search of the step.
    reached : list of Grasp
        The grasps that search reached where the part lies.
    search : callable
        ``search(world, constraint, q_start, deadline, put_down, grasps, first_goals)``: a
        step search's plan (put down at the first reachable of the ``put_down`` poses, or
        the step itself), trying ``grasps`` in their order and ``first_goals`` first
        (:class:`~thirdhand.execute.step_search.StepSearch`).
    verts, cell, hints
        Every part's body vertices, the work cell, demonstrated grasps.
    q_start : ndarray, shape (dof,)
    seed : int

    Returns
    -------
    plan : StepPlan or None
        Both halves' segments, the report of the second with
        :attr:`~thirdhand.execute.step_plan.StepReport.regrasp` set.
    why : str
        Why no regrasp was found (empty when one was).
    """
    robot, scene, part = world.robot, world.scene, constraint.child
    rng = np.random.default_rng([seed, plain.report.index, 71])
    part_pose = world.pose(part)
    n_goals = N_GOALS if options.sample_free_dofs else 1
    goals, dofs = sample_goals(
        world.pose(constraint.parent), constraint, n_goals, rng, stratified=True
    )
    if not reached:
        return None, "regrasp not tried: no grasp reached where the part lies"
    spots = rest_spots(part, part_pose, verts, world.poses(), cell, rng)
    if not spots:
        return None, f"regrasp not tried: no free spot within {NEAR_M:g} m of the arm"
    # per spot, the grasps there that reach a goal and were not already tried from where
    # the part lies (those failed); each grasp checked once
    tried = {_key(g) for g in reached}
    place_at: dict[tuple[str, str, bytes], int] = {}
    ik_seed = seed * 7919 + 9000
    spot_grasps = []
    for pose, _ in spots:
        gs = world_grasps(
            world, task, constraint, hints, pose, options.max_grasps,
            fit=options.fit_grasps_to_fingers,
        )  # fmt: skip
        new = [g for g in gs if _key(g) not in place_at]
        hit = place_reach(robot, scene, new, goals, q_start, seed=ik_seed)
        place_at.update((_key(g), j) for g, j in zip(new, hit, strict=True))
        spot_grasps.append([g for g in gs if place_at[_key(g)] >= 0 and _key(g) not in tried])
    if all(j < 0 for j in place_at.values()):
        return None, "regrasp not tried: no grasp reaches the goal"
    if not any(spot_grasps):
        return None, (
            "regrasp not tried: every grasp that reaches the goal was tried where the part lies"
        )
    scene.allow(GRIPPER, part)
    try:
        put_ok, n_place = score_spots(
            robot, scene, [p for p, _ in spots], reached, spot_grasps, q_start, seed=ik_seed + 1
        )
    finally:
        scene.disallow(GRIPPER, part)
    arm = np.asarray(cell.arm_xy)
    order = sorted(
        (s for s in range(len(spots)) if put_ok[s] and n_place[s] > 0),
        key=lambda s: (-n_place[s], float(np.hypot(*(spots[s][0][:2, 3] - arm)))),
    )
    counts = (len(spots), len(order))
    if not order:
        return None, (
            f"regrasp: none of {len(spots)} free spots near the arm both reached with a "
            f"grasp that holds {part} now ({sum(put_ok)}) and placeable from "
            f"({sum(n > 0 for n in n_place)})"
        )
    why = "regrasp: no put-down and pick from the feasible spots within the time limit"
    limit = options.step_time_limit
    deadline = time.perf_counter() + 2 * limit
    while order and time.perf_counter() < deadline:
        put = np.stack([spots[s][0] for s in order])
        down = search(world, constraint, q_start, time.perf_counter() + limit, put, reached, None)
        if not down.report.success or down.final_pose is None:
            why = f"regrasp: put-down failed ({down.report.status})"
            break
        j = order[int(np.argmin([np.abs(spots[s][0] - down.final_pose).max() for s in order]))]
        q_down = down.segments[-1].path[-1]
        world.set_pose(part, spots[j][0])
        try:
            # the grasps that reach a goal from there first, then the rest as ranked; the
            # goals they reach first, most reached first
            first = spot_grasps[j]
            keys = {_key(g) for g in first}
            rest = world_grasps(
                world, task, constraint, hints, spots[j][0], options.max_grasps,
                fit=options.fit_grasps_to_fingers,
            )  # fmt: skip
            hits = np.bincount([place_at[k] for k in keys], minlength=len(goals))
            top = [int(k) for k in np.argsort(-hits, kind="stable") if hits[k] > 0]
            again = search(world, constraint, q_down, time.perf_counter() + limit, None,
                           first + [g for g in rest if _key(g) not in keys],
                           (goals[top], dofs[top]))  # fmt: skip
        finally:
            world.set_pose(part, part_pose)
        if again.report.success:
            return _joined(down, again, spots[j], verts[part], plain, arm, counts), ""
        why = f"regrasp: picked again from the spot, the step failed ({again.report.status})"
        order.remove(j)
    return None, why


def _joined(
    down: StepPlan, again: StepPlan, spot: tuple[FloatArray, bool], verts: FloatArray,
    plain: StepPlan, arm: FloatArray, counts: tuple[int, int],
) -> StepPlan:  # fmt: skip
    """One plan: the put-down's segments (named ``"regrasp ..."``), then the step's."""
    names = {"insert": "put down"}
    first = [
        Segment(f"regrasp {names.get(s.name, s.name)}", s.path, s.before, s.after)
        for s in down.segments
    ]
    rep = again.report
    rep.motions = {
        **{f"regrasp {names.get(k, k)}": v for k, v in down.report.motions.items()},
        **rep.motions,
    }
    pose, face_down = spot
    vw = _transform(pose, verts)
    centre = (vw.min(axis=0) + vw.max(axis=0))[:2] / 2.0
    rep.regrasp = RegraspReport(
        spot=(float(pose[0, 3]), float(pose[1, 3]), float(pose[2, 3])),
        distance_m=float(np.hypot(*(centre - arm))),
        face_down=face_down,
        put_down_grasp=down.report.grasp or "",
        plain_status=plain.report.status,
        spots=counts,
    )
    return StepPlan(rep, first + again.segments, again.final_pose)
