"""Rerun recordings (``.rrd``): a demonstration and what was learned from it on one timeline.

Open the file with ``rerun out.rrd`` (the viewer of the ``rerun-sdk`` package,
the optional extra ``thirdhand[rerun]``). Entities and timelines written:

- ``world/bodies/<body>`` (timeline ``time``): the pose at every tracked frame
  (``Transform3D``) and axes; a gap holds no sample.
- ``world/bodies/<body>/mesh`` (static): the part's mesh, or its bounding box,
  when the task knows it.
- ``world/paths/<body>`` (static): the body's path, split at gaps.
- ``phases/labels/<a>--<b>`` (``time``): ground-truth interaction, 0/1 per frame.
- ``phases/segmented/<a>--<b>/{probability,label}`` (``time``): a
  ``thirdhand.phases/1`` file's pairs (a null probability is no sample).
- ``keyframes`` (``time``): one text marker per plan step.
- ``world/keyframes/<body>`` (timelines ``time`` at each step's time, and
  ``plan_step``, the step's number): every body's pose in the step's keyframe
  (the assembly as it was when the step's constraint appeared), drawn as a
  translucent copy of the part's mesh or box (``…/shape``, static); on the
  ``time`` timeline the last keyframe stays shown until the next one.
- ``world/bodies/<parent>/constraints/<id>`` (static): the learned constraint,
  the child's pose in the parent; under it ``frame`` (the constraint frame, with
  axes), ``frame/free/translation`` (an arrow per free translation spanning its
  range), ``frame/free/rotation`` (an arc per free rotation over its range) and
  ``frame/label``.
- ``execution/joints/<joint>`` (timeline ``execution_time``): the robot's joint
  trajectory, radians.
- ``execution/bodies/<body>`` (``execution_time``): the replay's poses
  (``OUT.parquet`` beside ``OUT.json``).
- ``live/steps`` (``time``): a live run's recognised and undone steps
  (``thirdhand live … --record OUT``'s ``OUT.json``, ``recognised``).
- ``execution/robot/<shape>`` (``execution_time``): the arm as the planner saw
  it, every collision shape of the robot (:mod:`thirdhand.export.robot_model`;
  cylinders, spheres, boxes, meshes, static) at its world pose per sample. The
  robot's root pose comes from the record (``base_pose``; with ``base_pos``, a live
  run whose base drove, the root's position at every sample), or, for records made
  before it was stored, from the replay's tool frame.

Body names are escaped into one entity-path part each (``/human/rh/thumb``
becomes ``\\/human\\/rh\\/thumb``). Times are seconds on the demonstration's
axis (``execution_time``: seconds of the executed run).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from thirdhand.arrays import FloatArray
from thirdhand.demonstration import Demonstration
from thirdhand.errors import FormatError, OutputError
from thirdhand.readlimits import MAX_RUN_BYTES, MAX_SIDE_BYTES, loads_json, read_text_input

if TYPE_CHECKING:
    from thirdhand.execute.robot import Robot
    from thirdhand.taskfile import TaskFile


#: Length of the axes drawn at every body, metres.
AXIS_LENGTH = 0.05
#: Radius of the arcs drawn for free rotations, metres.
ARC_RADIUS = 0.04
#: Timeline of the demonstration and of an executed run.
TIMELINE = "time"
EXECUTION_TIMELINE = "execution_time"
#: Sequence timeline of the plan's keyframes (1 = the first step).
STEP_TIMELINE = "plan_step"
#: Colours (RGBA) of the keyframe ghosts and of the robot's shapes.
KEYFRAME_RGBA = (90, 160, 230, 90)
ROBOT_RGBA = (235, 235, 235, 255)


def body_path(name: str, root: str = "world/bodies") -> str:
    """The entity path of a body (its name escaped into one path part)."""
    import rerun as rr

    return f"{root}/{rr.escape_entity_path_part(name)}"


def _runs(valid: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """``[start, end)`` index ranges of consecutive True values."""
    d = np.diff(np.concatenate([[0], valid.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1), strict=True))


def _log_bodies(rec: Any, demo: Demonstration, root: str, timeline: str, paths: bool) -> None:
    import rerun as rr

    for name in demo.body_names:
        v = demo.valid(name)
        entity = body_path(name, root)
        rec.log(entity, rr.TransformAxes3D(AXIS_LENGTH), static=True)
        if not v.any():
            continue
        rec.send_columns(
            entity,
            indexes=[rr.TimeColumn(timeline, duration=demo.t[v])],
            columns=rr.Transform3D.columns(
                translation=demo.pos(name)[v], quaternion=demo.quat(name)[v]
            ),
        )
        if paths:
            p = demo.pos(name)
            strips = [p[a:b] for a, b in _runs(v) if b - a >= 2]
            if strips:
                rec.log(body_path(name, "world/paths"), rr.LineStrips3D(strips), static=True)


def _log_label_phases(rec: Any, demo: Demonstration) -> int:
    import rerun as rr

    n = 0
    for a, b in demo.labels.interaction_pairs():
        on = np.zeros(demo.n_frames)
        for i in demo.labels.interactions:
            if (i.a, i.b) == (a, b):
                on[(demo.t >= i.start) & (demo.t <= i.end)] = 1.0
        rec.send_columns(
            f"phases/labels/{_pair(a, b)}",
            indexes=[rr.TimeColumn(TIMELINE, duration=demo.t)],
            columns=rr.Scalars.columns(scalars=on),
        )
        n += 1
    return n


def _pair(a: str, b: str) -> str:
    import rerun as rr

    return rr.escape_entity_path_part(f"{a}--{b}")


def read_phases(path: Path) -> dict[str, Any]:
    """A ``thirdhand.phases/1`` file (``thirdhand segment --json``), checked."""

    def error(message: str) -> FormatError:
        return FormatError(path, f"not a readable phases JSON file: {message}")

    doc = loads_json(
        read_text_input(path, what="phases file", limit=MAX_SIDE_BYTES, error=error), error=error
    )
    if not isinstance(doc, dict) or doc.get("format") != "thirdhand.phases/1":
        raise FormatError(path, "expected a thirdhand.phases/1 file (thirdhand segment --json)")
    t = doc.get("time")
    if not isinstance(t, list) or not isinstance(doc.get("pairs"), list):
        raise FormatError(path, "a phases file needs a 'time' list and a 'pairs' list")
    for k, pair in enumerate(doc["pairs"]):
        label = pair.get("label") if isinstance(pair, dict) else None
        if not isinstance(label, list) or len(label) != len(t):
            raise FormatError(
                path, f"pair {k}: 'label' must have one value per time", where="pairs"
            )
    return doc


def _log_segmented_phases(rec: Any, doc: dict[str, Any]) -> int:
    import rerun as rr

    t = np.asarray(doc["time"], dtype=np.float64)
    for pair in doc["pairs"]:
        base = f"phases/segmented/{_pair(str(pair['a']), str(pair['b']))}"
        label = np.asarray(pair["label"], dtype=np.float64)
        rec.send_columns(
            f"{base}/label",
            indexes=[rr.TimeColumn(TIMELINE, duration=t)],
            columns=rr.Scalars.columns(scalars=label),
        )
        prob = pair.get("probability")
        if isinstance(prob, list) and len(prob) == t.size:
            pv = np.asarray([np.nan if x is None else x for x in prob], dtype=np.float64)
            ok = np.isfinite(pv)
            if ok.any():
                rec.send_columns(
                    f"{base}/probability",
                    indexes=[rr.TimeColumn(TIMELINE, duration=t[ok])],
                    columns=rr.Scalars.columns(scalars=pv[ok]),
                )
    return len(doc["pairs"])


def _arc(axis: int, lo: float, hi: float) -> FloatArray:
    """Points of an arc about coordinate ``axis`` from angle ``lo`` to ``hi`` (radians)."""
    n = max(4, int(np.ceil(abs(hi - lo) / np.radians(5))) + 1)
    a = np.linspace(lo, hi, n)
    u, w = [(1, 2), (2, 0), (0, 1)][axis]
    pts = np.zeros((n, 3))
    pts[:, u] = ARC_RADIUS * np.cos(a)
    pts[:, w] = ARC_RADIUS * np.sin(a)
    return pts


def _log_constraints(rec: Any, task: TaskFile, bodies: Sequence[str]) -> int:
    import rerun as rr

    colours = np.array([[230, 60, 60], [60, 200, 60], [60, 90, 230]], dtype=np.uint8)
    n = 0
    for c in task.constraints:
        parent = body_path(c.parent) if c.parent in bodies else "world"
        entity = f"{parent}/constraints/{rr.escape_entity_path_part(c.id)}"
        # child pose in the parent, then the constraint frame in the child
        rec.log(
            entity,
            rr.Transform3D(translation=c.pos, quaternion=rr.Quaternion(xyzw=c.quat)),
            static=True,
        )
        frame = f"{entity}/frame"
        rec.log(
            frame,
            rr.Transform3D(translation=c.frame.pos, quaternion=rr.Quaternion(xyzw=c.frame.quat)),
            rr.TransformAxes3D(AXIS_LENGTH),
            static=True,
        )
        ranges = c.free_dof_array()
        origins, vectors, arrow_colours, labels = [], [], [], []
        strips, strip_colours = [], []
        for k in range(3):
            lo, hi = ranges[k]
            if hi > lo:
                start = np.zeros(3)
                start[k] = lo
                vec = np.zeros(3)
                vec[k] = hi - lo
                origins.append(start)
                vectors.append(vec)
                arrow_colours.append(colours[k])
                labels.append(f"t{'xyz'[k]} [{lo:.3g}, {hi:.3g}] m")
        for k in range(3):
            lo, hi = ranges[3 + k]
            if hi > lo:
                strips.append(_arc(k, lo, hi))
                strip_colours.append(colours[k])
        if origins:
            rec.log(
                f"{frame}/free/translation",
                rr.Arrows3D(origins=origins, vectors=vectors, colors=arrow_colours, labels=labels),
                static=True,
            )
        if strips:
            rec.log(
                f"{frame}/free/rotation",
                rr.LineStrips3D(strips, colors=strip_colours),
                static=True,
            )
        rec.log(
            f"{frame}/label",
            rr.TextDocument(
                f"{c.id}: {c.type} {c.parent} -> {c.child}"
                + (f" ({c.symbol})" if c.symbol else "")
                + f", confidence {c.confidence:.2f}"
            ),
            static=True,
        )
        n += 1
    return n


def _log_keyframes(rec: Any, task: TaskFile, shapes: dict[str, Any]) -> int:
    """Text markers per step; every keyframe's body poses, on ``time`` and ``plan_step``."""
    import rerun as rr

    steps = [(i, s) for i, s in enumerate(task.plan) if s.time is not None]
    for i, s in steps:
        rec.set_time(TIMELINE, duration=float(s.time))  # type: ignore[arg-type]
        sym = f", {s.symbol}" if s.symbol else ""
        rec.log("keyframes", rr.TextLog(f"step {i + 1}: {s.action}({s.parent}, {s.child}{sym})"))
    rec.reset_time()
    posed: set[str] = set()
    for i, s in enumerate(task.plan):
        for body, pose in s.keyframe.items():
            entity = body_path(body, "world/keyframes")
            rec.reset_time()
            rec.set_time(STEP_TIMELINE, sequence=i + 1)
            if s.time is not None:
                rec.set_time(TIMELINE, duration=float(s.time))
            rec.log(
                entity,
                rr.Transform3D(translation=pose.pos, quaternion=rr.Quaternion(xyzw=pose.quat)),
            )
            posed.add(body)
    rec.reset_time()
    for body in sorted(posed):
        if body in shapes:
            rec.log(f"{body_path(body, 'world/keyframes')}/shape", shapes[body], static=True)
    return len(steps)


def _object_meshes(task: TaskFile, task_path: Path | None) -> dict[str, FloatArray]:
    """Triangles ``(F, 3, 3)`` of every object the task can draw (mesh file or box)."""
    from thirdhand.task.meshes import object_triangles

    out = {}
    for obj in task.objects:
        tri = object_triangles(obj, task_path)
        if tri is not None:
            out[obj.name] = np.asarray(tri, dtype=np.float64).reshape(-1, 3, 3)
    return out


def _mesh(tri: FloatArray, rgba: Sequence[int]) -> Any:
    import rerun as rr

    verts = np.asarray(tri, dtype=np.float32).reshape(-1, 3)
    return rr.Mesh3D(
        vertex_positions=verts,
        triangle_indices=np.arange(verts.shape[0], dtype=np.uint32).reshape(-1, 3),
        albedo_factor=[c / 255 for c in rgba],
    )


def _log_meshes(rec: Any, meshes: dict[str, FloatArray], bodies: Sequence[str]) -> int:
    n = 0
    for name, tri in meshes.items():
        if name not in bodies:
            continue
        rec.log(f"{body_path(name)}/mesh", _mesh(tri, (191, 178, 153, 153)), static=True)
        n += 1
    return n


def read_execution(path: Path) -> dict[str, Any]:
    """An executed run's ``OUT.json`` (``thirdhand execute --record OUT``), checked."""

    def error(message: str) -> FormatError:
        return FormatError(path, f"not a readable execution JSON file: {message}")

    doc = loads_json(
        read_text_input(path, what="execution file", limit=MAX_RUN_BYTES, error=error), error=error
    )
    if not isinstance(doc, dict) or "t" not in doc or "q" not in doc:
        raise FormatError(path, "expected an execution file with 't' and 'q' (thirdhand execute)")
    t, q = _joint_arrays(doc)
    if t.ndim != 1 or q.ndim != 2 or q.shape[0] != t.size:
        raise FormatError(path, f"'q' must have one row per time: {q.shape} for {t.size} times")
    problem = _robot_problem(doc, t, q)
    if problem is not None:
        raise FormatError(path, problem)
    steps = doc.get("recognised", [])
    if not isinstance(steps, list) or not all(
        isinstance(s, dict) and isinstance(s.get("t"), (int, float)) for s in steps
    ):
        raise FormatError(path, "'recognised' must be a list of {'t': seconds, ...}")
    if "base_pose" in doc and not _is_pose(doc["base_pose"]):
        raise FormatError(
            path, "'base_pose' must be {'pos': [x, y, z], 'quat': [x, y, z, w]}, finite, unit"
        )
    if "base_pos" in doc:
        try:
            moved = np.asarray(doc["base_pos"], dtype=np.float64)
        except (TypeError, ValueError):
            moved = np.zeros(0)
        if moved.shape != (t.size, 3) or not np.all(np.isfinite(moved)) or "base_pose" not in doc:
            raise FormatError(
                path, f"'base_pos' must be {t.size} finite [x, y, z] rows, beside a 'base_pose'"
            )
    return doc


def _robot_problem(doc: dict[str, Any], t: FloatArray, q: FloatArray) -> str | None:
    """How a run that names a robot thirdhand simulates contradicts it (None if not).

    Joint names, limits and times (:func:`~thirdhand.execute.run_check.run_problem`);
    velocities for an executed run (a live run's arm follows the person, sampled
    at the stream's frames, and is not held to them here; its times are checked
    from its first sample, the stream's clock need not start at 0).
    """
    from thirdhand.execute.robot import ROBOTS
    from thirdhand.execute.run_check import robot_description, run_problem

    name = doc.get("robot")
    if not isinstance(name, str) or name not in ROBOTS or q.size == 0:
        return None
    names = doc.get("joint_names")
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        return "'joint_names': expected a list of strings"
    live = doc.get("source") == "thirdhand.live"
    if live and t.size:  # on the stream's clock, which need not start at 0
        t = t - t[0]
    return run_problem(robot_description(name), names, t, q, velocities=not live)


def _joint_arrays(doc: dict[str, Any]) -> tuple[FloatArray, FloatArray]:
    """``t`` (n,) seconds and ``q`` (n, dof) radians of a run file; (0,) and (0, 0) for a
    live run without the arm."""
    t = np.asarray(doc["t"], dtype=np.float64)
    q = np.asarray(doc["q"], dtype=np.float64)
    if t.size == 0 and q.size == 0:
        q = q.reshape(0, 0)
    return t, q


def _is_pose(value: Any) -> bool:
    """``{"pos": 3 finite numbers, "quat": 4 finite numbers of unit norm}``."""
    if not isinstance(value, dict):
        return False
    try:
        pos = np.asarray(value.get("pos"), dtype=np.float64)
        quat = np.asarray(value.get("quat"), dtype=np.float64)
    except (TypeError, ValueError):
        return False
    return (
        pos.shape == (3,)
        and quat.shape == (4,)
        and bool(np.all(np.isfinite(pos)) and np.all(np.isfinite(quat)))
        and abs(float(np.linalg.norm(quat)) - 1.0) < 1e-6
    )


def _robot_base(doc: dict[str, Any], replay: Demonstration | None, arm: Robot) -> FloatArray | None:
    """``T_world_root`` of the recorded arm: stored, else from the replay's tool frame.

    ``arm`` is the robot loaded with its root at the world origin.
    """
    from thirdhand import se3
    from thirdhand.execute.record import TOOL_BODY

    base = doc.get("base_pose")
    if base is not None:
        return se3.matrix_from_pose(np.asarray(base["pos"]), np.asarray(base["quat"]))
    if replay is None or TOOL_BODY not in replay.body_names:
        return None
    from thirdhand.export.robot_model import base_from_tool

    t = np.asarray(doc["t"], dtype=np.float64)
    valid = np.flatnonzero(replay.valid(TOOL_BODY))
    if valid.size == 0:
        return None
    k = int(valid[0])
    j = int(np.argmin(np.abs(t - replay.t[k])))
    if abs(t[j] - replay.t[k]) > 1e-3:  # the two files sample the same run at the same times
        return None
    tool = se3.matrix_from_pose(replay.pos(TOOL_BODY)[k], replay.quat(TOOL_BODY)[k])
    return base_from_tool(arm, np.asarray(doc["q"][j], dtype=np.float64), tool)


def _robot_archetype(shape: Any) -> Any:
    import rerun as rr

    colour = [ROBOT_RGBA]
    if shape.kind == "cylinder":
        return rr.Cylinders3D(
            lengths=[shape.size[1]], radii=[shape.size[0]], colors=colour, fill_mode="solid"
        )
    if shape.kind == "sphere":
        r = float(shape.size[0])
        return rr.Ellipsoids3D(half_sizes=[[r, r, r]], colors=colour, fill_mode="solid")
    if shape.kind == "box":
        return rr.Boxes3D(half_sizes=[shape.size], colors=colour, fill_mode="solid")
    return rr.Mesh3D(
        vertex_positions=np.asarray(shape.vertices, dtype=np.float32),
        triangle_indices=shape.triangles,
        albedo_factor=[c / 255 for c in ROBOT_RGBA],
    )


def _log_robot(rec: Any, doc: dict[str, Any], replay: Demonstration | None, path: Path) -> int:
    """The arm's collision shapes over the run; 0 when the record names no known robot."""
    import rerun as rr

    from thirdhand import se3
    from thirdhand.execute.robot import ROBOTS, Robot
    from thirdhand.export.robot_model import robot_shapes, shape_transforms

    name = doc.get("robot")
    if name not in ROBOTS:
        return 0
    arm = Robot.load(str(name))  # root at the world origin; the base is applied below
    base = _robot_base(doc, replay, arm)
    if base is None:
        return 0
    t, q = _joint_arrays(doc)
    if q.shape[1] != arm.dof:
        raise FormatError(path, f"'q' has {q.shape[1]} joints; {name} has {arm.dof}")
    shapes = robot_shapes(arm)
    if "base_pos" in doc:  # a base that drove: the root's position at every sample
        base = np.repeat(base[None], t.size, axis=0)
        base[:, :3, 3] = np.asarray(doc["base_pos"], dtype=np.float64)
        poses = base[:, None] @ shape_transforms(arm, shapes, q)
    else:
        poses = base @ shape_transforms(arm, shapes, q)  # every shape moves with the root
    for k, shape in enumerate(shapes):
        entity = f"execution/robot/{rr.escape_entity_path_part(shape.name)}"
        rec.log(entity, _robot_archetype(shape), static=True)
        pos, quat = se3.pose_from_matrix(poses[:, k])
        rec.send_columns(
            entity,
            indexes=[rr.TimeColumn(EXECUTION_TIMELINE, duration=t)],
            columns=rr.Transform3D.columns(translation=pos, quaternion=quat),
        )
    return len(shapes)


def _log_execution(rec: Any, doc: dict[str, Any], path: Path) -> tuple[int, int]:
    """The joint scalars, the replay's bodies and the robot; (joints, robot shapes) written."""
    import rerun as rr

    for s in doc.get("recognised", []):  # a live run's steps, on the stream's clock
        rec.set_time(TIMELINE, duration=float(s["t"]))
        verb = "recognised" if s.get("kind") == "formed" else "undone"
        rec.log(
            "live/steps",
            rr.TextLog(
                f"step {s.get('step')} {verb}: {s.get('constraint')} "
                f"({s.get('parent')} <- {s.get('child')})"
            ),
        )
    rec.reset_time()
    t, q = _joint_arrays(doc)
    names = doc.get("joint_names") or doc.get("joints") or [f"q{i}" for i in range(q.shape[1])]
    for j, name in enumerate(names[: q.shape[1]]):
        rec.send_columns(
            f"execution/joints/{rr.escape_entity_path_part(str(name))}",
            indexes=[rr.TimeColumn(EXECUTION_TIMELINE, duration=t)],
            columns=rr.Scalars.columns(scalars=q[:, j]),
        )
    replay_path = path.with_suffix(".parquet")
    replay = None
    if replay_path.is_file():
        from thirdhand import io

        replay = io.load(replay_path)
        _log_bodies(rec, replay, "execution/bodies", EXECUTION_TIMELINE, paths=False)
    return q.shape[1], _log_robot(rec, doc, replay, path)


def _foreign_phases(doc: dict[str, Any], known: set[str]) -> str | None:
    """Why a phases file is not of this task's bodies (None when it is)."""
    for k, pair in enumerate(doc["pairs"]):
        for role in ("a", "b"):
            name = pair.get(role)
            if name not in known:
                return (
                    f"pairs[{k}].{role}: {name!r} is a body of neither the task nor its "
                    "recording: the phases of another task"
                )
    return None


def _foreign_run(doc: dict[str, Any], task: TaskFile) -> str | None:
    """Why a run file is not a run of this task (None when it is)."""
    objects = {o.name for o in task.objects}
    ids = {c.id for c in task.constraints}
    for key in ("steps", "recognised"):
        for k, s in enumerate(doc.get(key) or []):
            if not isinstance(s, dict):
                continue
            for role in ("parent", "child"):
                if role in s and s[role] not in objects:
                    return (
                        f"{key}[{k}].{role}: {s[role]!r} is not an object of the task: "
                        "a run of another task"
                    )
            if s.get("constraint") is not None and s["constraint"] not in ids:
                return (
                    f"{key}[{k}].constraint: {s['constraint']!r} is not a constraint of the "
                    "task: a run of another task"
                )
    return None


def write_rrd(
    path: str | os.PathLike[str],
    demo: Demonstration | None,
    *,
    task: TaskFile | None = None,
    task_path: Path | None = None,
    phases: Path | None = None,
    execution: Path | None = None,
    name: str = "thirdhand",
) -> dict[str, int]:
    """Write a Rerun recording (see the module documentation).

    Parameters
    ----------
    path : path-like
        The ``.rrd`` file; its folder must exist. Written atomically.
    demo : Demonstration or None
        The recording; None writes only the task (and execution).
    task : TaskFile, optional
        Learned constraints, plan (keyframes) and object meshes.
    task_path : Path, optional
        The task file, for meshes named relative to it.
    phases : Path, optional
        A ``thirdhand.phases/1`` file.
    execution : Path, optional
        ``OUT.json`` of ``thirdhand execute --record OUT``.
    name : str
        The recording's application id.

    Returns
    -------
    dict
        Counts of what was written: ``bodies``, ``label_pairs``, ``segmented_pairs``,
        ``keyframes``, ``constraints``, ``meshes``, ``joints``, ``robot_shapes``.

    Raises
    ------
    OutputError
        The target's folder does not exist, or the file cannot be written.
    FormatError
        A phases file naming bodies of neither the task nor the recording, or a run
        whose steps name objects or constraints the task lacks (another task's).
    """
    import rerun as rr

    from thirdhand.fileops import atomic_output

    p = Path(path)
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        raise OutputError(f"{p}: the folder {folder} does not exist")
    phases_doc = read_phases(phases) if phases is not None else None
    exec_doc = read_execution(execution) if execution is not None else None
    known = (
        {*(demo.body_names if demo is not None else ()), *(o.name for o in task.objects)}
        if (task is not None)
        else None
    )
    if phases_doc is not None and phases is not None and known is not None:
        problem = _foreign_phases(phases_doc, known)
        if problem is not None:
            raise FormatError(phases, problem)
    if exec_doc is not None and execution is not None and task is not None:
        problem = _foreign_run(exec_doc, task)
        if problem is not None:
            raise FormatError(execution, problem)
    counts = dict.fromkeys(
        (
            "bodies",
            "label_pairs",
            "segmented_pairs",
            "keyframes",
            "constraints",
            "meshes",
            "joints",
            "robot_shapes",
        ),
        0,
    )
    with atomic_output(p) as tmp:
        rec = rr.RecordingStream(name, recording_id=f"{name}-{p.stem}")
        rec.save(str(tmp))
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        bodies: list[str] = []
        if demo is not None:
            bodies = demo.body_names
            _log_bodies(rec, demo, "world/bodies", TIMELINE, paths=True)
            counts["bodies"] = len(bodies)
            counts["label_pairs"] = _log_label_phases(rec, demo)
        if phases_doc is not None:
            counts["segmented_pairs"] = _log_segmented_phases(rec, phases_doc)
        if task is not None:
            meshes = _object_meshes(task, task_path)
            ghosts = {n: _mesh(tri, KEYFRAME_RGBA) for n, tri in meshes.items()}
            counts["keyframes"] = _log_keyframes(rec, task, ghosts)
            counts["constraints"] = _log_constraints(rec, task, bodies)
            counts["meshes"] = _log_meshes(rec, meshes, bodies)
        if exec_doc is not None and execution is not None:
            counts["joints"], counts["robot_shapes"] = _log_execution(rec, exec_doc, execution)
        rec.flush()
        rec.disconnect()
    return counts


def missing_extra() -> str | None:
    """A one-line message when the ``rerun`` extra is not installed, else None."""
    try:
        import rerun  # noqa: F401
    except ImportError:
        return "writing .rrd needs the rerun extra: pip install 'thirdhand[rerun]'"
    return None
