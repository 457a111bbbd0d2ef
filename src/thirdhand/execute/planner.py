"""Collision-free joint-space motion planning, seeded and always time-bounded.

:func:`plan_motion` first tries the straight joint-space segment; otherwise it
runs RRT-Connect (:func:`rrt_connect`, the default ``"rrtconnect"``: two trees
in numpy arrays, every edge checked in one batched call of the sphere layer)
or an OMPL planner (``"ompl_rrtconnect"``, ``"rrtstar"``, ...) on a
``RealVectorStateSpace`` bounded by the joint limits. Every edge is checked
densely with :meth:`CollisionScene.check_path` (no point of the robot or the
grasped part moves more than 1 cm between two checks, and each check keeps half
that distance of clearance), so every edge accepted is collision-free along the
whole continuous motion, not only at the samples; the sphere covers decide
wherever they clear a pair, coal's exact check wherever they do not. The path is then
shortcut (random arc-length shortcuts, each checked densely, then redundant
vertices dropped) with a seeded generator, and the final path checked densely
once more. The same seed gives the same path unless a time limit cuts the
search (OMPL's generator is seeded through ``ompl.util.RNG.setSeed``).
"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from ompl import base as ob
from ompl import geometric as og
from ompl import util as ou

from thirdhand.arrays import FloatArray
from thirdhand.errors import ThirdhandError
from thirdhand.execute.robot import Robot
from thirdhand.execute.scene import CollisionScene

PLANNERS: dict[str, Any] = {
    "rrtconnect": None,  # ours: rrt_connect below
    "ompl_rrtconnect": og.RRTConnect,
    "rrt": og.RRT,
    "rrtstar": og.RRTstar,
    "informedrrtstar": og.InformedRRTstar,
    "aorrtc": og.AORRTC,
}
"""Planner names accepted by :func:`plan_motion`: ``"rrtconnect"`` is :func:`rrt_connect`, the
others OMPL's (the optimising ones use the whole time limit)."""


class PlanningError(ThirdhandError):
    """A planning request was malformed (unknown planner, wrong shapes, bad limits)."""


@dataclass
class PlanResult:
    """Outcome of one planning query.

    Attributes
    ----------
    success : bool
        A collision-free path was found.
    path : ndarray, shape (m, dof), or None
        Waypoints from the start to the reached goal, radians; straight
        joint-space segments between them are collision-free (dense check).
    status : str
        ``"direct"`` (straight segment), ``"planned"``, or why it failed:
        ``"start invalid: ..."``, ``"goal invalid: ..."``, ``"timeout"``,
        ``"dense check failed"``.
    planning_time_s : float
        Wall time of the whole query (checks, search, shortcutting), seconds.
    joint_length_rad : float
        Euclidean joint-space length of the path, radians.
    tool_length_m : float
        Length of the tool frame's path in the world, metres.
    n_checks : int
        Configurations collision-checked during the query.
    goal_index : int or None
        Which goal of the goal set was reached.
    planner : str
        Planner name.
    """

    success: bool
    path: FloatArray | None
    status: str
    planning_time_s: float
    joint_length_rad: float = float("nan")
    tool_length_m: float = float("nan")
    n_checks: int = 0
    goal_index: int | None = None
    planner: str = "rrtconnect"

    def __bool__(self) -> bool:
        return self.success


def joint_length(path: ArrayLike) -> float:
    """Euclidean joint-space length of a waypoint path (m, dof), radians."""
    p = np.asarray(path, dtype=np.float64)
    return float(np.sum(np.linalg.norm(np.diff(p, axis=0), axis=1))) if len(p) > 1 else 0.0


def tool_length(robot: Robot, path: ArrayLike, *, max_step_rad: float = 0.01) -> float:
    """Length of the tool frame's path in the world, metres, along straight joint segments.

    Each segment is subdivided so that no joint moves more than ``max_step_rad``.
    """
    p = np.asarray(path, dtype=np.float64)
    if len(p) < 2:
        return 0.0
    parts = [p[:1]]
    for a, b in itertools.pairwise(p):
        n = max(int(np.ceil(np.max(np.abs(b - a)) / max_step_rad)), 1)
        parts.append(a + (np.arange(1, n + 1) / n)[:, None] * (b - a))
    pos, _ = robot.fk_batch(np.vstack(parts))
    return float(np.sum(np.linalg.norm(np.diff(pos, axis=0), axis=1)))


def _to_array(state: ob.State, dof: int) -> FloatArray:
    return np.array([state[i] for i in range(dof)], dtype=np.float64)


class _DenseMotionValidator(ob.MotionValidator):
    """OMPL motion validator that checks a segment with the scene's dense check."""

    def __init__(
        self, si: ob.SpaceInformation, scene: CollisionScene, dof: int, step: tuple[float, float]
    ) -> None:
        super().__init__(si)
        self._scene = scene
        self._dof = dof
        self._step = step

    def checkMotion(self, s1: ob.State, s2: ob.State) -> bool:
        seg = np.stack([_to_array(s1, self._dof), _to_array(s2, self._dof)])
        return self._scene.check_path(seg, max_step_m=self._step[0], max_step_rad=self._step[1])


def shortcut(
    scene: CollisionScene,
    path: ArrayLike,
    rng: np.random.Generator,
    *,
    iterations: int = 100,
    patience: int = 10,
    deadline: float = float("inf"),
    max_step_m: float = 0.01,
    max_step_rad: float = 0.02,
    exact: bool = False,
) -> FloatArray:
    """Shorten a collision-free waypoint path by random shortcuts, each checked densely.

    A first pass drops every vertex that the vertex before it connects past
    (greedily, farthest first). Then each iteration draws two points along the
    path (uniform in arc length) and replaces what lies between them by the
    straight segment if it (and the remaining pieces of the two segments it
    cuts) is collision-free, until ``patience`` attempts in a row fail; a final
    pass drops vertices again (until the deadline, too).

    Parameters
    ----------
    scene : CollisionScene
        The world (with the grasped part, if any).
    path : array_like, shape (m, dof)
        Collision-free waypoints, radians.
    rng : numpy.random.Generator
        Source of the shortcut endpoints.
    iterations : int
        Shortcut attempts at most.
    patience : int
        Stop after this many failed attempts in a row.
    deadline : float
        ``time.perf_counter()`` value after which to stop early.
    max_step_m, max_step_rad : float
        Density of the checks (see :meth:`CollisionScene.interpolate`).
    exact : bool
        Ask coal about the shortcuts the sphere covers cannot clear (slower; by
        default such a shortcut is not taken).

    Returns
    -------
    ndarray, shape (m', dof)
        Same endpoints, no longer in joint space.
    """
    p = np.array(path, dtype=np.float64)

    def free(seg: FloatArray) -> bool:
        # a shortcut the spheres cannot clear is dropped unless coal clears it (``exact``, or a
        # scene without the sphere layer)
        if scene.path_free_spheres(seg, max_step_m=max_step_m, max_step_rad=max_step_rad):
            return True
        return (exact or not scene.use_spheres) and scene.check_path(
            seg, max_step_m=max_step_m, max_step_rad=max_step_rad
        )

    def prune(p: FloatArray) -> FloatArray:
        keep = [0]
        i = 0
        while i < len(p) - 1:
            if time.perf_counter() > deadline:  # out of time: keep the remaining vertices
                keep.extend(range(i + 1, len(p)))
                break
            j = len(p) - 1
            while j > i + 1 and not free(p[[i, j]]):
                j -= 1
            keep.append(j)
            i = j
        return np.asarray(p[keep], dtype=np.float64)

    p = prune(p)
    misses = 0
    for _ in range(iterations):
        if len(p) < 3 or misses >= patience or time.perf_counter() > deadline:
            break
        seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        a, b = np.sort(rng.uniform(0.0, cum[-1], size=2))
        ia = min(int(np.searchsorted(cum, a, side="right")) - 1, len(p) - 2)
        ib = min(int(np.searchsorted(cum, b, side="right")) - 1, len(p) - 2)
        misses += 1
        if ia == ib:
            continue
        qa = p[ia] + (a - cum[ia]) / max(seg[ia], 1e-12) * (p[ia + 1] - p[ia])
        qb = p[ib] + (b - cum[ib]) / max(seg[ib], 1e-12) * (p[ib + 1] - p[ib])
        # The pieces kept of the two cut segments are re-checked too: their
        # interpolated configurations differ from the ones checked before.
        if free(np.stack([p[ia], qa, qb, p[ib + 1]])):
            p = np.vstack([p[: ia + 1], qa, qb, p[ib + 1 :]])
            misses = 0
    return prune(p)


def plan_motion(
    robot: Robot,
    scene: CollisionScene,
    q_start: ArrayLike,
    goal: ArrayLike,
    *,
    planner: str = "rrtconnect",
    time_limit: float = 5.0,
    seed: int = 0,
    simplify: bool = True,
    max_step_m: float = 0.01,
    max_step_rad: float = 0.02,
) -> PlanResult:
    """Plan a collision-free joint path from ``q_start`` to one goal configuration.

    Parameters
    ----------
    robot : Robot
        The arm (joint limits bound the search).
    scene : CollisionScene
        The world, in its current state (grasped part included).
    q_start : array_like, shape (dof,)
        Start configuration, radians.
    goal : array_like, shape (dof,) or (k, dof)
        Goal configuration or a set of alternatives (e.g. IK solutions of
        goal poses sampled in a constraint's free DOFs); any one may be reached.
    planner : str
        A key of :data:`PLANNERS`.
    time_limit : float
        Bound on the OMPL search, seconds; shortcutting gets at most a quarter
        of it more. Planning never runs unbounded.
    seed : int
        Seeds OMPL's generator and the shortcutting.
    simplify : bool
        Shortcut the path.
    max_step_m, max_step_rad : float
        Density of every motion check (see :meth:`CollisionScene.interpolate`).

    Returns
    -------
    PlanResult
        Falsy with ``path=None`` on failure; ``status`` says why.

    Raises
    ------
    PlanningError
        For an unknown planner, a non-positive time limit or wrong shapes.
    """
    t0 = time.perf_counter()
    if planner not in PLANNERS:
        raise PlanningError(f"unknown planner {planner!r}: expected one of {sorted(PLANNERS)}")
    if not time_limit > 0:
        raise PlanningError(f"time_limit must be positive seconds, got {time_limit}")
    dof = robot.dof
    start = robot.check_q(q_start)
    goals = np.asarray(goal, dtype=np.float64)
    if goals.ndim == 1:
        goals = goals[None]
    if goals.ndim != 2 or goals.shape[1] != dof or goals.shape[0] == 0:
        raise PlanningError(f"goal: expected shape ({dof},) or (k, {dof}), got {goals.shape}")
    checks0 = scene.n_checks
    step = (max_step_m, max_step_rad)

    def free(seg: FloatArray) -> bool:
        return scene.check_path(seg, max_step_m=max_step_m, max_step_rad=max_step_rad)

    def fail(status: str) -> PlanResult:
        return PlanResult(
            False,
            None,
            status,
            time.perf_counter() - t0,
            n_checks=scene.n_checks - checks0,
            planner=planner,
        )

    def done(path: FloatArray, status: str) -> PlanResult:
        idx = int(np.argmin(np.linalg.norm(goals - path[-1], axis=1)))
        path[-1] = goals[idx]
        return PlanResult(
            True,
            path,
            status,
            time.perf_counter() - t0,
            joint_length(path),
            tool_length(robot, path),
            scene.n_checks - checks0,
            idx,
            planner,
        )

    if not scene.is_valid(start):
        hits = scene.collisions(start) if robot.within_limits(start) else [("joint", "limits")]
        return fail(f"start invalid: {_describe(hits)}")
    ok_goals = scene.valid_mask(goals)
    if not np.any(ok_goals):
        g0 = goals[0]
        hits = scene.collisions(g0) if robot.within_limits(g0) else [("joint", "limits")]
        return fail(f"goal invalid: {_describe(hits)}")
    goal_idx = np.flatnonzero(ok_goals)
    order = goal_idx[np.argsort(np.linalg.norm(goals[goal_idx] - start, axis=1), kind="stable")]
    for k in order[:3]:
        if free(np.stack([start, goals[k]])):
            return done(np.stack([start, goals[k]]), "direct")

    if PLANNERS[planner] is None:
        path = rrt_connect(
            robot, scene, start, goals[goal_idx], deadline=t0 + time_limit,
            rng=np.random.default_rng(seed), max_step_m=max_step_m, max_step_rad=max_step_rad,
        )  # fmt: skip
    else:
        path = _ompl_search(
            robot, scene, start, goals[goal_idx], planner, t0 + time_limit, seed, step
        )
    if path is None:
        return fail("timeout")
    if simplify:
        # A fixed number of shortcut attempts, no wall-clock deadline: the same seed
        # gives the same path however loaded the machine is.
        path = shortcut(
            scene,
            path,
            np.random.default_rng(seed),
            max_step_m=max_step_m,
            max_step_rad=max_step_rad,
        )
    if not free(path):
        return fail("dense check failed")
    return done(path, "planned")


def rrt_connect(
    robot: Robot,
    scene: CollisionScene,
    start: FloatArray,
    goals: FloatArray,
    *,
    deadline: float,
    rng: np.random.Generator,
    max_step_m: float = 0.01,
    max_step_rad: float = 0.02,
    range_frac: float = 0.2,
    max_nodes: int = 50_000,
) -> FloatArray | None:
    """RRT-Connect (Kuffner and LaValle 2000) between a start and a set of goal configurations.

    Two trees, one rooted at ``start`` and one at every goal, grow in turn: the
    one extends by at most ``range`` towards a uniform sample of the joint
    limits, the other then connects to the new node greedily (steps of at most
    ``range``) until it reaches it or is blocked. ``range`` is ``range_frac``
    times the diagonal of the joint limits' box (OMPL's default). Nodes live in
    numpy arrays; the nearest node is found by brute force; every edge is
    checked densely (:meth:`CollisionScene.check_path`), so the joined path is
    collision-free along its whole length.

    Parameters
    ----------
    robot : Robot
    scene : CollisionScene
    start : ndarray, shape (dof,)
        Valid start configuration, radians.
    goals : ndarray, shape (k, dof)
        Valid goal configurations, radians.
    deadline : float
        ``time.perf_counter()`` value at which to give up.
    rng : numpy.random.Generator
        Source of the samples.
    max_step_m, max_step_rad : float
        Density of the edge checks (see :meth:`CollisionScene.interpolate`).
    range_frac : float
        Longest edge as a fraction of the joint box's diagonal.
    max_nodes : int
        Bound on the nodes of each tree.

    Returns
    -------
    ndarray, shape (m, dof), or None
        Waypoints from ``start`` to one of ``goals``; None at the deadline.
    """
    dof = robot.dof
    lo, hi = robot.lower, robot.upper
    reach = range_frac * float(np.linalg.norm(hi - lo))
    trees = [_Tree(start[None], max_nodes, dof), _Tree(goals, max_nodes, dof)]

    def free(a: FloatArray, b: FloatArray, root: bool) -> bool:
        seg = np.stack([a, b])
        if scene.path_free_spheres(seg, max_step_m=max_step_m, max_step_rad=max_step_rad):
            return True
        # near the start and the goals (a hand at its grasp, a part at its goal) the
        # spheres are too coarse: coal decides there (and everywhere without them)
        return (root or not scene.use_spheres) and scene.check_path(
            seg, max_step_m=max_step_m, max_step_rad=max_step_rad
        )

    def extend(tree: _Tree, q: FloatArray) -> tuple[int, int]:
        """(status, node): 0 trapped, 1 advanced, 2 reached ``q``."""
        i = tree.nearest(q)
        near = tree.nodes[i]
        d = float(np.linalg.norm(q - near))
        reached = d <= reach
        q_new = q if reached else near + (reach / d) * (q - near)
        if not free(near, q_new, i < tree.n_roots):
            return 0, -1
        k = tree.add(q_new, i)
        return (2 if reached else 1), k

    a, b = 0, 1
    while time.perf_counter() < deadline:
        if trees[0].full() or trees[1].full():
            return None
        status, k = extend(trees[a], rng.uniform(lo, hi))
        if status:
            q_new = trees[a].nodes[k].copy()
            while True:
                s2, j = extend(trees[b], q_new)
                if s2 == 2:
                    half_a, half_b = trees[a].branch(k), trees[b].branch(j)
                    joined = np.vstack([half_a[::-1], half_b[1:]])  # q_new once
                    return joined if a == 0 else joined[::-1].copy()
                if s2 == 0 or time.perf_counter() >= deadline or trees[b].full():
                    break
        a, b = b, a
    return None


class _Tree:
    """Nodes (n, dof) and parent indices of one RRT tree (roots have parent -1)."""

    def __init__(self, roots: FloatArray, capacity: int, dof: int) -> None:
        self.nodes = np.empty((capacity + len(roots), dof))
        self.parent = np.full(capacity + len(roots), -1, dtype=np.intp)
        self.n = self.n_roots = len(roots)
        self.nodes[: self.n] = roots

    def full(self) -> bool:
        return self.n >= len(self.nodes)

    def nearest(self, q: FloatArray) -> int:
        d = self.nodes[: self.n] - q
        return int(np.argmin(np.einsum("ij,ij->i", d, d)))

    def add(self, q: FloatArray, parent: int) -> int:
        self.nodes[self.n] = q
        self.parent[self.n] = parent
        self.n += 1
        return self.n - 1

    def branch(self, k: int) -> FloatArray:
        """Nodes from ``k`` back to its root, shape (m, dof)."""
        idx = []
        while k >= 0:
            idx.append(k)
            k = int(self.parent[k])
        return self.nodes[idx].copy()


def _describe(hits: list[tuple[str, str]]) -> str:
    if not hits:
        return "unknown"
    shown = ", ".join(f"{a}–{b}" for a, b in hits[:3])
    return shown + (f" (+{len(hits) - 3} more)" if len(hits) > 3 else "")


def _ompl_search(
    robot: Robot,
    scene: CollisionScene,
    start: FloatArray,
    goals: FloatArray,
    planner: str,
    deadline: float,
    seed: int,
    step: tuple[float, float],
) -> FloatArray | None:
    """Run the OMPL planner until ``deadline``; the raw waypoint path or None."""
    dof = robot.dof
    level = ou.getLogLevel()
    ou.setLogLevel(ou.LOG_NONE)  # setSeed complains once generators exist; it still reseeds
    ou.RNG.setSeed(int(seed) % (2**31 - 1) + 1)
    space = ob.RealVectorStateSpace(dof)
    bounds = ob.RealVectorBounds(dof)
    for i in range(dof):
        bounds.setLow(i, float(robot.lower[i]))
        bounds.setHigh(i, float(robot.upper[i]))
    space.setBounds(bounds)
    setup = og.SimpleSetup(space)
    si = setup.getSpaceInformation()

    def valid(state: ob.State) -> bool:
        return scene.is_valid(_to_array(state, dof))

    setup.setStateValidityChecker(valid)
    validator = _DenseMotionValidator(si, scene, dof, step)
    si.setMotionValidator(validator)
    s = space.allocState()
    for i in range(dof):
        s[i] = float(start[i])
    setup.setStartState(s)
    goal_states = ob.GoalStates(si)
    for g in goals:
        gs = space.allocState()
        for i in range(dof):
            gs[i] = float(g[i])
        goal_states.addState(gs)
    setup.setGoal(goal_states)
    setup.setPlanner(PLANNERS[planner](si))
    remaining = deadline - time.perf_counter()
    try:
        if remaining <= 0:
            return None
        status = setup.solve(remaining)
        if not setup.haveExactSolutionPath() or "Exact" not in str(status):
            return None
        sol = setup.getSolutionPath()
        return np.array([_to_array(sol.getState(i), dof) for i in range(sol.getStateCount())])
    finally:
        ou.setLogLevel(level)
