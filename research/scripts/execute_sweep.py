"""The execution sweep: learned synthetic tasks × seeds × robot × meshes/boxes, offline.

Usage: ``python research/scripts/execute_sweep.py [--scene chair --scene bench] [--seeds 1-12]
[--robot panda --robot baxter] [--meshes DIR] [--boxes] [--step-time 30]
[--placement auto|geometry|reach]``.

Each run learns the task from the synthetic demonstration of ``scene`` with that seed
(:func:`thirdhand.learn.run.learn_task` with the later stages off, one demonstration),
lays the parts out with the same seed and executes the plan offline. With ``--meshes``
the part meshes are used (and with ``--boxes`` as well, a second run with bounding boxes
only). Prints one row per run (steps done, configurations in collision, planning time
per step, the first failure) and the success table (see research/notes/execution.md).
"""

from __future__ import annotations

import argparse
import statistics
import time

from thirdhand.execute.executor import ExecutionOptions, Executor
from thirdhand.learn.run import learn_task
from thirdhand.synth import make_scene


def _seeds(text: str) -> list[int]:
    if "-" in text:
        a, b = text.split("-")
        return list(range(int(a), int(b) + 1))
    return [int(v) for v in text.split(",")]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", action="append", choices=["chair", "bench"])
    ap.add_argument("--seeds", type=_seeds, default=_seeds("1-12"))
    ap.add_argument("--robot", action="append", choices=["panda", "baxter"])
    ap.add_argument("--meshes", default=None, help="Folder of the part meshes.")
    ap.add_argument("--boxes", action="store_true", help="Also run with bounding boxes only.")
    ap.add_argument("--step-time", type=float, default=30.0)
    ap.add_argument("--plan-time", type=float, default=3.0)
    ap.add_argument("--placement", choices=["auto", "geometry", "reach"], default="auto")
    ap.add_argument("--start-grasps", type=int, default=0)
    args = ap.parse_args()
    kinds = []
    if args.meshes:
        kinds.append(("meshes", [args.meshes]))
    if args.boxes or not args.meshes:
        kinds.append(("boxes", []))
    opts = ExecutionOptions(
        step_time_limit=args.step_time,
        plan_time_limit=args.plan_time,
        placement=args.placement,
        start_grasps=args.start_grasps,
    )
    rows: dict[tuple[str, str, str], list[tuple[bool, int, list[float]]]] = {}
    for scene in args.scene or ["chair", "bench"]:
        for seed in args.seeds:
            task = learn_task(
                [make_scene(scene, seed=seed)], primitives=False, reward=False, grasps=False
            ).task
            for robot in args.robot or ["panda"]:
                for kind, search in kinds:
                    t0 = time.perf_counter()
                    ex = Executor.for_task(task, robot, seed=seed, options=opts, search=search)
                    res = ex.run_offline(seed=seed)
                    done = sum(r.success for r in res.steps)
                    times = [r.planning_time_s for r in res.steps]
                    fail = next((r for r in res.steps if not r.success), None)
                    why = "" if fail is None else f"  {fail.child}→{fail.constraint}: {fail.status}"
                    why += f"  [{'; '.join(ex.notes)}]" if ex.notes else ""
                    print(f"{scene} seed {seed:2d} {robot} {kind}: {done}/{len(res.steps)} steps, "
                          f"{res.n_collisions} collisions, {time.perf_counter() - t0:5.1f} s{why}",
                          flush=True)  # fmt: skip
                    rows.setdefault((scene, robot, kind), []).append(
                        (res.success, res.n_collisions, times)
                    )
    print()
    print(f"{'scene':<6} {'robot':<7} {'parts':<7} {'every step':>10}  {'collisions':>10}  "
          f"{'median t':>8}  {'max t':>6}")  # fmt: skip
    for (scene, robot, kind), runs in rows.items():
        ok = sum(r[0] for r in runs)
        ts = [t for r in runs for t in r[2]]
        n_col = sum(r[1] for r in runs)
        print(f"{scene:<6} {robot:<7} {kind:<7} {ok:>5}/{len(runs):<4}  "
              f"{n_col:>10}  {statistics.median(ts):7.2f} s  {max(ts):5.1f} s")  # fmt: skip


if __name__ == "__main__":
    main()
