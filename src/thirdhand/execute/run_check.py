"""A recorded run checked against the robot it names: joints, limits, times, velocities.

A run file (``execute --record``'s ``OUT.json``, ``live --record``'s) names its
robot; a run edited by hand, or written for another robot, must not reach a real
arm. :func:`robot_description` reads what a run is checked against from the
robot's URDF alone (no kinematics library): the arm's joint names, position and
velocity limits, every link (tf frames a part may not take) and the joints the
simulation holds still. :func:`run_problem` is the check, a pure function that
returns the first problem as one line naming the sample and the joint.
"""

from __future__ import annotations

import functools
import math
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from thirdhand.arrays import FloatArray
from thirdhand.errors import ThirdhandError

#: Longest run accepted, seconds (a day: far beyond any assembly, far below 2**31 s).
MAX_RUN_S = 86_400.0
#: How far a recorded joint may lie outside its limits, radians (or metres): the
#: record rounds to 1e-6, the planner keeps within the limits.
LIMIT_TOL = 1e-3
#: Relative slack on a velocity limit (the record's rounding of t and q).
VELOCITY_SLACK = 0.05
#: Absolute slack on a joint's displacement between two samples (rounding to 1e-6).
STEP_TOL = 4e-6


@dataclass(frozen=True)
class RobotDescription:
    """What a run is checked against, read from the robot's URDF.

    Attributes
    ----------
    name : str
        ``"panda"`` or ``"baxter"``.
    root_link : str
        The URDF's root link.
    links : tuple of str
        Every link of the URDF (each a tf frame of ``robot_state_publisher``).
    arm_joints : tuple of str
        The arm's joints, base to tip.
    lower, upper : ndarray, shape (dof,)
        Position limits of the arm joints, radians.
    velocity : ndarray, shape (dof,)
        Velocity limits of the arm joints, rad/s.
    held : dict of str to float
        The other movable joints and the value the simulation holds them at.
    finger_limits : dict of str to (float, float)
        Lower and upper limit of every held joint.
    """

    name: str
    root_link: str
    links: tuple[str, ...]
    arm_joints: tuple[str, ...]
    lower: FloatArray
    upper: FloatArray
    velocity: FloatArray
    held: dict[str, float]
    finger_limits: dict[str, tuple[float, float]]


class UnknownRobotError(ThirdhandError, ValueError):
    """A run names a robot thirdhand does not simulate."""


@functools.cache
def robot_description(name: str) -> RobotDescription:
    """The URDF facts of a robot thirdhand simulates (cached).

    Raises
    ------
    UnknownRobotError
        For any other name.
    """
    from thirdhand.execute.robot import ROBOTS, robots_dir

    spec = ROBOTS.get(name)
    if spec is None:
        raise UnknownRobotError(f"{name!r} is not a robot thirdhand simulates ({sorted(ROBOTS)})")
    urdf = ET.parse(robots_dir() / spec.urdf).getroot()
    joints = {str(j.get("name")): j for j in urdf.findall("joint")}
    children = {j.find("child").get("link") for j in joints.values()}  # type: ignore[union-attr]
    links = tuple(str(link.get("name")) for link in urdf.findall("link"))
    roots = [n for n in links if n not in children]

    def limits(joint: str) -> tuple[float, float, float]:
        lim = joints[joint].find("limit")
        if joints[joint].get("type") == "continuous" or lim is None:
            return -math.inf, math.inf, float(lim.get("velocity", "inf")) if lim else math.inf
        return tuple(float(lim.get(k, "nan")) for k in ("lower", "upper", "velocity"))  # type: ignore[return-value]

    arm = np.array([limits(j) for j in spec.arm_joints], dtype=np.float64)
    movable = [
        n for n, j in joints.items() if j.get("type") in ("revolute", "prismatic", "continuous")
    ]
    held = {n: float(spec.locked.get(n, 0.0)) for n in movable if n not in spec.arm_joints}
    return RobotDescription(
        name=name,
        root_link=roots[0],
        links=links,
        arm_joints=spec.arm_joints,
        lower=arm[:, 0],
        upper=arm[:, 1],
        velocity=arm[:, 2],
        held=held,
        finger_limits={n: limits(n)[:2] for n in held},
    )


def run_problem(
    robot: RobotDescription,
    joint_names: Sequence[str],
    t: FloatArray,
    q: FloatArray,
    *,
    velocities: bool = True,
) -> str | None:
    """The first way a recorded joint run contradicts its robot, as one line, or None.

    Parameters
    ----------
    robot : RobotDescription
    joint_names : sequence of str
        The run's joint names: must be the robot's arm joints, in order.
    t : ndarray, shape (n,)
        Seconds from the start: finite, >= 0, strictly increasing, at most
        :data:`MAX_RUN_S`.
    q : ndarray, shape (n, dof)
        Joint positions, radians: within the limits (:data:`LIMIT_TOL`).
    velocities : bool
        Also check that every joint's displacement between consecutive samples,
        over their time step, is within its velocity limit (a run time-scaled by
        1e-6 moves a million times too fast).
    """
    names = list(joint_names)
    arm = list(robot.arm_joints)
    if names != arm:
        if len(names) != len(arm):
            return f"'joint_names' has {len(names)} joints; {robot.name} has {len(arm)} ({arm})"
        k = next(i for i, (a, b) in enumerate(zip(names, arm, strict=True)) if a != b)
        return f"'joint_names'[{k}] is {names[k]!r}; {robot.name}'s joint {k} is {arm[k]!r}"
    if q.shape != (t.size, len(arm)):
        return f"'q' has shape {q.shape}, expected ({t.size}, {len(arm)}) for 't' and the joints"
    bad = ~np.isfinite(t)
    if bad.any():
        return f"'t'[{int(np.argmax(bad))}] is {t[bad][0]}, not a finite time"
    if t.size and t[0] < 0:
        return f"'t'[0] is {t[0]} s; a run starts at 0 s or later"
    if t.size and t[-1] > MAX_RUN_S:
        k = int(np.argmax(t > MAX_RUN_S))
        return f"'t'[{k}] is {t[k]:.6g} s; a run lasts at most {MAX_RUN_S:.0f} s"
    dt = np.diff(t)
    if np.any(dt <= 0):
        k = int(np.argmax(dt <= 0)) + 1
        return f"'t'[{k}] = {t[k]} s is not after 't'[{k - 1}] = {t[k - 1]} s"
    finite = np.isfinite(q)
    if not finite.all():
        i, j = (int(v) for v in np.argwhere(~finite)[0])
        return f"'q'[{i}] ({arm[j]}) is {q[i, j]}, not a finite position"
    out = (q < robot.lower - LIMIT_TOL) | (q > robot.upper + LIMIT_TOL)
    if out.any():
        i, j = (int(v) for v in np.argwhere(out)[0])
        return (
            f"'q'[{i}] at {t[i]:.6g} s: {arm[j]} = {q[i, j]:.6g} is outside its limits "
            f"[{robot.lower[j]:.6g}, {robot.upper[j]:.6g}]"
        )
    if velocities and t.size > 1:
        moved = np.abs(np.diff(q, axis=0))
        allowed = (1.0 + VELOCITY_SLACK) * robot.velocity[None] * dt[:, None] + STEP_TOL
        fast = moved > allowed
        if fast.any():
            i, j = (int(v) for v in np.argwhere(fast)[0])
            speed = moved[i, j] / dt[i]
            return (
                f"'q'[{i + 1}] at {t[i + 1]:.6g} s: {arm[j]} moves at {speed:.6g} rad/s since "
                f"the sample before; its limit is {robot.velocity[j]:.6g} rad/s"
            )
    return None
