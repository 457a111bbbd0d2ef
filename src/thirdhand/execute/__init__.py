"""Execution on a simulated arm — the motion layer: robot, collision world, planner, timing.

Public API (poses are ``(pos (3,), quat xyzw (4,))`` tuples or objects with
``pos`` and ``quat``, such as :class:`thirdhand.taskfile.Pose`; everything is in
the world frame, metres and radians)::

    Robot.load(name: "panda" | "baxter", *, base_pose=None, gripper_opening=None) -> Robot
    robot.dof: int;  robot.home -> q (dof,);  robot.joint_names: list[str]
    robot.lower, robot.upper, robot.velocity_limits, robot.acceleration_limits: (dof,)
    robot.fk(q) -> (pos (3,), quat (4,))          # tool (grasp) frame
    robot.fk_batch(qs (n, dof)) -> (pos (n, 3), quat (n, 4))
    robot.ik(target, q_seed=None, *, seed=0, n_restarts=32, options=None, accept=None) -> q | None
    robot.ik_all(target, q_seed=None, *, seed=0, n_restarts=32, options=None) -> (k, dof)
    robot.ik_batch(targets (n, 4, 4), q_seeds (n, dof), *, options=None) -> (q (n, dof), ok (n,))
    robot.random_q(rng, n=None);  robot.within_limits(q);  robot.frame_pose(q, frame)

    scene = CollisionScene(robot, *, tolerance=1e-3, spheres=True)
    scene.add_table(*, height=0.75, size=(2.0, 1.6), center=(0, 0), thickness=0.05, name="table")
    scene.add_box(name, pose, size)
    scene.add_object(name, pose, *, mesh_path=None, size=None, scale=1e-3, box_center=(0, 0, 0))
    scene.set_object_pose(name, pose);  scene.object_pose(name, q=None);  scene.remove_object(name)
    scene.attach(name, q);  scene.detach(name, q);  scene.attached -> str | None
    scene.allow(a, b);  scene.disallow(a, b)      # names, or the groups "gripper" / "robot"
    scene.is_valid(q) -> bool;  scene.valid_mask(qs, *, exact=False) -> (n,) bool
    scene.collisions(q) -> [(a, b), ...]
    scene.check_path(qs, *, max_step_m=0.01, max_step_rad=0.02, clearance=True) -> bool
    scene.sphere_free_mask(qs) -> (n,) bool;  scene.path_free_spheres(qs) -> bool  # conservative
    scene.interpolate(qs, ...) -> dense qs;  scene.n_checks;  scene.reset_counter()
    scene.checks -> SceneChecks                   # the checker the scene delegates to:
    checks.pair_table() -> PairTable;  checks.pair_margins(clearance=0.0) -> (P,)
    checks.sphere_flags(qs, margins=None) -> (n, P);  checks.valid_mask(qs, *, margins=None)

    pair_table.pair_table(PairWorld, tolerance) -> PairTable   # pure: which pairs, which margins
    pair_table.pair_margins(table, clearance);  pair_table.path_margin_levels(...)

    plan_motion(robot, scene, q_start, q_goal | goal_set (k, dof), *, planner="rrtconnect",
                time_limit=5.0, seed=0, simplify=True) -> PlanResult
    PlanResult.success, .path (m, dof) | None, .planning_time_s, .joint_length_rad,
               .tool_length_m, .n_checks, .status, .goal_index
    time_parametrize(path, vel_limits, acc_limits, *, rate_hz=100.0, scale=1.0) -> Trajectory
    Trajectory.t (m,), .q (m, dof), .duration_s
"""

from __future__ import annotations

from thirdhand.execute.kinematics import IkOptions
from thirdhand.execute.meshes import load_mesh
from thirdhand.execute.planner import PLANNERS, PlanningError, PlanResult, plan_motion, shortcut
from thirdhand.execute.robot import ROBOTS, PoseLike, Robot, RobotError, as_pose, pose_matrix
from thirdhand.execute.scene import GRIPPER, ROBOT, CollisionScene, SceneError
from thirdhand.execute.timing import Trajectory, time_parametrize

__all__ = [
    "GRIPPER",
    "PLANNERS",
    "ROBOT",
    "ROBOTS",
    "CollisionScene",
    "IkOptions",
    "PlanResult",
    "PlanningError",
    "PoseLike",
    "Robot",
    "RobotError",
    "SceneError",
    "Trajectory",
    "as_pose",
    "load_mesh",
    "plan_motion",
    "pose_matrix",
    "shortcut",
    "time_parametrize",
]
