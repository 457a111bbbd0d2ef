"""The ``--json`` document of a simulated run (``"schema": "thirdhand.simulation/1"``)."""

from __future__ import annotations

from dataclasses import asdict
from typing import Any

from thirdhand.simulate.run import SimulatedRun
from thirdhand.simulate.settings import SimulateSettings

SCHEMA = "thirdhand.simulation/1"


def _round(v: Any) -> Any:
    return round(v, 3) if isinstance(v, float) else v


def simulation_document(
    run: SimulatedRun,
    settings: SimulateSettings,
    *,
    task: str,
    robot: str,
    source: str,
    video: str | None,
    video_note: str | None,
    frames: int,
) -> dict[str, Any]:
    """The JSON document: per step ``status``, errors, slip, force; the rest; the times.

    ``grasp`` is the grasp mode (``friction`` or ``weld``); ``steps[i].grasp`` the
    planner's grasp of that step. Lengths in mm, angles in degrees, forces in N,
    times in seconds.
    """
    r = run.result
    steps = []
    for o in sorted(r.steps, key=lambda o: o.index):
        d = {k: _round(v) for k, v in asdict(o).items()}
        steps.append(d)
    sim, wall = r.sim_time_s, sum(run.timings.values())
    return {
        "schema": SCHEMA,
        "task": task,
        "robot": robot,
        "source": source,
        "grasp": r.grasp,
        "success": r.success,
        "steps": steps,
        "rest": {
            "seconds": settings.rest_time,
            "largest_displacement_mm": round(r.rest_displacement_mm, 3),
            "part": r.rest_part,
        },
        "sim_time_s": round(sim, 3),
        "wall_time_s": round(wall, 3),
        "stepping_real_time_factor": round(sim / r.wall_time_s, 3) if r.wall_time_s > 0 else None,
        "timings_s": {k: round(v, 3) for k, v in run.timings.items()},
        "pieces": dict(run.built.pieces),
        "notes": list(run.built.notes),
        "video": video,
        "video_note": video_note,
        "frames": frames,
        "settings": settings.model_dump(mode="json"),
    }
