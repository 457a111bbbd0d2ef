"""Physics simulation speed on the demo chair: simulated seconds per wall-clock second.

Plans the synthetic chair of ``thirdhand demo`` (the ground-truth task of
``make_scene("chair", seed=0)``) on the Panda as ``thirdhand simulate`` does, then
simulates the run twice: once with an empty decomposition cache and a video (where the
time goes on a first run: decomposition, model building, stepping, rendering), once
again from the cache without a video (what a second run costs). Prints the real-time factor of
the stepping alone and of the whole run, and the share of each part.

Usage: ``python benchmarks/simulate_speed.py [--meshes DIR] [--fps N]``
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", os.environ.get("OMP_NUM_THREADS", "1"))
os.environ.setdefault("MUJOCO_GL", "egl")

import argparse
import tempfile
import time
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    here = Path(__file__).resolve().parents[1]
    ap.add_argument("--meshes", default=str(here.parent / "shared" / "data" / "3rdhand" / "meshes"))
    ap.add_argument("--fps", type=int, default=25)
    args = ap.parse_args()

    from thirdhand.simulate.plan import plan_offline
    from thirdhand.simulate.run import simulate_run
    from thirdhand.simulate.settings import SimulateSettings
    from thirdhand.simulate.video import count_frames, open_video
    from thirdhand.synth import make_scene
    from thirdhand.synth.task import truth_task

    task = truth_task(make_scene("chair", seed=0))
    search = [args.meshes] if Path(args.meshes).is_dir() else []
    t0 = time.perf_counter()
    plan = plan_offline(task, task_path=None, robot="panda", seed=0, search=search)
    planning = time.perf_counter() - t0
    print(f"planning (as thirdhand simulate plans): {planning:.1f} s; "
          f"{sum(s.planned for s in plan.steps)} of {len(plan.steps)} steps planned")  # fmt: skip
    with tempfile.TemporaryDirectory() as tmp:
        video = Path(tmp) / "chair.mp4"
        cfg = SimulateSettings(cache=str(Path(tmp) / "cache"), fps=args.fps)
        writers = []

        def sink(model):
            w, why = open_video(model, video, fps=cfg.fps, width=cfg.width, height=cfg.height,
                                lookat=plan.robot_base[:3, 3], distance=2.0)  # fmt: skip
            if why:
                print(f"no video: {why}")
            writers.append(w)
            return w

        first = simulate_run(task, plan, cfg, search=search, make_sink=sink)
        for w in writers:
            if w is not None:
                w.close()
        frames = count_frames(video) if video.exists() else 0
        second = simulate_run(task, plan, cfg, search=search)
    for name, run in (("first run (cold cache, video)", first), ("second run (cached)", second)):
        r, tm = run.result, run.timings
        total = sum(tm.values())
        print(f"\n{name}: {r.sim_time_s:.1f} simulated s in {total:.1f} wall s "
              f"({r.sim_time_s / total:.2f}x real time overall, "
              f"{r.sim_time_s / tm['stepping']:.2f}x for the stepping alone)")  # fmt: skip
        for k, v in tm.items():
            print(f"  {k:14s} {v:7.2f} s  {100 * v / total:5.1f} %")
    steps = sorted(first.result.steps, key=lambda o: o.index)
    statuses = ", ".join(f"{o.child} {o.status}" for o in steps)
    print(f"\nvideo: {frames} frames at {args.fps} fps; statuses: {statuses}")


if __name__ == "__main__":
    main()
