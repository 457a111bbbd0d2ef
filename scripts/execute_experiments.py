"""Free-DOF experiment: placing a hard-to-reach leg with vs without goals sampled in the free DOFs.

Usage: ``python scripts/execute_experiments.py [--scene bench|chair] [--runs 50] [--meshes DIR]``.
Prints one row per run and the summary table (see docs/execution.md).
"""

from __future__ import annotations

import argparse

from thirdhand.execute.experiments import free_dof_experiment, summary_table
from thirdhand.synth import make_scene
from thirdhand.synth.task import truth_task


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--scene", default="bench", choices=["bench", "chair"])
    ap.add_argument("--runs", type=int, default=50)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--meshes", action="append", default=[])
    ap.add_argument("--step-time", type=float, default=20.0)
    args = ap.parse_args()
    task = truth_task(make_scene(args.scene, seed=0))
    seeds = range(args.first_seed, args.first_seed + args.runs)
    out = []
    for s in seeds:
        (o,) = free_dof_experiment(task, [s], search=args.meshes, step_time_limit=args.step_time)
        out.append(o)
        print(
            f"seed {s:3d} {o.constraint}: with {o.with_sampling!s:5} ({o.time_with_s:5.1f} s)  "
            f"without {o.without_sampling!s:5} ({o.time_without_s:5.1f} s)",
            flush=True,
        )
    print(f"\n{args.scene}: {len(out)} seeded runs")
    print(summary_table(out))


if __name__ == "__main__":
    main()
