"""The MuJoCo model of a work cell: the planner's arm, the table and the parts.

Built with MuJoCo's model-editing API (:class:`mujoco.MjSpec`). The arm comes
from the same URDF of ``example-robot-data`` that the planner loads
(:mod:`thirdhand.execute.robot`), with three changes to its text: the visual
elements dropped (MuJoCo does not read Collada), static bodies kept
(``fusestatic="false"``, so the tool frame exists as a body) and both fingers
driven (the URDF's mimic is not a MuJoCo constraint). Its collision geometry is
the URDF's spheres and cylinders; flat pads are added on the fingertips, where
the planner's tool frame lies.

Every arm joint has a position servo with velocity feed-forward (the control is
``q_ref + (kv / kp) q̇_ref``, so the damping acts on the velocity error and not on
the absolute velocity) and its torque limit from the URDF; the arm's own weight
is compensated (``gravcomp``). Each finger is force-driven as the real gripper's
grasp: it pushes with the gripper's force (closing) or opens with it, damped to the
gripper's speed.

Contacts: the arm touches the parts (not the table, not itself: the planner
already keeps those apart); the parts touch each other and the table. The base
part stands clamped to the world (the fixture). Each part has two welds,
inactive until the run needs them: to the hand (the weld grasp) and to its
parent (the fastening).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field

import mujoco
import numpy as np

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.execute.grasps import PAD_HALF_M
from thirdhand.execute.robot import ROBOTS, robots_dir
from thirdhand.readlimits import read_text_input
from thirdhand.simulate.parts import MassProperties, Piece, SimulateError
from thirdhand.simulate.settings import SimulateSettings

#: Robots the simulation builds (the Baxter's URDF collides through Collada meshes).
SIM_ROBOTS = ("panda",)
#: Body of the tool frame, of the hand, and the finger joints of each robot.
HAND = "panda_hand"
TOOL = "panda_hand_tcp"
FINGERS = ("panda_finger_joint1", "panda_finger_joint2")
#: Joint speed limits of the arm, rad/s (Franka's datasheet, the URDF's velocity limits).
ARM_SPEED = (2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61)
#: Finger joint value of the open gripper, metres.
FINGER_OPEN = 0.04
#: Free speed of a finger, m/s (the Franka Hand's largest): its damping is force / speed.
FINGER_SPEED = 0.1
#: Half sizes of a fingertip pad (x along the hand's x, y its thickness, z along the finger), m:
#: the pad the planner checks a grasp closes on (:data:`thirdhand.execute.grasps.PAD_HALF_M`).
PAD_HALF = (PAD_HALF_M[0], 0.004, PAD_HALF_M[1])
#: Where the pad's centre sits in the finger body, metres (the tool point is 0.045 up it).
PAD_Z = 0.045
#: Half sizes of the hand's casing, metres, from the hand's frame to the fingers' base
#: (the URDF's spheres and cylinder reach 23 mm past the fingers' base toward the tool).
HAND_HALF = (0.03, 0.1, 0.029)
#: Contact bits: the arm touches parts only; parts touch parts, the table and the arm.
ARM_BITS = (1, 0)
PART_BITS = (2, 3)
TABLE_BITS = (2, 2)
#: Stiffer contacts than MuJoCo's default (time constant s, damping ratio) for a firm grasp.
CONTACT_SOLREF = (0.004, 1.0)
CONTACT_SOLIMP = (0.95, 0.99, 0.001, 0.5, 2.0)
#: The wrist camera: on the hand's side (its x), in the hand's frame, metres, looking at
#: the point between the fingertips (the approach is the hand's z), vertical field of view °.
WRIST_CAMERA = "wrist"
WRIST_CAMERA_POS = (0.07, 0.0, 0.03)
WRIST_CAMERA_TARGET = (0.0, 0.0, 0.16)
WRIST_CAMERA_FOVY = 75.0


@dataclass(frozen=True)
class PartModel:
    """A part to put in the model.

    Attributes
    ----------
    name : str
    pieces : list of Piece
        Convex collision pieces, body frame, metres.
    mass : MassProperties
    pose : ndarray, shape (4, 4)
        Start pose, world frame.
    fixed : bool
        Clamped to the world (the base part in its fixture).
    """

    name: str
    pieces: Sequence[Piece]
    mass: MassProperties
    pose: FloatArray
    fixed: bool = False


@dataclass(frozen=True)
class CellModel:
    """What the model holds besides the arm.

    Attributes
    ----------
    robot : str
    robot_base : ndarray, shape (4, 4)
        Robot root pose, world frame.
    table_z : float
        Table top height, metres.
    table_extent : tuple of 4 floats
        x min, x max, y min, y max, metres.
    parts : list of PartModel
    joints : list of (str, str)
        ``(child, parent)`` pairs that are fastened during the run.
    """

    robot: str
    robot_base: FloatArray
    table_z: float
    table_extent: tuple[float, float, float, float]
    parts: Sequence[PartModel]
    joints: Sequence[tuple[str, str]] = field(default_factory=list)


def robot_urdf_text(robot: str) -> str:
    """The planner's URDF with the three changes MuJoCo needs (see the module docstring)."""
    if robot not in SIM_ROBOTS:
        raise SimulateError(
            f"robot {robot!r}: the physics simulation builds {', '.join(SIM_ROBOTS)} only"
        )
    root = robots_dir()
    text = read_text_input(root / ROBOTS[robot].urdf, what="robot model (URDF)")
    text = re.sub(r"<visual>.*?</visual>", "", text, flags=re.S)
    text = re.sub(r"<mimic[^>]*/>", "", text)
    text = text.replace("package://example-robot-data/robots/", f"{root}/")
    return re.sub(
        r"(<robot[^>]*>)",
        r'\1<mujoco><compiler fusestatic="false" discardvisual="false"/></mujoco>',
        text,
        count=1,
    )


def _quat_wxyz(rot: FloatArray) -> list[float]:
    x, y, z, w = se3.quat_from_matrix(rot)
    return [float(w), float(x), float(y), float(z)]


def _contacts(geom: mujoco.MjsGeom, bits: tuple[int, int]) -> None:
    geom.contype, geom.conaffinity = bits


def build_spec(cell: CellModel, settings: SimulateSettings) -> mujoco.MjSpec:
    """The model of ``cell`` as an editable spec (compile it with ``spec.compile()``).

    Raises
    ------
    SimulateError
        For a robot the simulation does not build.
    """
    spec = mujoco.MjSpec.from_string(robot_urdf_text(cell.robot))
    spec.option.timestep = settings.timestep
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.option.impratio = 10.0
    spec.option.noslip_iterations = 0
    spec.visual.global_.offwidth = max(settings.width, 640)
    spec.visual.global_.offheight = max(settings.height, 480)
    _arm(spec, cell, settings)
    _table(spec, cell, settings)
    for part in cell.parts:
        _part(spec, part, settings)
    for part in cell.parts:
        if not part.fixed:
            eq = spec.add_equality()
            eq.type = mujoco.mjtEq.mjEQ_WELD
            eq.objtype = mujoco.mjtObj.mjOBJ_BODY
            eq.name = f"grasp:{part.name}"
            eq.name1, eq.name2 = part.name, HAND
            eq.active = False
            eq.solref = list(CONTACT_SOLREF)
    for child, parent in cell.joints:
        eq = spec.add_equality()
        eq.type = mujoco.mjtEq.mjEQ_WELD
        eq.objtype = mujoco.mjtObj.mjOBJ_BODY
        eq.name = f"fasten:{child}"
        eq.name1, eq.name2 = child, parent
        eq.active = False
        eq.solref = list(CONTACT_SOLREF)
    return spec


def _arm(spec: mujoco.MjSpec, cell: CellModel, settings: SimulateSettings) -> None:
    robot_spec = ROBOTS[cell.robot]
    root = spec.worldbody.first_body()
    root.pos = [float(v) for v in cell.robot_base[:3, 3]]
    root.quat = _quat_wxyz(cell.robot_base[:3, :3])
    for body in spec.bodies:
        if body.name != "world":
            body.gravcomp = 1.0
    for g in spec.geoms:
        _contacts(g, ARM_BITS)
        g.rgba = [0.85, 0.85, 0.88, 1.0]
    # The fingers touch through their pads only: the URDF's finger capsules stand
    # proud of the pads' faces, and a board between the fingers rests on them instead.
    for name in ("panda_leftfinger", "panda_rightfinger"):
        for g in spec.body(name).geoms:
            _contacts(g, (0, 0))
    hand = spec.body(HAND)
    for g in list(hand.geoms):
        spec.delete(g)
    casing = hand.add_geom()
    casing.name = "hand_casing"
    casing.type = mujoco.mjtGeom.mjGEOM_BOX
    casing.size = list(HAND_HALF)
    casing.pos = [0.0, 0.0, HAND_HALF[2]]
    casing.mass = 0.0
    casing.rgba = [0.85, 0.85, 0.88, 1.0]
    _contacts(casing, ARM_BITS)
    kp, kv = settings.stiffness, settings.damping
    for name in robot_spec.arm_joints:
        j = spec.joint(name)
        j.armature = 0.1
        act = spec.add_actuator()
        act.name = name
        act.target = name
        act.trntype = mujoco.mjtTrn.mjTRN_JOINT
        act.gaintype = mujoco.mjtGain.mjGAIN_FIXED
        act.biastype = mujoco.mjtBias.mjBIAS_AFFINE
        act.gainprm[0] = kp
        act.biasprm[:3] = [0.0, -kp, -kv]
        act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        effort = 87.0 if name[-1] in "1234" else 12.0
        act.forcerange = [-effort, effort]
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
    for name in FINGERS:
        j = spec.joint(name)
        j.armature = 1.0  # heavy enough that the soft joint limit holds the open force
        j.damping = [settings.gripper_force / FINGER_SPEED, 0.0, 0.0]
        j.limited = mujoco.mjtLimited.mjLIMITED_TRUE
        j.range = [0.0, FINGER_OPEN]
        act = spec.add_actuator()
        act.name = name
        act.target = name
        act.trntype = mujoco.mjtTrn.mjTRN_JOINT
        act.gaintype = mujoco.mjtGain.mjGAIN_FIXED
        act.biastype = mujoco.mjtBias.mjBIAS_NONE
        act.gainprm[0] = 1.0
        act.ctrlrange = [-settings.gripper_force, settings.gripper_force]
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
    # The Franka Hand's fingers move together (one motor, a rack): without the coupling a
    # held part slides across the hand with both fingers as the arm accelerates.
    eq = spec.add_equality()
    eq.type = mujoco.mjtEq.mjEQ_JOINT
    eq.objtype = mujoco.mjtObj.mjOBJ_JOINT
    eq.name = "fingers"
    eq.name1, eq.name2 = FINGERS
    eq.data[:5] = [0.0, 1.0, 0.0, 0.0, 0.0]
    eq.solref = list(CONTACT_SOLREF)
    for side in (1.0, -1.0):
        body = spec.body("panda_leftfinger" if side > 0 else "panda_rightfinger")
        pad = body.add_geom()
        pad.name = f"pad_{'left' if side > 0 else 'right'}"
        pad.type = mujoco.mjtGeom.mjGEOM_BOX
        pad.size = list(PAD_HALF)
        pad.pos = [0.0, side * PAD_HALF[1], PAD_Z]
        pad.friction = [settings.friction, 0.02, 0.0001]
        pad.condim = 4
        pad.solref = list(CONTACT_SOLREF)
        pad.solimp = list(CONTACT_SOLIMP)
        pad.mass = 0.0
        pad.rgba = [0.2, 0.2, 0.2, 1.0]
        _contacts(pad, ARM_BITS)
    _wrist_camera(hand)


def _wrist_camera(hand: mujoco.MjsBody) -> None:
    """A camera on the hand looking along the approach between the fingers (image x: hand y)."""
    pos, target = np.asarray(WRIST_CAMERA_POS), np.asarray(WRIST_CAMERA_TARGET)
    z = (pos - target) / np.linalg.norm(pos - target)  # a MuJoCo camera looks along its -z
    x = np.array([0.0, 1.0, 0.0])
    cam = hand.add_camera()
    cam.name = WRIST_CAMERA
    cam.pos = [float(v) for v in pos]
    cam.quat = _quat_wxyz(np.column_stack([x, np.cross(z, x), z]))
    cam.fovy = WRIST_CAMERA_FOVY


def _table(spec: mujoco.MjSpec, cell: CellModel, settings: SimulateSettings) -> None:
    x0, x1, y0, y1 = cell.table_extent
    g = spec.worldbody.add_geom()
    g.name = "table"
    g.type = mujoco.mjtGeom.mjGEOM_BOX
    thickness = 0.05
    g.size = [(x1 - x0) / 2.0, (y1 - y0) / 2.0, thickness / 2.0]
    g.pos = [(x0 + x1) / 2.0, (y0 + y1) / 2.0, cell.table_z - thickness / 2.0]
    g.friction = [settings.part_friction, 0.005, 0.0001]
    g.rgba = [0.55, 0.45, 0.35, 1.0]
    _contacts(g, TABLE_BITS)
    floor = spec.worldbody.add_geom()
    floor.name = "floor"
    floor.type = mujoco.mjtGeom.mjGEOM_PLANE
    floor.size = [3.0, 3.0, 0.1]
    floor.rgba = [0.3, 0.32, 0.35, 1.0]
    _contacts(floor, TABLE_BITS)
    light = spec.worldbody.add_light()
    light.pos = [(x0 + x1) / 2.0, (y0 + y1) / 2.0, cell.table_z + 2.5]
    light.dir = [0.0, 0.0, -1.0]
    light.diffuse = [0.8, 0.8, 0.8]
    light.castshadow = False  # shadows double the software renderer's time per frame


#: Colours of the parts in the video, cycled.
PALETTE = (
    (0.90, 0.62, 0.25, 1.0),
    (0.35, 0.62, 0.85, 1.0),
    (0.45, 0.75, 0.40, 1.0),
    (0.85, 0.40, 0.40, 1.0),
    (0.65, 0.50, 0.80, 1.0),
    (0.85, 0.80, 0.35, 1.0),
)


def _part(spec: mujoco.MjSpec, part: PartModel, settings: SimulateSettings) -> None:
    body = spec.worldbody.add_body()
    body.name = part.name
    body.pos = [float(v) for v in part.pose[:3, 3]]
    body.quat = _quat_wxyz(part.pose[:3, :3])
    if not part.fixed:
        body.add_freejoint()
    evals, evecs = np.linalg.eigh(part.mass.inertia)
    if np.linalg.det(evecs) < 0:
        evecs[:, 2] *= -1.0
    body.explicitinertial = True
    body.mass = part.mass.mass
    body.ipos = [float(v) for v in part.mass.com]
    body.iquat = _quat_wxyz(evecs)
    body.inertia = [float(max(v, 1e-9)) for v in evals]
    colour = PALETTE[sum(map(ord, part.name)) % len(PALETTE)]
    for i, piece in enumerate(part.pieces):
        mesh = spec.add_mesh()
        mesh.name = f"{part.name}:{i}"
        mesh.uservert = piece.vertices.reshape(-1).tolist()
        g = body.add_geom()
        g.name = f"{part.name}:{i}"
        g.type = mujoco.mjtGeom.mjGEOM_MESH
        g.meshname = mesh.name
        g.mass = 0.0
        g.friction = [settings.part_friction, 0.005, 0.0001]
        g.solref = list(CONTACT_SOLREF)
        g.solimp = list(CONTACT_SOLIMP)
        g.rgba = list(colour)
        _contacts(g, PART_BITS)
