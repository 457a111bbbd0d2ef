"""An execution record in the review GUI: the robot's run replayed on the task's scene.

``thirdhand execute TASK --record OUT`` writes ``OUT.parquet`` (a
:class:`~thirdhand.demonstration.Demonstration` of the task's parts and the
robot's tool frame, :data:`~thirdhand.execute.record.TOOL_BODY`, world frame,
metres) and ``OUT.json`` (the joint trajectory and the per-step reports).
:func:`load_replay` reads both and checks they belong to the task under review;
:func:`robot_contacts` says which part the robot holds when (the part that moves:
in a record only the held part moves), so playback colours it as held.

The robot's links are not drawn (their meshes would take the software-WebGL
view from ~1 frame/s down further): the tool frame is drawn as axes, and the
held part at its recorded pose.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from thirdhand.demonstration import Demonstration
from thirdhand.errors import ThirdhandError
from thirdhand.execute.record import TOOL_BODY, record_paths
from thirdhand.readlimits import MAX_RUN_BYTES, loads_json, read_text_input
from thirdhand.review.playback import HandContacts
from thirdhand.task.model import TaskFile

#: ``meta["source"]`` of a record written by ``thirdhand execute --record``.
RECORD_SOURCE = "thirdhand.execute"
#: A part is held while it moves more than this between two samples, metres or radians.
MOVING = 1e-6
#: Samples a carried part may stand still between two executed segments and stay held.
PAUSE_SAMPLES = 3


class ReplayError(ThirdhandError, ValueError):
    """An execution record that cannot be replayed over this task."""


@dataclass(frozen=True)
class Replay:
    """An execution record ready to play back.

    Attributes
    ----------
    path : Path
        The replay file (``.parquet``).
    demo : Demonstration
        Parts and the tool frame over time (``meta["name"]`` set to ``"execution: <file>"``).
    steps : list of dict
        The per-step reports of the trajectory file (``index``, ``child``,
        ``success``, ``status``...), empty when it is absent.
    success : bool or None
        Whether the run assembled the task (None without the trajectory file).
    note : str
        Something worth saying that is not a refusal (e.g. the task file's name differs).
    segments : list of dict
        The trajectory file's executed segments (``step``, ``segment``, ``t_start``...).
    """

    path: Path
    demo: Demonstration
    steps: list[dict[str, Any]] = field(default_factory=list)
    success: bool | None = None
    note: str = ""
    segments: list[dict[str, Any]] = field(default_factory=list)

    def step_starts(self) -> dict[str, float]:
        """When the run began each step, by the step's constraint id (seconds)."""
        first: dict[int, float] = {}
        for seg in self.segments:
            k = int(seg.get("step", -1))
            first[k] = min(first.get(k, math.inf), float(seg.get("t_start", math.inf)))
        out: dict[str, float] = {}
        for s in self.steps:
            cid, k = s.get("constraint"), int(s.get("index", -1))
            if cid and k in first and math.isfinite(first[k]):
                out[str(cid)] = first[k]
        return out

    def summary(self) -> str:
        """One line: the run's outcome and the first failed step with its reason."""
        failed = [s for s in self.steps if not s.get("success", True)]
        if self.success is None:
            head = f"execution {self.path.name}: no trajectory file, outcome unknown"
        elif self.success:
            n = len(self.steps)
            head = f"execution {self.path.name}: assembled ({n} step{'' if n == 1 else 's'})"
        else:
            head = f"execution {self.path.name}: failed"
        if failed:
            s = failed[0]
            head += (
                f"; step {int(s.get('index', 0)) + 1} ({s.get('child', '?')}): "
                f"{s.get('status', 'failed')}"
            )
        return head + (f" ({self.note})" if self.note else "")


def replay_view(
    demo: Demonstration,
) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """A camera position and target showing everything a record moves, z up.

    The target is the centre of the box holding every body (parts, tool frame)
    over the whole run; the camera looks at it from the (+x, -y) diagonal, above,
    from 1.8 times the box's half-diagonal (at least 0.3 m): every body within 30°
    of the view axis, inside viser's default field of view.

    Returns
    -------
    eye, target : tuple of 3 float
        Metres, world frame.
    """
    pts = [demo.pos(n)[demo.valid(n)] for n in demo.body_names]
    every = np.concatenate([p for p in pts if len(p)]) if any(len(p) for p in pts) else None
    if every is None:
        return (1.0, -1.0, 1.0), (0.0, 0.0, 0.0)
    lo, hi = every.min(axis=0), every.max(axis=0)
    centre = 0.5 * (lo + hi)
    reach = max(0.5 * float(np.linalg.norm(hi - lo)), 0.3)
    away = np.array([1.0, -1.0, 0.0]) / math.sqrt(2.0)
    eye = centre + 1.8 * reach * (away + np.array([0.0, 0.0, 0.6]))
    return (float(eye[0]), float(eye[1]), float(eye[2])), (
        float(centre[0]),
        float(centre[1]),
        float(centre[2]),
    )


def _parts(task: TaskFile) -> set[str]:
    return {o.name for o in task.objects if o.kind == "part"}


def load_replay(path: str | os.PathLike[str], task: TaskFile, task_path: Path) -> Replay:
    """Read an execution record and check it is a run of ``task``.

    Parameters
    ----------
    path : path-like
        ``OUT.parquet`` (or ``OUT``) written by ``thirdhand execute --record OUT``.
    task : TaskFile
        The task under review.
    task_path : Path
        Its file (the record names the task by its file's stem).

    Returns
    -------
    Replay

    Raises
    ------
    ReplayError
        Not a readable record, not written by ``thirdhand execute``, no tool frame,
        or a record of another task: its parts are not the task's parts, or its
        steps name constraints the task does not have. One line saying what and where.
    """
    from thirdhand import io

    replay, traj = record_paths(path)
    if not replay.exists():
        raise ReplayError(f"{replay}: no such execution record (thirdhand execute --record)")
    try:
        demo = io.load(replay)
    except ThirdhandError as exc:
        raise ReplayError(f"{replay}: not an execution record: {exc}") from None
    if demo.meta.get("source") != RECORD_SOURCE:
        raise ReplayError(
            f"{replay}: not an execution record (written by "
            f"{demo.meta.get('source', 'an unknown program')!s}, not thirdhand execute --record)"
        )
    if TOOL_BODY not in demo.body_names:
        raise ReplayError(f"{replay}: no robot tool frame {TOOL_BODY!r} in the record")
    theirs = {b.name for b in demo.bodies if b.kind == "part"}
    ours = _parts(task)
    if theirs != ours:
        extra, missing = sorted(theirs - ours), sorted(ours - theirs)
        said = []
        if extra:
            said.append(f"it moves {', '.join(extra)}, which {task_path.name} does not have")
        if missing:
            said.append(f"it lacks {', '.join(missing)}")
        raise ReplayError(
            f"{replay}: a record of another task ({demo.meta.get('task', '?')}): " + "; ".join(said)
        )
    steps: list[dict[str, Any]] = []
    segments: list[dict[str, Any]] = []
    success: bool | None = None
    if traj.exists():
        try:
            doc = loads_json(
                read_text_input(
                    traj, what="trajectory file", limit=MAX_RUN_BYTES, error=ReplayError
                ),
                error=ReplayError,
            )
            steps = list(doc.get("steps", []))
            segments = list(doc.get("segments", []))
            success = bool(doc["success"]) if "success" in doc else None
        except (OSError, ValueError, TypeError, AttributeError) as exc:
            raise ReplayError(f"{traj}: unreadable trajectory file: {exc}") from None
        ids = {c.id for c in task.constraints}
        unknown = sorted({str(s["constraint"]) for s in steps if s.get("constraint")} - ids)
        if unknown:
            raise ReplayError(
                f"{traj}: a record of another task: its steps establish {', '.join(unknown)}, "
                f"not constraints of {task_path.name}"
            )
    recorded = str(demo.meta.get("task", ""))
    ours_name = task_path.name.removesuffix(".json")
    note = f"recorded as task {recorded!r}" if recorded and recorded != ours_name else ""
    demo = demo.replace(meta={**demo.meta, "name": f"execution: {replay.name}"})
    return Replay(replay, demo, steps, success, note, segments)


def robot_contacts(demo: Demonstration) -> HandContacts:
    """When the robot holds each part: the intervals over which the part moves.

    In a record every part not carried stands still (its pose is repeated), so a
    part moving between two samples is the one attached to the tool; a pause of at
    most :data:`PAUSE_SAMPLES` samples (between two segments) does not end the hold.

    Returns
    -------
    HandContacts
        Intervals (s) under the side ``"robot"``, source ``"execution"``.
    """
    out: dict[tuple[str, str], list[tuple[float, float]]] = {}
    t = demo.t
    # A record repeats a sample between two executed segments (the arm stops there):
    # a still part for at most PAUSE_SAMPLES samples is still held.
    gap = PAUSE_SAMPLES * float(np.median(np.diff(t))) if demo.n_frames > 1 else 0.0
    for b in demo.bodies:
        if b.kind != "part" or demo.n_frames < 2:
            continue
        tr = demo.track(b.name)
        step = np.linalg.norm(np.diff(tr.pos, axis=0), axis=1)
        turn = np.abs(np.diff(tr.quat, axis=0)).max(axis=1)
        moving = np.nan_to_num(np.maximum(step, turn), nan=0.0) > MOVING
        if not moving.any():
            continue
        # Runs of moving samples [i, j): the part is held from t[i] to t[j].
        edges = np.diff(np.concatenate([[0], moving.astype(np.int8), [0]]))
        starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
        spans: list[tuple[float, float]] = []
        for i, j in zip(starts, ends, strict=True):
            if spans and t[i] - spans[-1][1] <= gap:  # the pause between two segments
                spans[-1] = (spans[-1][0], float(t[j]))
            else:
                spans.append((float(t[i]), float(t[j])))
        out[(b.name, "robot")] = spans
    return HandContacts(out, "execution")


__all__ = [
    "RECORD_SOURCE",
    "Replay",
    "ReplayError",
    "load_replay",
    "replay_view",
    "robot_contacts",
]
