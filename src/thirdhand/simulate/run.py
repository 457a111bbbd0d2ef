"""One simulated run, end to end: build the cell, compile the model, run it, time it."""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from thirdhand.simulate.cell import BuiltCell, build_cell
from thirdhand.simulate.model import build_spec
from thirdhand.simulate.plan import RunPlan
from thirdhand.simulate.runner import FrameSink, Simulation, SimulationResult
from thirdhand.simulate.settings import SimulateSettings
from thirdhand.task.model import TaskFile


@dataclass
class SimulatedRun:
    """A run's simulation and where its time went.

    Attributes
    ----------
    result : SimulationResult
    built : BuiltCell
    timings : dict of str to float
        Wall-clock seconds: ``decomposition`` (0 when cached), ``build`` (model),
        ``stepping``, ``rendering`` (the frame sink).
    """

    result: SimulationResult
    built: BuiltCell
    timings: dict[str, float]


def tool_path(plan: RunPlan) -> np.ndarray:
    """The planned tool point at each sample of the plan (n, 3), world, metres (pinocchio)."""
    from thirdhand.execute.robot import Robot
    from thirdhand.se3 import pose_from_matrix

    pos, quat = pose_from_matrix(plan.robot_base)
    robot = Robot.load(plan.robot, base_pose=(pos, quat))
    return np.asarray(robot.tool_transforms(plan.q)[:, :3, 3], dtype=np.float64)


def simulate_run(
    task: TaskFile,
    plan: RunPlan,
    settings: SimulateSettings,
    *,
    task_path: str | os.PathLike[str] | None = None,
    search: Sequence[str | os.PathLike[str]] = (),
    make_sink: Callable[[Any], FrameSink | None] | None = None,
) -> SimulatedRun:
    """Simulate ``plan`` of ``task`` (see :class:`~thirdhand.simulate.runner.Simulation`).

    ``make_sink(model)`` is called with the compiled model and returns the frame
    sink (a video writer) or None.
    """
    t0 = time.perf_counter()
    built = build_cell(task, plan, settings, task_path=task_path, search=search)
    t1 = time.perf_counter()
    model = build_spec(built.cell, settings).compile()
    sink = make_sink(model) if make_sink is not None else None
    constraints = {c.id: c for c in task.constraints}
    sim = Simulation(model, plan, constraints, built.corners, settings,
                     tool_planned=tool_path(plan), sink=sink)  # fmt: skip
    t2 = time.perf_counter()
    result = sim.run()
    timings = {
        "decomposition": built.decomposition_s,
        "build": (t1 - t0 - built.decomposition_s) + (t2 - t1),
        "stepping": result.wall_time_s,
        "rendering": result.render_time_s,
    }
    result.timings = timings
    return SimulatedRun(result, built, timings)
