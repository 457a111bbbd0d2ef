"""The simulated arm as the planner saw it: its collision shapes and where they were.

An executed run (``thirdhand execute --record OUT``) stores the joint trajectory
``q (T, dof)``, the robot's name and the pose of its root in the world. This
module turns that into drawable shapes — every collision object of the reduced
model (cylinders, spheres, boxes, meshes), each attached to one arm joint or
fixed to the world — and their world poses over time, for the Rerun export.

Runs recorded before the base pose was stored get it back from the replay's
tool frame (:func:`base_from_tool`): the tool's world pose equals
``T_world_root · T_root_tool(q)``, so one sample fixes ``T_world_root``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np
from numpy.typing import NDArray

from thirdhand.arrays import FloatArray

if TYPE_CHECKING:
    from thirdhand.execute.robot import Robot


ShapeKind = Literal["cylinder", "sphere", "box", "mesh"]


@dataclass(frozen=True)
class RobotShape:
    """One collision object of the arm.

    Attributes
    ----------
    name : str
        The geometry object's name (``panda_link3_0``).
    joint : int
        Index of the arm joint it moves with (``Robot.joint_names``), or -1 when it
        is fixed to the world (a pedestal, a torso).
    placement : ndarray, shape (4, 4)
        The shape's frame in that joint's frame (in the world for ``joint == -1``).
    kind : {"cylinder", "sphere", "box", "mesh"}
        Cylinders lie along their frame's z axis, centred on its origin.
    size : ndarray
        cylinder: ``(radius, length)``; sphere: ``(radius,)``; box: half sizes
        ``(3,)``; mesh: empty. Metres.
    vertices : ndarray, shape (V, 3), optional
        A mesh's vertices in the shape's frame, metres.
    triangles : ndarray, shape (F, 3), optional
        A mesh's vertex indices.
    """

    name: str
    joint: int
    placement: FloatArray
    kind: ShapeKind
    size: FloatArray
    vertices: FloatArray | None = None
    triangles: NDArray[np.uint32] | None = None


def robot_shapes(robot: Robot) -> list[RobotShape]:
    """Every collision object of ``robot``'s reduced model, in its model order."""
    import coal

    shapes = []
    for g in robot.geometry.geometryObjects:
        geo = g.geometry
        placement = np.array(g.placement.homogeneous, dtype=np.float64)
        joint = int(g.parentJoint) - 1
        vertices = triangles = None
        if isinstance(geo, coal.Cylinder):
            kind: ShapeKind = "cylinder"
            size = np.array([geo.radius, 2.0 * geo.halfLength])
        elif isinstance(geo, coal.Sphere):
            kind, size = "sphere", np.array([geo.radius])
        elif isinstance(geo, coal.Box):
            kind, size = "box", np.array(geo.halfSide, dtype=np.float64)
        elif isinstance(geo, coal.BVHModelBase):
            kind, size = "mesh", np.zeros(0)
            vertices = np.array(geo.vertices(), dtype=np.float64).reshape(-1, 3)
            tri = [geo.tri_indices(i) for i in range(geo.num_tris)]
            triangles = np.array([[t[0], t[1], t[2]] for t in tri], dtype=np.uint32)
        else:  # no other shape is in the shipped robots' collision models
            continue
        shapes.append(RobotShape(g.name, joint, placement, kind, size, vertices, triangles))
    return shapes


def shape_transforms(robot: Robot, shapes: list[RobotShape], qs: FloatArray) -> FloatArray:
    """World poses of ``shapes`` at every configuration.

    Parameters
    ----------
    robot : Robot
        The arm, its base pose folded in.
    shapes : list of RobotShape
        From :func:`robot_shapes` of the same robot.
    qs : ndarray, shape (T, dof)
        Joint angles, radians.

    Returns
    -------
    ndarray, shape (T, len(shapes), 4, 4)
        ``T_world_shape`` per configuration and shape.
    """
    qa = np.asarray(qs, dtype=np.float64).reshape(-1, robot.dof)
    joints = robot.chain.joint_transforms(qa)  # (T, dof, 4, 4), world frame
    out = np.empty((qa.shape[0], len(shapes), 4, 4))
    for k, s in enumerate(shapes):
        out[:, k] = s.placement if s.joint < 0 else joints[:, s.joint] @ s.placement
    return out


def base_from_tool(robot: Robot, q: FloatArray, t_world_tool: FloatArray) -> FloatArray:
    """``T_world_root`` from one configuration and the tool's world pose at it.

    Parameters
    ----------
    robot : Robot
        The arm loaded with its root at the world origin (no base pose).
    q : ndarray, shape (dof,)
        Joint angles, radians.
    t_world_tool : ndarray, shape (4, 4)
        The tool frame's pose in the world at ``q`` (the replay's ``robot_tool``).

    Returns
    -------
    ndarray, shape (4, 4)
    """
    t_root_tool = robot.tool_transforms(np.asarray(q, dtype=np.float64)[None])[0]
    return np.asarray(t_world_tool @ np.linalg.inv(t_root_tool), dtype=np.float64)


__all__ = ["RobotShape", "base_from_tool", "robot_shapes", "shape_transforms"]
