"""An executed run as a ROS 2 bag in one MCAP file, for a real arm to follow.

``thirdhand execute TASK --record OUT`` writes ``OUT.json`` (the joint
trajectory, the robot, its base pose, the per-step reports) and ``OUT.parquet``
(the replay: every part's pose over time). :func:`write_mcap` turns the pair
into the topics a ROS 2 integrator plays back with ``ros2 bag play``:

``/joint_trajectory``
    ``trajectory_msgs/msg/JointTrajectory``, one message per step the robot did,
    the arm's joints named as in its URDF (``panda_joint1`` … ``panda_joint7``;
    Baxter's ``right_s0`` … ``right_w2``), the points at the record's rate with
    ``time_from_start`` from the timing law (seconds from the step's start),
    positions and velocities (each motion segment starts and ends at rest); the
    arm's return home after the last step ends that step's trajectory.
``/joint_states``
    ``sensor_msgs/msg/JointState`` at every sample: the arm joints and the joints
    the simulation held still (the Panda's fingers open at 0.04 m, Baxter's
    tucked left arm), so ``robot_state_publisher`` can draw the whole robot.
``/tf``
    ``tf2_msgs/msg/TFMessage`` at every sample: ``world -> <part>`` for every part
    placed at that time, the frames named after the task's objects: a name
    that is a valid frame id and not one of the robot's links is its own frame;
    any other is made one, unique whatever the other names are
    (:func:`frame_ids`: ``leg 3`` beside ``leg_3`` becomes ``leg_3_`` and 8 hex
    digits of the name's hash).
``/tf_static``
    ``world -> <robot root link>`` (``panda_link0``; Baxter's ``base``), the base
    pose the run was planned for, offered with transient-local durability as
    ``tf_static`` is.
``/gripper_command``
    ``control_msgs/msg/GripperCommand`` when the gripper should close on a part
    (``position`` the finger joint's closed limit: 0 m for the Panda) or open
    (the simulation's open value, 0.04 m), ``max_effort`` 0 (the gripper
    controller's default). The simulation attaches a held part to the tool; its
    fingers stay open in ``/joint_states``. Runs recorded before segments said
    what they held have no gripper commands.

Every header stamp and log time is on one clock: the run's ``t = 0`` is 1 s
after the Unix epoch (as :func:`thirdhand.io.rosbag.write` without a start
time), so ``ros2 bag play --clock`` drives nodes that use simulated time.

Only a successful run is exported: a run with a step not done is refused
(:class:`~thirdhand.errors.FormatError`), since playing half an assembly on a
real arm is never what the user wants. The file is written with ``rosbags`` (a
core dependency) through the temp-file-and-rename helpers.
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from thirdhand.arrays import FloatArray
from thirdhand.errors import FormatError
from thirdhand.execute.run_check import UnknownRobotError, robot_description, run_problem
from thirdhand.fileops import atomic_output

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

    from thirdhand.demonstration import Demonstration

PathLike = str | os.PathLike[str]

#: The schema of an ``execute --record`` trajectory file.
TRAJECTORY_SCHEMA = "thirdhand.trajectory/1"
#: The fixed frame every pose is given in.
WORLD_FRAME = "world"
#: Log time of the run's ``t = 0``, nanoseconds since the Unix epoch.
ORIGIN_NS = 1_000_000_000
#: Step statuses that mean the arm moved (its motion is exported).
ROBOT_DONE = "done"
#: Step statuses that count as done (``"done by person"``: no arm motion).
DONE_STATUSES = ("done", "done by person")

_NS = 1_000_000_000
_JOINT_TRAJECTORY = "trajectory_msgs/msg/JointTrajectory"
_JOINT_STATE = "sensor_msgs/msg/JointState"
_TFMESSAGE = "tf2_msgs/msg/TFMessage"
_GRIPPER = "control_msgs/msg/GripperCommand"
#: ``control_msgs/msg/GripperCommand`` (not in rosbags' store; the definition is embedded).
_GRIPPER_MSG = "float64 position\nfloat64 max_effort\n"
#: The finger joint whose position a gripper command sets.
GRIPPER_JOINT = {"panda": "panda_finger_joint1", "baxter": "r_gripper_l_finger_joint"}


@dataclass(frozen=True)
class GripperEvent:
    """The gripper closes on ``part`` (or opens, ``part`` None) at ``t`` seconds."""

    t: float
    part: str | None


@dataclass(frozen=True)
class StepMotion:
    """The arm's motion of one step.

    Attributes
    ----------
    index : int
        The plan step's index.
    constraint, parent, child : str
    first, stop : int
        The step's samples are ``t[first:stop]`` of the run.
    """

    index: int
    constraint: str
    parent: str
    child: str
    first: int
    stop: int


@dataclass(frozen=True)
class ExecutionRecord:
    """An executed run as read back from ``execute --record``.

    Attributes
    ----------
    robot : str
        ``"panda"`` or ``"baxter"``.
    base_pos : ndarray, shape (3,)
        The robot root's position in the world, metres.
    base_quat : ndarray, shape (4,)
        Its orientation, unit quaternion x y z w.
    joint_names : list of str
        The arm's joints, base to tip, as in the URDF.
    t : ndarray, shape (n,)
        Seconds from the start, strictly increasing.
    q : ndarray, shape (n, dof)
        Joint positions, radians.
    velocity : ndarray, shape (n, dof)
        Joint velocities, rad/s: central differences inside each motion segment,
        zero at its ends (every segment is time-parametrised from rest to rest).
    steps : list of StepMotion
        The steps the arm did, in the order it did them.
    n_person_steps : int
        Steps a person did (no arm motion).
    gripper : list of GripperEvent
        The first (open or holding) and every change of what the gripper holds,
        in time order; empty for a record whose segments do not say.
    """

    robot: str
    base_pos: FloatArray
    base_quat: FloatArray
    joint_names: list[str]
    t: FloatArray
    q: FloatArray
    velocity: FloatArray
    steps: list[StepMotion]
    n_person_steps: int
    gripper: list[GripperEvent]


def _num_array(p: Path, doc: dict[str, Any], key: str, ndim: int) -> FloatArray:
    try:
        a = np.asarray(doc[key], dtype=np.float64)
    except (KeyError, TypeError, ValueError):
        raise FormatError(p, f"{key!r}: expected an array of numbers") from None
    if a.ndim != ndim or not np.all(np.isfinite(a)):
        raise FormatError(p, f"{key!r}: expected a {ndim}-d array of finite numbers")
    return a


def read_execution(path: PathLike) -> ExecutionRecord:
    """Read and check an ``execute --record`` trajectory file (``OUT.json``).

    Raises
    ------
    FormatError
        Not a trajectory file, inconsistent arrays, or a run with a step not done
        (a failed run is not exported to a robot: the message names the steps).
    """
    p = Path(path)
    from thirdhand.readlimits import MAX_RUN_BYTES, read_json

    doc = read_json(p, what="run (execute --record)", limit=MAX_RUN_BYTES, strict=True)
    if not isinstance(doc, dict) or doc.get("schema") != TRAJECTORY_SCHEMA:
        got = doc.get("schema") if isinstance(doc, dict) else type(doc).__name__
        raise FormatError(
            p, f"expected an execute --record file (schema {TRAJECTORY_SCHEMA!r}), got {got!r}"
        )
    t = _num_array(p, doc, "t", 1)
    q = _num_array(p, doc, "q", 2)
    names = doc.get("joint_names")
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        raise FormatError(p, "'joint_names': expected a list of strings")
    if q.shape != (t.size, len(names)) or t.size == 0:
        raise FormatError(
            p, f"'q' has shape {q.shape}, expected ({t.size}, {len(names)}) for 't' and the joints"
        )
    try:
        robot = robot_description(str(doc.get("robot")))
    except UnknownRobotError as exc:
        raise FormatError(p, f"'robot' {exc}") from None
    problem = run_problem(robot, names, t, q)
    if problem is not None:
        raise FormatError(p, problem)
    steps = doc.get("steps")
    segments = doc.get("segments")
    if not isinstance(steps, list) or not isinstance(segments, list):
        raise FormatError(p, "expected 'steps' and 'segments' lists")
    listed: dict[int, int] = {}
    for k, s in enumerate(steps):
        if not isinstance(s, dict) or not isinstance(s.get("index"), int):
            raise FormatError(p, f"steps[{k}]: expected a step report with an integer 'index'")
        if s["index"] < 0 or s["index"] in listed:
            why = "is negative" if s["index"] < 0 else f"is also steps[{listed[s['index']]}]"
            raise FormatError(p, f"steps[{k}]: step {s['index']} {why}; each step is listed once")
        listed[s["index"]] = k
    for k, seg in enumerate(segments):
        problem = _segment_problem(seg, t, listed)
        if problem is not None:
            raise FormatError(p, f"segments[{k}]: {problem}")
    not_done = [s for s in steps if s.get("status") not in DONE_STATUSES]
    if not_done or doc.get("success") is not True or not steps:
        detail = "; ".join(
            f"step {s['index']} ({s.get('child')} -> {s.get('parent')}): {s.get('status')}"
            for s in not_done[:3]
        )
        more = f" and {len(not_done) - 3} more" if len(not_done) > 3 else ""
        why = "no step" if not steps else f"success is {doc.get('success')!r}"
        raise FormatError(
            p,
            "the run failed, only a successful run is exported to a robot"
            + (f" ({detail}{more})" if detail else f" ({why})"),
        )
    base = doc.get("base_pose") or {}
    try:
        base_pos = np.asarray(base["pos"], dtype=np.float64).reshape(3)
        base_quat = np.asarray(base["quat"], dtype=np.float64).reshape(4)
    except (KeyError, TypeError, ValueError):
        raise FormatError(p, "'base_pose': expected pos (3 numbers) and quat (4 numbers)") from None
    norm = float(np.linalg.norm(base_quat))
    if not np.isfinite(norm) or abs(norm - 1.0) > 1e-3:
        raise FormatError(p, f"'base_pose.quat' is not a unit quaternion (norm {norm:.4g})")
    velocity = np.zeros_like(q)
    span_of: dict[int, list[int]] = {}
    last: int | None = None
    for k, seg in enumerate(segments):
        try:
            lo, hi = np.searchsorted(t, [seg["t_start"] - 1e-6, seg["t_end"] + 1e-6])
            step = int(seg["step"])
        except (KeyError, TypeError, ValueError):
            raise FormatError(p, f"segments[{k}]: expected step, t_start and t_end") from None
        if step < 0 and last is not None:
            step = last  # the return home (step -1) ends the last step's trajectory
        last = step
        if hi - lo >= 3:
            velocity[lo + 1 : hi - 1] = (q[lo + 2 : hi] - q[lo : hi - 2]) / (
                t[lo + 2 : hi] - t[lo : hi - 2]
            )[:, None]
        span = span_of.setdefault(step, [int(lo), int(hi)])
        span[0], span[1] = min(span[0], int(lo)), max(span[1], int(hi))
    motions = []
    for s in steps:
        if s.get("status") != ROBOT_DONE:
            continue
        lo_hi = span_of.get(int(s["index"]))
        if lo_hi is None or lo_hi[1] - lo_hi[0] < 2:
            raise FormatError(p, f"step {s['index']}: done, but no motion segment in 'segments'")
        motions.append(
            StepMotion(
                index=int(s["index"]),
                constraint=str(s.get("constraint")),
                parent=str(s.get("parent")),
                child=str(s.get("child")),
                first=lo_hi[0],
                stop=lo_hi[1],
            )
        )
    motions.sort(key=lambda m: m.first)
    gripper: list[GripperEvent] = []
    if segments and all("attached" in seg for seg in segments):
        for seg in segments:
            part = seg["attached"] if isinstance(seg["attached"], str) else None
            if not gripper or gripper[-1].part != part:
                gripper.append(GripperEvent(t=float(seg["t_start"]), part=part))
    return ExecutionRecord(
        robot=robot.name,
        base_pos=base_pos,
        base_quat=base_quat / norm,
        joint_names=list(names),
        t=t,
        q=q,
        velocity=velocity,
        steps=motions,
        n_person_steps=sum(s.get("status") == "done by person" for s in steps),
        gripper=gripper,
    )


def _segment_problem(seg: Any, t: FloatArray, steps: dict[int, int]) -> str | None:
    """How a ``segments`` entry is malformed (None if it is not)."""
    if not isinstance(seg, dict):
        return "expected step, t_start and t_end"
    step, span = seg.get("step"), (seg.get("t_start"), seg.get("t_end"))
    if not isinstance(step, int) or not all(isinstance(v, (int, float)) for v in span):
        return "expected an integer step and numbers t_start and t_end"
    lo, hi = float(span[0]), float(span[1])  # type: ignore[arg-type]
    if step != -1 and step not in steps:
        return f"step {step} is not in 'steps' (-1 is the return home)"
    if not (t[0] - 1e-6 <= lo <= hi <= t[-1] + 1e-6):
        return f"[{lo}, {hi}] s is not a time span within the run's [{t[0]}, {t[-1]}] s"
    return None


def replay_path(execution: PathLike) -> Path:
    """The replay ``execute --record`` writes beside the trajectory file."""
    return Path(execution).with_suffix(".parquet")


_FRAME_ID = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*")


def _frame_stem(name: str) -> str:
    parts = re.sub(r"[^A-Za-z0-9_/]", "_", name).split("/")
    parts = [f"_{s}" if s[0].isdigit() else s for s in parts if s]
    return "/".join(parts) or "part"


def frame_ids(names: Sequence[str], *, reserved: Sequence[str] = ()) -> list[str]:
    """Valid tf frame ids for distinct object names, unique by construction.

    A name that is already a valid frame id (``[A-Za-z_][A-Za-z0-9_]*`` parts
    joined by ``/``, no leading ``/``) and not :data:`WORLD_FRAME` or one of
    ``reserved`` (the robot's links) is its own frame. Any other name's
    characters outside ``[A-Za-z0-9_/]`` become ``_`` (``leg 3`` -> ``leg_3``);
    when that stem is a frame another name has, or the stem of another name
    too, it is followed by ``_`` and 8 hex digits of the name's SHA-256
    (``leg 3`` beside ``leg_3`` -> ``leg_3_…``). So a name's frame does not
    depend on the order of the names, and two names never share a frame.

    Raises
    ------
    FormatError
        Two names given twice, or mapped to one frame (a broken invariant).
    """
    import hashlib
    from collections import Counter

    taken = {WORLD_FRAME, *reserved}
    own = {n for n in names if _FRAME_ID.fullmatch(n) and n not in taken}
    stems = {n: _frame_stem(n) for n in names if n not in own}
    shared = Counter(stems.values())
    out = []
    for n in names:
        frame = n
        if n not in own:
            frame = stems[n]
            if frame in taken or frame in own or shared[frame] > 1:
                frame = f"{frame}_{hashlib.sha256(n.encode()).hexdigest()[:8]}"
        out.append(frame)
    if len(set(out)) != len(out) or taken & set(out) or len(set(names)) != len(names):
        raise FormatError("frames", f"no distinct tf frames for the objects {list(names)}")
    return out


def robot_joints(robot: str) -> tuple[str, dict[str, float], tuple[float, float]]:
    """The robot's root link, the joints the simulation held still, the gripper's range.

    Returns
    -------
    root_link : str
    held : dict of str to float
        Joint name to its value in the simulation (rad or m).
    gripper : (float, float)
        :data:`GRIPPER_JOINT`'s open (the simulation's) and closed (its other
        limit) positions.

    Raises
    ------
    FormatError
        For a robot thirdhand does not simulate.
    """
    try:
        desc = robot_description(robot)
    except UnknownRobotError as exc:
        raise FormatError(robot, str(exc)) from None
    finger = GRIPPER_JOINT[robot]
    opened = desc.held[finger]
    closed = max(desc.finger_limits[finger], key=lambda b: abs(b - opened))
    return desc.root_link, dict(desc.held), (opened, closed)


def _stamp(store: Typestore, ns: int) -> Any:
    return store.types["builtin_interfaces/msg/Time"](sec=ns // _NS, nanosec=ns % _NS)


def _header(store: Typestore, ns: int, frame: str) -> Any:
    return store.types["std_msgs/msg/Header"](stamp=_stamp(store, ns), frame_id=frame)


def _transform(store: Typestore, ns: int, child: str, pos: Any, quat: Any) -> Any:
    types = store.types
    x, y, z = (float(v) for v in pos)
    qx, qy, qz, qw = (float(v) for v in quat)
    return types["geometry_msgs/msg/TransformStamped"](
        header=_header(store, ns, WORLD_FRAME),
        child_frame_id=child,
        transform=types["geometry_msgs/msg/Transform"](
            translation=types["geometry_msgs/msg/Vector3"](x=x, y=y, z=z),
            rotation=types["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw),
        ),
    )


def _messages(
    run: ExecutionRecord,
    replay: Demonstration,
    store: Typestore,
    *,
    root_link: str,
    held: dict[str, float],
    gripper: tuple[float, float],
) -> list[tuple[int, str, Any]]:
    """``(log time ns, topic, message)`` sorted by time (``/tf_static`` first)."""
    types = store.types
    stamps = ORIGIN_NS + np.round(run.t * _NS).astype(np.int64)
    out: list[tuple[int, str, Any]] = []
    base = _transform(store, int(stamps[0]), root_link, run.base_pos, run.base_quat)
    out.append((int(stamps[0]), "/tf_static", types[_TFMESSAGE](transforms=[base])))
    names = [*run.joint_names, *held]
    held_q = np.array(list(held.values()), dtype=np.float64)
    zeros = np.zeros(len(held))
    for i, ns in enumerate(stamps.tolist()):
        msg = types[_JOINT_STATE](
            header=_header(store, ns, ""),
            name=names,
            position=np.concatenate([run.q[i], held_q]),
            velocity=np.concatenate([run.velocity[i], zeros]),
            effort=np.zeros(0),
        )
        out.append((ns, "/joint_states", msg))
    parts = [b.name for b in replay.bodies if b.kind == "part"]
    links = robot_description(run.robot).links
    frames = dict(zip(parts, frame_ids(parts, reserved=links), strict=True))
    pos = {n: replay.pos(n) for n in parts}
    quat = {n: replay.quat(n) for n in parts}
    seen = {
        n: np.all(np.isfinite(pos[n]), axis=1) & np.all(np.isfinite(quat[n]), axis=1) for n in parts
    }
    for i, ns in enumerate(_replay_stamps(replay, run).tolist()):
        transforms = [
            _transform(store, ns, frames[n], pos[n][i], quat[n][i]) for n in parts if seen[n][i]
        ]
        if transforms:
            out.append((ns, "/tf", types[_TFMESSAGE](transforms=transforms)))
    point_t, dur_t = (
        types["trajectory_msgs/msg/JointTrajectoryPoint"],
        types["builtin_interfaces/msg/Duration"],
    )
    for step in run.steps:
        sl = slice(step.first, step.stop)
        since = np.round((run.t[sl] - run.t[step.first]) * _NS).astype(np.int64).tolist()
        points = [
            point_t(
                positions=run.q[step.first + k],
                velocities=run.velocity[step.first + k],
                accelerations=np.zeros(0),
                effort=np.zeros(0),
                time_from_start=dur_t(sec=d // _NS, nanosec=d % _NS),
            )
            for k, d in enumerate(since)
        ]
        ns = int(stamps[step.first])
        msg = types[_JOINT_TRAJECTORY](
            header=_header(store, ns, WORLD_FRAME), joint_names=run.joint_names, points=points
        )
        out.append((ns, "/joint_trajectory", msg))
    for ev in run.gripper:
        ns = ORIGIN_NS + round(ev.t * _NS)
        position = gripper[0] if ev.part is None else gripper[1]
        out.append((ns, "/gripper_command", types[_GRIPPER](position=position, max_effort=0.0)))
    order = {
        "/tf_static": 0,
        "/gripper_command": 1,
        "/joint_trajectory": 2,
        "/joint_states": 3,
        "/tf": 4,
    }
    out.sort(key=lambda m: (m[0], order[m[1]]))
    return out


def _replay_stamps(replay: Demonstration, run: ExecutionRecord) -> NDArray[np.int64]:
    if replay.n_frames != run.t.size or not np.allclose(replay.t, run.t, atol=1e-5):
        raise FormatError(
            "replay",
            f"the replay has {replay.n_frames} frames, the trajectory {run.t.size} samples: "
            "not the same run (execute --record writes both)",
        )
    return ORIGIN_NS + np.round(run.t * _NS).astype(np.int64)


def write_mcap(execution: PathLike, target: PathLike) -> dict[str, int]:
    """Write an executed run (``execute --record`` ``OUT.json``) as a ROS 2 MCAP file.

    Parameters
    ----------
    execution : path-like
        The trajectory file; the replay ``OUT.parquet`` must be beside it.
    target : path-like
        The ``.mcap`` file to write (atomically; an existing one is kept as a
        numbered backup: the caller checks ``--force``).

    Returns
    -------
    dict of str to int
        Messages written per topic.

    Raises
    ------
    FormatError
        A failed run, a malformed record, or a missing or mismatched replay.
    """
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability
    from rosbags.interfaces import QosTime as _QosTime
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    from thirdhand import io

    run = read_execution(execution)
    replay_file = replay_path(execution)
    if not replay_file.is_file():
        raise FormatError(
            execution, f"no replay {replay_file.name} beside it (execute --record writes both)"
        )
    replay = io.load(replay_file)
    try:
        root_link, held, gripper = robot_joints(run.robot)
    except FormatError as exc:
        raise FormatError(execution, f"'robot' {exc.message}") from None
    store = get_typestore(Stores.LATEST)
    store.register(get_types_from_msg(_GRIPPER_MSG, _GRIPPER))
    try:
        messages = _messages(run, replay, store, root_link=root_link, held=held, gripper=gripper)
    except FormatError as exc:
        raise FormatError(replay_file, exc.message) from None
    never = _QosTime(sec=0, nsec=0)
    latched = Qos(
        QosHistory.KEEP_LAST,
        1,
        QosReliability.RELIABLE,
        QosDurability.TRANSIENT_LOCAL,
        never,
        never,
        QosLiveliness.AUTOMATIC,
        never,
        False,
    )
    types = {
        "/tf_static": _TFMESSAGE,
        "/joint_trajectory": _JOINT_TRAJECTORY,
        "/joint_states": _JOINT_STATE,
        "/tf": _TFMESSAGE,
    }
    if run.gripper:
        types["/gripper_command"] = _GRIPPER
    counts = dict.fromkeys(types, 0)
    target = Path(target)
    with atomic_output(target) as built:
        folder = built.parent / target.stem
        with Writer(folder, version=Writer.VERSION_LATEST, storage_plugin=StoragePlugin.MCAP) as w:
            conns = {
                topic: w.add_connection(
                    topic,
                    typ,
                    typestore=store,
                    offered_qos_profiles=[latched] if topic == "/tf_static" else (),
                )
                for topic, typ in types.items()
            }
            for ns, topic, msg in messages:
                w.write(conns[topic], ns, store.serialize_cdr(msg, types[topic]))
                counts[topic] += 1
        os.rename(folder / f"{target.stem}.mcap", built)
    return counts
