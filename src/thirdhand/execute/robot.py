"""Robot models (Panda, one Baxter arm) from ``example-robot-data``: limits, FK and IK.

The URDF, SRDF and collision geometry come from the ``example-robot-data``
package (found through its installed distribution, no fixed path). Each robot
is reduced with :func:`pinocchio.buildReducedModel` to one 7-DOF arm: the
gripper fingers (and for Baxter the head and the left arm) are locked. The
robot's base pose is folded into the model, so the pinocchio "universe" frame
*is* the world frame of the scene and every pose here is in the world.

The tool frame is the point between the fingertips: Panda ``panda_hand_tcp``
(z out of the hand along the approach, fingers closing along y), Baxter
``right_gripper`` (the same axes). A grasp is a pose of the part in that frame.
"""

from __future__ import annotations

import importlib.metadata
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.errors import ThirdhandError
from thirdhand.execute.kinematics import Chain, IkOptions, solve_ik


class _HasPose(Protocol):
    @property
    def pos(self) -> Any: ...

    @property
    def quat(self) -> Any: ...


PoseLike = tuple[ArrayLike, ArrayLike] | _HasPose
"""``(pos (3,), quat xyzw (4,))`` or an object with ``pos`` and ``quat`` (a task-file Pose)."""


class RobotError(ThirdhandError):
    """A robot could not be loaded or was given an invalid configuration."""


def as_pose(pose: PoseLike) -> tuple[FloatArray, FloatArray]:
    """Normalise a pose to ``(pos (3,), quat (4,))`` float64 arrays, x y z w.

    Raises
    ------
    ThirdhandError
        If the shapes are wrong or the quaternion is zero.
    """
    if isinstance(pose, (tuple, list)):
        pos, quat = pose
    else:
        pos, quat = pose.pos, pose.quat
    p = np.asarray(pos, dtype=np.float64)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ThirdhandError(f"expected a finite position of shape (3,), got {p.shape}")
    return p.copy(), se3.check_quat(quat).reshape(4)


def pose_matrix(pose: PoseLike) -> FloatArray:
    """Homogeneous transform (4, 4) of a pose."""
    return se3.matrix_from_pose(*as_pose(pose))


def robots_dir() -> Path:
    """Directory ``.../share/example-robot-data/robots`` of the installed package.

    Raises
    ------
    RobotError
        If ``example-robot-data`` is not installed.
    """
    try:
        dist = importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError:
        raise RobotError(
            "example-robot-data is not installed (pip install example-robot-data)"
        ) from None
    path = Path(str(dist.locate_file("cmeel.prefix/share/example-robot-data/robots")))
    if not path.is_dir():
        raise RobotError(f"example-robot-data: no robots directory at {path}")
    return path


@dataclass(frozen=True)
class RobotSpec:
    """What to load for one robot and how to reduce it.

    Attributes
    ----------
    urdf, srdf : str
        Paths relative to :func:`robots_dir`.
    arm_joints : tuple of str
        The joints kept, base to tip.
    tool_frame : str
        Frame of the grasp point.
    gripper_links : tuple of str
        Links an attached part may touch (hand and fingers).
    home : tuple of float
        Home configuration of the arm, radians.
    locked : dict
        Values of locked joints (others at 0), radians or metres.
    acceleration_limits : tuple of float
        Per-joint acceleration limits, rad/s² (URDFs carry none).
    """

    urdf: str
    srdf: str
    arm_joints: tuple[str, ...]
    tool_frame: str
    gripper_links: tuple[str, ...]
    home: tuple[float, ...]
    locked: dict[str, float] = field(default_factory=dict)
    acceleration_limits: tuple[float, ...] = (5.0,) * 7


ROBOTS: dict[str, RobotSpec] = {
    "panda": RobotSpec(
        urdf="panda_description/urdf/panda_collision.urdf",
        srdf="panda_description/srdf/panda.srdf",
        arm_joints=tuple(f"panda_joint{i}" for i in range(1, 8)),
        tool_frame="panda_hand_tcp",
        gripper_links=("panda_hand", "panda_leftfinger", "panda_rightfinger"),
        home=(0.0, -0.785398, 0.0, -2.35619, 0.0, 1.5707, 0.785398),
        locked={"panda_finger_joint1": 0.04, "panda_finger_joint2": 0.04},
        # Franka's datasheet limits, halved for smooth simulated motions.
        acceleration_limits=(7.5, 3.75, 5.0, 6.25, 7.5, 10.0, 10.0),
    ),
    "baxter": RobotSpec(
        urdf="baxter_description/urdf/baxter.urdf",
        srdf="baxter_description/srdf/baxter_manipulation.srdf",
        arm_joints=tuple(f"right_{j}" for j in ("s0", "s1", "e0", "e1", "w0", "w1", "w2")),
        tool_frame="right_gripper",
        gripper_links=(
            "right_gripper_base",
            "right_hand",
            "r_gripper_l_finger",
            "r_gripper_l_finger_tip",
            "r_gripper_r_finger",
            "r_gripper_r_finger_tip",
        ),
        home=(0.0, -0.55, 0.0, 0.75, 0.0, 1.26, 0.0),
        # The left arm tucked out to its side, fingers open.
        locked={
            "left_s0": 0.8,
            "left_s1": -0.55,
            "left_e1": 0.75,
            "left_w1": 1.26,
            "r_gripper_l_finger_joint": 0.020833,
            "r_gripper_r_finger_joint": -0.020833,
        },
        acceleration_limits=(4.0,) * 7,
    ),
}


def _prefold_base(model: pin.Model, geom: pin.GeometryModel, base: pin.SE3) -> None:
    """Move everything attached to the universe by ``base`` (world ← robot root)."""
    for j in range(1, model.njoints):
        if model.parents[j] == 0:
            model.jointPlacements[j] = base * model.jointPlacements[j]
    for f in model.frames:
        if f.parentJoint == 0 and f.name != "universe":
            f.placement = base * f.placement
    for i in range(len(model.frames)):
        fr = model.frames[i]
        if fr.parentJoint == 0 and fr.name != "universe":
            model.frames[i] = fr
    for i in range(geom.ngeoms):
        g = geom.geometryObjects[i]
        if g.parentJoint == 0:
            g.placement = base * g.placement


class Robot:
    """One arm: pinocchio model, collision geometry, limits, FK and IK, in the world frame.

    Build it with :meth:`load`. Configurations ``q`` are arrays of shape
    ``(dof,)`` in radians, ordered base to tip as :attr:`joint_names`.

    Attributes
    ----------
    name : str
        ``"panda"`` or ``"baxter"``.
    model : pinocchio.Model
        Reduced model (``nq == dof``), base pose folded in.
    geometry : pinocchio.GeometryModel
        Collision geometry of the reduced model, SRDF pairs already removed.
    srdf_path : pathlib.Path
        The SRDF whose disabled pairs were applied.
    joint_names : list of str
    lower, upper : ndarray, shape (dof,)
        Joint limits, radians.
    velocity_limits : ndarray, shape (dof,)
        From the URDF, rad/s.
    acceleration_limits : ndarray, shape (dof,)
        rad/s².
    tool_frame : str
        Name of the grasp frame.
    tool_frame_id : int
        Its pinocchio frame index.
    tool_joint : int
        Joint (0-based) the grasp frame is attached to.
    t_joint_tool : ndarray, shape (4, 4)
        Grasp frame in that joint's frame, metres.
    gripper_links : tuple of str
        Links an attached part is allowed to touch.
    base_pose : tuple of ndarray
        Robot root in the world, ``(pos (3,), quat (4,))``.
    """

    def __init__(
        self,
        name: str,
        model: pin.Model,
        geometry: pin.GeometryModel,
        spec: RobotSpec,
        srdf_path: Path,
        base_pose: tuple[FloatArray, FloatArray],
    ) -> None:
        self.name = name
        self.model = model
        self.geometry = geometry
        self.srdf_path = srdf_path
        self.base_pose = base_pose
        self.joint_names = [model.names[j] for j in range(1, model.njoints)]
        self.lower = np.array(model.lowerPositionLimit, dtype=np.float64)
        self.upper = np.array(model.upperPositionLimit, dtype=np.float64)
        self.velocity_limits = np.array(model.velocityLimit, dtype=np.float64)
        self.acceleration_limits = np.array(spec.acceleration_limits, dtype=np.float64)
        self.tool_frame = spec.tool_frame
        self.gripper_links = spec.gripper_links
        self._home = np.clip(np.array(spec.home, dtype=np.float64), self.lower, self.upper)
        self.data = model.createData()
        self.chain = Chain.from_model(model)
        fid = model.getFrameId(spec.tool_frame)
        frame = model.frames[fid]
        self.tool_frame_id = fid
        self.tool_joint = int(frame.parentJoint) - 1
        self.t_joint_tool = np.array(frame.placement.homogeneous, dtype=np.float64)

    @classmethod
    def load(
        cls, name: str, *, base_pose: PoseLike | None = None, gripper_opening: float | None = None
    ) -> Robot:
        """Load ``"panda"`` or ``"baxter"`` (its right arm) from example-robot-data.

        Parameters
        ----------
        name : str
            Robot name, a key of :data:`ROBOTS`.
        base_pose : pose, optional
            Pose of the robot's root link in the world (Panda ``panda_link0``,
            Baxter ``base`` — the torso, about 0.93 m above its pedestal's foot).
            Identity by default.
        gripper_opening : float, optional
            Finger joint value, metres (Panda 0…0.04, fixed during planning);
            the spec's open value by default.

        Raises
        ------
        RobotError
            For an unknown name or a missing package.
        """
        if name not in ROBOTS:
            raise RobotError(f"unknown robot {name!r}: expected one of {sorted(ROBOTS)}")
        spec = ROBOTS[name]
        root = robots_dir()
        urdf = root / spec.urdf
        srdf = root / spec.srdf
        package_dirs = [str(root.parent.parent)]
        full = pin.buildModelFromUrdf(str(urdf))
        geom = pin.buildGeomFromUrdf(
            full, str(urdf), pin.GeometryType.COLLISION, package_dirs=package_dirs
        )
        q_ref = pin.neutral(full)
        for jname, value in spec.locked.items():
            jid = full.getJointId(jname)
            q_ref[full.joints[jid].idx_q] = value
        if gripper_opening is not None:
            for jname in spec.locked:
                if "finger" in jname:
                    jid = full.getJointId(jname)
                    sign = -1.0 if spec.locked[jname] < 0 else 1.0
                    q_ref[full.joints[jid].idx_q] = sign * gripper_opening
        lock = [j for j in range(1, full.njoints) if full.names[j] not in spec.arm_joints]
        model, rgeom = pin.buildReducedModel(full, geom, lock, q_ref)
        if [model.names[j] for j in range(1, model.njoints)] != list(spec.arm_joints):
            raise RobotError(f"{name}: reduced model does not have the joints {spec.arm_joints}")
        pose = (np.zeros(3), se3.quat_identity()) if base_pose is None else as_pose(base_pose)
        _prefold_base(model, rgeom, pin.SE3(se3.matrix_from_pose(*pose)))
        rgeom.addAllCollisionPairs()
        pin.removeCollisionPairs(model, rgeom, str(srdf))
        return cls(name, model, rgeom, spec, srdf, pose)

    # -- configurations ---------------------------------------------------------------

    @property
    def dof(self) -> int:
        """Number of arm joints."""
        return int(self.model.nq)

    @property
    def home(self) -> FloatArray:
        """Home configuration, shape (dof,), radians (a copy)."""
        return self._home.copy()

    def check_q(self, q: ArrayLike) -> FloatArray:
        """Validate one configuration: shape (dof,), finite; returns float64.

        Raises
        ------
        RobotError
            On a wrong shape or a non-finite value.
        """
        qa = np.asarray(q, dtype=np.float64)
        if qa.shape != (self.dof,) or not np.all(np.isfinite(qa)):
            raise RobotError(
                f"{self.name}: expected a finite configuration of shape ({self.dof},), "
                f"got shape {qa.shape}"
            )
        return qa

    def within_limits(self, q: ArrayLike, tol: float = 1e-9) -> bool:
        """True if every joint of ``q`` (dof,) lies within its limits (± ``tol`` rad)."""
        qa = self.check_q(q)
        return bool(np.all(qa >= self.lower - tol) and np.all(qa <= self.upper + tol))

    def random_q(self, rng: np.random.Generator, n: int | None = None) -> FloatArray:
        """Uniform configurations within the limits, shape (dof,) or (n, dof)."""
        shape = (self.dof,) if n is None else (n, self.dof)
        return np.asarray(rng.uniform(self.lower, self.upper, size=shape), dtype=np.float64)

    # -- kinematics -------------------------------------------------------------------

    def fk(self, q: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Tool pose in the world.

        Parameters
        ----------
        q : array_like, shape (dof,)
            Joint angles, radians.

        Returns
        -------
        pos : ndarray, shape (3,), metres, world frame
        quat : ndarray, shape (4,), x y z w
        """
        qa = self.check_q(q)
        t = self.tool_transforms(qa[None])[0]
        return se3.pose_from_matrix(t)

    def fk_batch(self, qs: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Tool poses of many configurations ``qs`` (n, dof): pos (n, 3), quat (n, 4)."""
        return se3.pose_from_matrix(self.tool_transforms(qs))

    def tool_transforms(self, qs: ArrayLike) -> FloatArray:
        """``T_world_tool`` of many configurations (n, dof), shape (n, 4, 4)."""
        qa = np.asarray(qs, dtype=np.float64).reshape(-1, self.dof)
        tj = self.chain.joint_transforms(qa)
        return np.asarray(tj[:, self.tool_joint] @ self.t_joint_tool, dtype=np.float64)

    def frame_pose(self, q: ArrayLike, frame: str) -> tuple[FloatArray, FloatArray]:
        """Pose of any model frame (a link name) in the world, through pinocchio.

        Raises
        ------
        RobotError
            If the frame does not exist.
        """
        qa = self.check_q(q)
        if not self.model.existFrame(frame):
            raise RobotError(f"{self.name}: no frame named {frame!r}")
        fid = self.model.getFrameId(frame)
        pin.framesForwardKinematics(self.model, self.data, qa)
        return se3.pose_from_matrix(self.data.oMf[fid].homogeneous)

    def ik(
        self,
        target: PoseLike,
        q_seed: ArrayLike | None = None,
        *,
        seed: int | np.random.Generator = 0,
        n_restarts: int = 32,
        options: IkOptions | None = None,
        accept: Any = None,
    ) -> FloatArray | None:
        """A configuration whose tool pose is ``target``, or None.

        Damped least squares on the world-frame SE(3) error with joint limits,
        started from ``q_seed`` and ``n_restarts`` uniform random configurations
        (all at once). Of the converged starts that ``accept`` takes, the one
        nearest ``q_seed`` (joint-space distance) is returned.

        Parameters
        ----------
        target : pose
            Desired tool pose in the world.
        q_seed : array_like, shape (dof,), optional
            Preferred start (home by default).
        seed : int or numpy.random.Generator
            Randomness of the restarts.
        n_restarts : int
            Random starts besides ``q_seed``.
        options : IkOptions, optional
            Iterations and tolerances (1e-4 m, 1e-3 rad by default).
        accept : callable, optional
            ``accept(q) -> bool`` filter, e.g. ``scene.is_valid`` for
            collision-free solutions; called nearest-first.

        Returns
        -------
        ndarray, shape (dof,), or None
            None when no start converges within the limits (or none is accepted).
        """
        sols = self.ik_all(target, q_seed, seed=seed, n_restarts=n_restarts, options=options)
        for q in sols:
            if accept is None or accept(q):
                return q
        return None

    def ik_all(
        self,
        target: PoseLike,
        q_seed: ArrayLike | None = None,
        *,
        seed: int | np.random.Generator = 0,
        n_restarts: int = 32,
        options: IkOptions | None = None,
    ) -> FloatArray:
        """Every converged IK solution from the seed and random starts, nearest ``q_seed`` first.

        Returns
        -------
        ndarray, shape (k, dof)
            ``k`` may be 0. Parameters as :meth:`ik`.
        """
        rng = np.random.default_rng(seed)
        q0 = self._home if q_seed is None else self.check_q(q_seed)
        starts = np.vstack([q0[None], self.random_q(rng, n_restarts)])
        q, ok = solve_ik(
            self.chain,
            self.tool_joint,
            self.t_joint_tool,
            pose_matrix(target),
            starts,
            self.lower,
            self.upper,
            options or IkOptions(),
        )
        sols = q[ok]
        order = np.argsort(np.linalg.norm(sols - q0, axis=1), kind="stable")
        return np.asarray(sols[order], dtype=np.float64)

    def ik_batch(
        self,
        targets: ArrayLike,
        q_seeds: ArrayLike,
        *,
        options: IkOptions | None = None,
    ) -> tuple[FloatArray, NDArray[np.bool_]]:
        """One local IK solve per (target, start) pair, all at once (no restarts).

        Parameters
        ----------
        targets : array_like, shape (n, 4, 4)
            Desired ``T_world_tool``.
        q_seeds : array_like, shape (n, dof)
            Start configurations, radians.

        Returns
        -------
        q : ndarray, shape (n, dof)
        converged : ndarray of bool, shape (n,)
        """
        return solve_ik(
            self.chain,
            self.tool_joint,
            self.t_joint_tool,
            np.asarray(targets, dtype=np.float64),
            np.asarray(q_seeds, dtype=np.float64),
            self.lower,
            self.upper,
            options or IkOptions(),
        )
