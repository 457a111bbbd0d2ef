"""Where the time of an executed step goes: IK, collision checks, the planner, the rest.

Executes the synthetic chair's ground-truth task offline (Panda, the start
layouts of ``--seeds``, the same steps as ``benchmarks/planning.py``) with wall-clock
timers wrapped around the stage's functions, and prints per step (medians over
the steps) and in total:

- IK: :func:`thirdhand.execute.kinematics.solve_ik` (batched damped least squares);
- collision checks: every configuration or path check of the scene
  (``SceneChecks`` batched checks, coal's narrow phase, the sphere kernels),
  split into those made by the planner and the others (grasp and goal selection,
  straight moves, the executor's dense check);
- planner overhead: :func:`thirdhand.execute.planner.plan_motion` minus its checks;
- the rest: grasp and goal ranking, primitives, bookkeeping.

Usage: ``python benchmarks/step_profile.py [--seeds 0,1,2] [--scene chair]``
"""

from __future__ import annotations

import argparse
import functools
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

MESHES = Path(os.environ.get("THIRDHAND_DATA", Path(__file__).parents[2] / "shared" / "data"))
MESHES = MESHES / "3rdhand" / "meshes"

TIMES = {"ik": 0.0, "check": 0.0, "check_in_planner": 0.0, "planner": 0.0}
_DEPTH = {"check": 0, "planner": 0}


def _wrap(owner: Any, name: str, kind: str) -> None:
    fn: Callable[..., Any] = getattr(owner, name)

    @functools.wraps(fn)
    def timed(*args: Any, **kwargs: Any) -> Any:
        if kind == "check" and _DEPTH["check"]:
            return fn(*args, **kwargs)
        if kind in _DEPTH:
            _DEPTH[kind] += 1
        t0 = time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            dt = time.perf_counter() - t0
            if kind in _DEPTH:
                _DEPTH[kind] -= 1
            TIMES[kind] += dt
            if kind == "check" and _DEPTH["planner"]:
                TIMES["check_in_planner"] += dt

    setattr(owner, name, timed)


def instrument() -> None:
    """Wrap the timed functions (module attributes are looked up at call time)."""
    from thirdhand.execute import collision_check, kinematics, planner, robot, step_search

    for name in ("valid_mask", "check_path", "collisions", "path_free_spheres", "pair_hits"):
        if hasattr(collision_check.SceneChecks, name):
            _wrap(collision_check.SceneChecks, name, "check")
    _wrap(kinematics, "solve_ik", "ik")
    robot.solve_ik = kinematics.solve_ik  # type: ignore[attr-defined]
    _wrap(planner, "plan_motion", "planner")
    step_search.plan_motion = planner.plan_motion  # type: ignore[attr-defined]
    from thirdhand.execute import executor

    executor.plan_motion = planner.plan_motion  # type: ignore[attr-defined]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", default="0,1,2")
    parser.add_argument("--scene", default="chair", choices=["chair", "bench"])
    args = parser.parse_args()
    instrument()
    from thirdhand.execute import Robot
    from thirdhand.execute.executor import ExecutionOptions, Executor
    from thirdhand.execute.layout import make_workcell, start_layout
    from thirdhand.synth import make_scene
    from thirdhand.synth.task import truth_task

    search = [str(MESHES)] if MESHES.is_dir() else []
    task = truth_task(make_scene(args.scene, seed=0))
    cell = make_workcell(task, search=search)
    robot = Robot.load("panda", base_pose=(cell.robot_base[:3, 3], [0.0, 0.0, 0.0, 1.0]))
    rows = []
    for seed in [int(v) for v in args.seeds.split(",")]:
        start = start_layout(task, cell, seed, search=search)
        ex = Executor(robot, task, cell, start, ExecutionOptions(), search=search)
        for k in TIMES:
            TIMES[k] = 0.0
        t0 = time.perf_counter()
        result = ex.run_offline(seed=seed)
        total = time.perf_counter() - t0
        n = len(result.steps)
        ok = sum(r.success for r in result.steps)
        rows.append((seed, n, ok, total, dict(TIMES)))
    print(f"step profile: {args.scene}, Panda, offline, seeds {args.seeds}")
    tot = {k: sum(r[4][k] for r in rows) for k in TIMES}
    wall = sum(r[3] for r in rows)
    steps = sum(r[1] for r in rows)
    done = sum(r[2] for r in rows)
    other_checks = tot["check"] - tot["check_in_planner"]
    planner_own = tot["planner"] - tot["check_in_planner"]
    rest = wall - tot["ik"] - tot["check"] - planner_own
    print(f"  {done}/{steps} steps done, wall {wall:.2f} s, per step {wall / steps:.3f} s")
    for label, v in (
        ("IK", tot["ik"]),
        ("collision checks in the planner", tot["check_in_planner"]),
        ("collision checks elsewhere (grasp/goal selection, straight moves, dense)", other_checks),
        ("planner overhead (search, shortcutting, minus checks)", planner_own),
        ("the rest (ranking, primitives, bookkeeping)", rest),
    ):
        print(f"  {label:75s} {v / steps:7.3f} s/step  {v / wall:6.1%}")
    print(f"  per-seed wall: {', '.join(f'{r[0]}: {r[3]:.2f} s' for r in rows)}")


if __name__ == "__main__":
    main()
