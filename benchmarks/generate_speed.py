"""``thirdhand generate`` speed on the demo chair: episodes per minute on one core, and where
the time goes (planning, physics, rendering, encoding).

Generates ``--episodes`` episodes of the synthetic chair of ``thirdhand demo`` (the
ground-truth task of ``make_scene("chair", seed=0)``, the 3rdHand meshes) serially,
twice: with the default physics (what is kept, and why the rest is not), and with
physics under which every planned step counts as done (the weld grasp, wide
tolerances), so that every episode is rendered and encoded as a kept one is. The
dataset has the default ``[generate]`` settings (10 fps, 224 x 224 cameras).

Usage: ``python benchmarks/generate_speed.py [--episodes N] [--meshes DIR]``
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", os.environ.get("OMP_NUM_THREADS", "1"))
os.environ.setdefault("MUJOCO_GL", "egl")

import argparse
import tempfile
import time
from pathlib import Path

#: Physics under which every planned step of the chair counts as done.
LENIENT = {
    "grasp": "weld", "position_tolerance": 1000.0, "angle_tolerance": 180.0,
    "slip_tolerance": 1000.0, "drop_distance": 10000.0,
}  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    here = Path(__file__).resolve().parents[1]
    ap.add_argument("--meshes", default=str(here.parent / "shared" / "data" / "3rdhand" / "meshes"))
    ap.add_argument("--episodes", type=int, default=4)
    args = ap.parse_args()

    from thirdhand.errors import ThirdhandError
    from thirdhand.generate.dataset import generate_dataset, jobs_for
    from thirdhand.generate.episodes import EpisodeJob
    from thirdhand.simulate.settings import SimulateSettings
    from thirdhand.synth import make_scene
    from thirdhand.synth.task import truth_task

    task = truth_task(make_scene("chair", seed=0))
    search = (args.meshes,) if Path(args.meshes).is_dir() else ()
    with tempfile.TemporaryDirectory() as tmp:
        cache = str(Path(tmp) / "cache")
        from thirdhand.generate.episodes import run_episode

        warm = EpisodeJob(task=task, task_path=None, name="chair", seed=0, search=search,
                          simulate=SimulateSettings(cache=cache))  # fmt: skip
        run_episode(warm)  # imports and the convex decompositions (cached), untimed
        for label, physics in (("default physics", {}), ("every planned step done", LENIENT)):
            job = EpisodeJob(task=task, task_path=None, name="chair", seed=0, search=search,
                             simulate=SimulateSettings(cache=cache, **physics))  # fmt: skip
            t0 = time.perf_counter()
            try:
                s = generate_dataset(jobs_for(job, 0, args.episodes), Path(tmp) / label)
                kept, tm, reasons = len(s.kept), s.timings, s.reasons
            except ThirdhandError as exc:  # none kept: the message counts the reasons
                kept, tm, reasons = 0, None, {str(exc): 1}
            wall = time.perf_counter() - t0
            print(f"\n{label}: {kept} of {args.episodes} episodes kept in {wall:.1f} s "
                  f"({60.0 * args.episodes / wall:.2f} episodes/min, "
                  f"{60.0 * kept / wall:.2f} kept/min)")  # fmt: skip
            if tm is not None:
                total = sum(tm.values())
                for k, v in tm.items():
                    print(f"  {k:10s} {v:7.1f} s  {100 * v / total:5.1f} %")
            for r, n in sorted(reasons.items(), key=lambda i: -i[1]):
                print(f"  not kept: {r} x{n}")


if __name__ == "__main__":
    main()
