"""Where the assembly stands: the base's orientation chosen by the arm's reach at every goal.

:func:`thirdhand.execute.layout.base_pose_candidates` ranks the 24 axis-aligned ways of
standing the base by geometry (out of the arm's inner radius, low, low fixture, near);
near-equal candidates differ there by millimetres, which says nothing about whether the
arm can place the parts. :func:`choose_placement` takes the first few geometric
candidates and scores each by one batched IK check: every child at goals spread over
its free DOFs (:func:`thirdhand.execute.goals.sweep_dofs`), held by each of its shape
grasps (roll twins dropped), the arm alone against the table, the fixture and the base
(:class:`~thirdhand.execute.world.SimWorld`). A goal counts as reachable when one grasp
has a collision-free IK solution there. Candidates are compared by how many children
have a reachable goal, then the smallest fraction of reachable goals over the children,
then the mean fraction; equal scores keep the geometric order.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from thirdhand.arrays import FloatArray
from thirdhand.execute import grasps as grasp_mod
from thirdhand.execute.goals import sweep_dofs, vary
from thirdhand.execute.layout import (
    Workcell,
    _pose_in_base,
    base_fixtures,
    base_pose_candidates,
)
from thirdhand.execute.robot import Robot
from thirdhand.execute.scene import CollisionScene
from thirdhand.execute.step_search import drop_twins, first_valid_ik
from thirdhand.execute.world import SimWorld
from thirdhand.task.model import TaskFile


@dataclass(frozen=True)
class PlacementScore:
    """How well the arm reaches the goals with the base at one pose.

    Attributes
    ----------
    rank : int
        Place of the candidate in the geometric order (0: the geometric choice).
    base_pose : ndarray, shape (4, 4)
        ``T_world_base``.
    reached : dict of str to (int, int)
        Per child: goals with a collision-free IK solution for some grasp, goals tried.
    pairs : dict of str to (int, int)
        Per child: (goal, grasp) pairs with a collision-free IK solution, pairs tried.
    """

    rank: int
    base_pose: FloatArray
    reached: dict[str, tuple[int, int]]
    pairs: dict[str, tuple[int, int]]

    @property
    def key(self) -> tuple[int, float, float, float, int]:
        """Sort key, best first.

        Children with a reachable goal, the worst child's fraction of reachable goals,
        the worst and the mean fraction of reachable (goal, grasp) pairs, the rank.
        """
        goals = [a / b for a, b in self.reached.values() if b > 0] or [0.0]
        pairs = [a / b for a, b in self.pairs.values() if b > 0] or [0.0]
        n_any = sum(a > 0 for a, _ in self.reached.values())
        return (-n_any, -min(goals), -min(pairs), -float(np.mean(pairs)), self.rank)


def spread_grasps(task: TaskFile, child: str, n: int = 16) -> list[grasp_mod.Grasp]:
    """At most ``n`` of a part's shape grasps (roll twins dropped), evenly spread in the list."""
    obj = next(o for o in task.objects if o.name == child)
    if obj.bbox_min is None or obj.bbox_max is None:
        return []
    gs = drop_twins(grasp_mod.shape_grasps(obj.bbox_min, obj.bbox_max))
    if len(gs) <= n:
        return gs
    return [gs[i] for i in np.linspace(0, len(gs) - 1, n).round().astype(int)]


def score_placement(
    robot: Robot,
    task: TaskFile,
    cell: Workcell,
    *,
    rank: int = 0,
    n_goals: int = 4,
    n_grasps: int = 16,
    n_restarts: int = 2,
    seed: int = 0,
    task_path: str | os.PathLike[str] | None = None,
    search: Sequence[str | os.PathLike[str]] = (),
) -> PlacementScore:
    """Reachable goals per child with the base at ``cell.base_pose`` (see the module notes).

    Parameters
    ----------
    robot : Robot
        The arm, mounted at ``cell.robot_base``.
    task : TaskFile
    cell : Workcell
    rank : int
        The candidate's geometric rank (kept in the score).
    n_goals : int
        Goals per child spread over its free rotations (a leg: ``n_goals`` spins).
    n_grasps : int
        Shape grasps per child (:func:`spread_grasps`).
    n_restarts : int
        Random IK starts per target besides the home configuration.
    seed : int
        Seed of the random starts.
    task_path, search
        Where to find meshes.
    """
    world = SimWorld(
        robot, task, cell, {cell.base: cell.base_pose}, task_path=task_path, search=search
    )
    reached: dict[str, tuple[int, int]] = {}
    pairs: dict[str, tuple[int, int]] = {}
    for c in task.constraints:
        grasps = spread_grasps(task, c.child, n_grasps)
        parent = cell.base_pose @ _pose_in_base(task, cell.base, c.parent)
        d = sweep_dofs(c, turn_step=2 * np.pi / max(n_goals, 1), shift_steps=2)[: n_goals + 1]
        goals = parent @ vary(c, d[1:] if len(d) > 1 else d)
        if not grasps:
            reached[c.child] = (0, len(goals))
            pairs[c.child] = (0, 0)
            continue
        targets = np.stack([g @ gr.pose for g in goals for gr in grasps])
        sols = first_valid_ik(
            robot, world.scene, targets, robot.home, seed=seed, n_restarts=n_restarts
        )
        ok = np.array([q is not None for q in sols]).reshape(len(goals), len(grasps))
        reached[c.child] = (int(ok.any(axis=1).sum()), len(goals))
        pairs[c.child] = (int(ok.sum()), ok.size)
    return PlacementScore(rank, cell.base_pose.copy(), reached, pairs)


def choose_placement(
    robot: Robot,
    task: TaskFile,
    cell: Workcell,
    assembly_xy: tuple[float, float],
    *,
    n_candidates: int = 3,
    n_goals: int = 4,
    n_restarts: int = 2,
    seed: int = 0,
    task_path: str | os.PathLike[str] | None = None,
    search: Sequence[str | os.PathLike[str]] = (),
) -> tuple[Workcell, list[PlacementScore]]:
    """The work cell with the base at the geometric candidate the arm reaches best.

    Parameters
    ----------
    robot : Robot
    task : TaskFile
    cell : Workcell
        As made by :func:`thirdhand.execute.layout.make_workcell` (its geometric choice).
    assembly_xy : tuple of 2 floats
        World x, y of the base's bounding-box centre, metres.
    n_candidates : int
        Geometric candidates scored (those keeping out of the inner radius, if any do).
    n_goals, n_restarts, seed, task_path, search
        As for :func:`score_placement`.

    Returns
    -------
    cell : Workcell
        A copy with the chosen base pose and its fixture.
    scores : list of PlacementScore
        Every scored candidate, best first.
    """
    cands = base_pose_candidates(
        task,
        base=cell.base,
        assembly_xy=assembly_xy,
        table_z=cell.table_z,
        robot_xy=cell.arm_xy,
        inner_radius=cell.reach[0],
        task_path=task_path,
        search=search,
    )
    least = cands[0][0][0]
    cands = [c for c in cands if c[0][0] == least][: max(n_candidates, 1)]
    scored: list[tuple[PlacementScore, Workcell]] = []
    for rank, (_, pose, height) in enumerate(cands):
        fixtures = base_fixtures(
            task,
            pose,
            height,
            base=cell.base,
            table_z=cell.table_z,
            task_path=task_path,
            search=search,
        )
        trial = replace(cell, base_pose=pose, fixtures=fixtures)
        score = score_placement(
            robot, task, trial, rank=rank, n_goals=n_goals, n_restarts=n_restarts, seed=seed,
            task_path=task_path, search=search,
        )  # fmt: skip
        scored.append((score, trial))
    scored.sort(key=lambda s: s[0].key)
    return scored[0][1], [s for s, _ in scored]


def reach_check(
    robot: Robot,
    task: TaskFile,
    cell: Workcell,
    min_grasps: int,
    *,
    near: float = 0.55,
    n_grasps: int = 24,
    n_restarts: int = 12,
    seed: int = 0,
) -> Callable[[str, FloatArray], bool]:
    """``accept(name, T_world_part)`` for :func:`~thirdhand.execute.layout.start_layout`.

    A spot nearer than ``near`` (m, horizontally from ``cell.arm_xy``) is taken as it is;
    a farther one only when at least ``min_grasps`` of the part's shape grasps that do not
    come from below there (:func:`spread_grasps`, ``n_grasps``) have an IK solution clear
    of the table (the arm alone, home and ``n_restarts`` random starts).
    """
    scene = CollisionScene(robot)
    scene.add_table(height=cell.table_z, size=cell.table_size, center=cell.table_center)
    grasps = {c.child: spread_grasps(task, c.child, n_grasps) for c in task.constraints}
    calls = [0]

    def accept(name: str, pose: FloatArray) -> bool:
        if np.hypot(*(pose[:2, 3] - np.asarray(cell.arm_xy))) < near:
            return True
        rot = pose[:3, :3]
        gs = [g for g in grasps.get(name, []) if -float((rot @ g.pose[:3, 2])[2]) >= -0.1]
        if len(gs) < min_grasps:
            return False
        calls[0] += 1
        targets = np.stack([pose @ g.pose for g in gs])
        sols = first_valid_ik(
            robot, scene, targets, robot.home, seed=seed + calls[0], n_restarts=n_restarts
        )
        return sum(q is not None for q in sols) >= min_grasps

    return accept
