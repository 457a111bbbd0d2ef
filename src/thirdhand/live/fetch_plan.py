"""How the assist's arm plans a fetch: grasp, lift clear, hand over.

In the world planned in (the tracked bodies grown by a clearance, the base at its
station), :func:`plan_fetch` searches a collision-free grasp from above
(:mod:`thirdhand.live.grasp`), plans home to it, lifts the part straight off what it
rests on until it touches nothing, searches a hand-over pose (held farthest from the
sphere the person sweeps first, :mod:`thirdhand.live.handover`) and plans the lift to
it. :func:`fetch_outcome` says what the result means for the assist.

Frames: world, metres; quaternions x y z w; joint configurations radians.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.live.grasp import grasp_targets, lift_clear, resting_on, top_grasp
from thirdhand.live.handover import targets_farthest_first

if TYPE_CHECKING:
    from thirdhand.execute.planner import PlanResult
    from thirdhand.execute.robot import Robot
    from thirdhand.execute.scene import CollisionScene

Pose = tuple[FloatArray, FloatArray]


@dataclass(frozen=True)
class FetchPlan:
    """What the planning of a fetch found.

    Attributes
    ----------
    q_grasp, q_lift, q_hand : ndarray of shape (dof,), or None
        The grasp, the lift's end and the hand-over configurations (None: none found or
        not searched).
    to_grasp, to_hand : PlanResult or None
        The plans from home to the grasp and from the lift's end to the hand-over (None:
        not planned).
    resting : tuple of str
        What the part rested on when grasped (the table, parts against it): it may
        touch them during the lift only.
    """

    q_grasp: FloatArray | None = None
    q_lift: FloatArray | None = None
    q_hand: FloatArray | None = None
    to_grasp: PlanResult | None = None
    to_hand: PlanResult | None = None
    resting: tuple[str, ...] = ()


def fetch_outcome(plan: FetchPlan) -> tuple[str, str] | None:
    """The outcome and status of a fetch the arm cannot do, or None: it can.

    ``unreachable`` when no grasp, clear lift or hand-over pose was found; ``no path``
    when a plan failed (its status).
    """
    r1, r2 = plan.to_grasp, plan.to_hand
    if plan.q_grasp is None or (r1 is not None and r1.success and plan.q_hand is None):
        status = (
            "no collision-free grasp"
            if plan.q_grasp is None
            else "no clear lift"
            if plan.q_lift is None
            else "no hand-over pose"
        )
        return "unreachable", status
    if r1 is None or r2 is None or not r2.success or r1.path is None or r2.path is None:
        return "no path", r2.status if r2 is not None else ("" if r1 is None else r1.status)
    return None


def plan_fetch(
    robot: Robot,
    scene: CollisionScene,
    *,
    name: str,
    part_pose: Pose,
    box: tuple[FloatArray, FloatArray],
    handover: Pose,
    root0: FloatArray,
    hands: Collection[str],
    lift_m: float,
    plan_time_s: float,
) -> FetchPlan:
    """Plan the fetch of the part ``name`` in ``scene`` (the world planned in, in which the
    part may touch the gripper).

    Parameters
    ----------
    robot : Robot
        The arm, its base at the fetch's station.
    scene : CollisionScene
        The world planned in; the part is attached to the gripper while the lift and
        the hand-over are planned, and detached again.
    name : str
        The part's object in ``scene``.
    part_pose : (ndarray (3,), ndarray (4,))
        Where the part is, world.
    box : (ndarray (3,), ndarray (3,))
        Its box's centre (part frame) and sides, metres.
    handover : (ndarray (3,), ndarray (4,))
        The hand-over tool pose (:func:`~thirdhand.live.handover.handover_pose`).
    root0 : ndarray, shape (3,)
        The root's first position: the centre of the sphere the person sweeps.
    hands : collection of str
        The tracked fingers' objects (obstacles, never what the part rests on).
    lift_m : float
        The straight lift's step, metres (:func:`~thirdhand.live.grasp.lift_clear`).
    plan_time_s : float
        Time limit of each planning query, seconds.
    """
    from thirdhand.execute.planner import plan_motion

    home = robot.home
    pos, quat = part_pose
    centre, size = box
    q_grasp = q_lift = q_hand = None
    resting: tuple[str, ...] = ()
    for target in grasp_targets(centre, size, pos, quat, top_grasp(centre, size, pos, quat)):
        q_grasp = robot.ik(target, home, seed=0, accept=scene.is_valid)
        if q_grasp is not None:
            break
    r1 = r2 = None
    if q_grasp is not None:
        r1 = plan_motion(robot, scene, home, q_grasp, time_limit=plan_time_s, seed=0, simplify=True)
        if r1.success:
            # A straight lift first, the only motion in which the part may touch what
            # it rests on (the table, parts lying against it), then a planned path.
            scene.attach(name, q_grasp)
            resting = resting_on(scene.collisions(q_grasp), name, hands, scene.objects)
            q_lift = lift_clear(robot, scene, name, q_grasp, resting, lift_m)
            if q_lift is not None:
                t_tool = se3.matrix_from_pose(*robot.fk(q_grasp))
                held = np.linalg.inv(t_tool) @ se3.matrix_from_pose(pos, quat)
                for target in targets_farthest_first(handover, centre, size, held, root0):
                    q_hand = robot.ik(target, q_lift, seed=0, n_restarts=16, accept=scene.is_valid)
                    if q_hand is not None:
                        break
            if q_hand is not None and q_lift is not None:
                r2 = plan_motion(
                    robot, scene, q_lift, q_hand, time_limit=plan_time_s, seed=0, simplify=True
                )
            scene.detach(name, q_grasp)
    return FetchPlan(q_grasp, q_lift, q_hand, r1, r2, resting)


__all__ = ["FetchPlan", "fetch_outcome", "plan_fetch"]
