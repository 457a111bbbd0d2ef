"""Test helpers for the review GUI: a partial-order plan and a synthetic execution record."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from thirdhand import io
from thirdhand.demonstration import BodyInfo, Demonstration
from thirdhand.execute.record import TOOL_BODY
from thirdhand.review.dofs import world_poses
from thirdhand.task.model import TaskFile

#: The held part's offset from its goal at the start of the carry, metres (world frame).
CARRY_FROM = np.array([0.30, -0.10, 0.20])
#: The tool frame's offset from the held part, metres (world frame).
TOOL_OFFSET = np.array([0.0, 0.0, 0.10])


def partial_order(task: TaskFile) -> TaskFile:
    """The chair's plan as a true partial order: the legs in any order, the last
    step (the back) after the fourth (leg1) only."""
    out = task.model_copy(deep=True)
    n = len(out.plan)
    for i, s in enumerate(out.plan):
        s.after = [n - 2] if i == n - 1 else []
    return TaskFile.model_validate(out.model_dump(by_alias=True))


def write_record(
    task: TaskFile,
    out: Path,
    *,
    held: str = "leg2",
    n: int = 60,
    task_name: str = "chair.task",
    failed: str | None = "leg3",
) -> Path:
    """Write ``out.parquet`` + ``out.json`` as ``thirdhand execute --record out`` does.

    Every part stands at its assembled world pose except ``held``, carried in a
    straight line from its goal + :data:`CARRY_FROM` to its goal between frames
    ``n // 6`` and ``5 n // 6`` (0.1 s apart), the tool frame :data:`TOOL_OFFSET`
    above it. The trajectory file reports ``held``'s step done and ``failed``'s
    step failed with a reason.
    """
    poses = world_poses(task)
    t = 0.1 * np.arange(n, dtype=float)
    parts = [o.name for o in task.objects if o.kind == "part"]
    pos: dict[str, np.ndarray] = {}
    quat: dict[str, np.ndarray] = {}
    for name in parts:
        pos[name] = np.repeat(np.asarray(poses[name].pos, float)[None], n, 0)
        quat[name] = np.repeat(np.asarray(poses[name].quat, float)[None], n, 0)
    a, b = n // 6, 5 * n // 6
    s = np.clip((np.arange(n) - a) / (b - a), 0.0, 1.0)
    goal = np.asarray(poses[held].pos, float)
    pos[held] = goal + (1.0 - s)[:, None] * CARRY_FROM
    pos[TOOL_BODY] = pos[held] + TOOL_OFFSET
    quat[TOOL_BODY] = np.repeat(np.array([[0.0, 1.0, 0.0, 0.0]]), n, 0)
    bodies = [BodyInfo(p, kind="part") for p in parts] + [BodyInfo(TOOL_BODY, kind="tool")]
    meta = {"source": "thirdhand.execute", "task": task_name, "robot": "panda", "units": "m"}
    replay = out.with_suffix(".parquet")
    io.save(Demonstration(t, bodies, pos, quat, meta=meta), replay)
    steps = []
    for i, st in enumerate(task.plan):
        if st.child == held:
            steps.append({"index": i, "child": held, "constraint": st.constraint, "success": True,
                          "status": "done"})  # fmt: skip
        elif st.child == failed:
            steps.append({"index": i, "child": failed, "constraint": st.constraint,
                          "success": False, "status": "no collision-free grasp"})  # fmt: skip
    doc = {"schema": "thirdhand.trajectory/1", "success": failed is None, "steps": steps}
    replay.with_suffix(".json").write_text(json.dumps(doc))
    return replay
