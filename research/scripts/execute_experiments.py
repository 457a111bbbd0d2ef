"""Free-DOF experiment: placing a hard-to-reach leg with vs without goals sampled in the free DOFs.

Usage: ``python research/scripts/execute_experiments.py [--condition reach+clutter] [--runs 50]
[--meshes DIR]``. For each condition (default: all of
``research.execution.CONDITIONS``), seeds are taken in order until ``--runs``
instances that are reachable in principle have run (the others are skipped and counted).
Prints one row per run and the summary table (see research/notes/execution.md).
"""

from __future__ import annotations

import argparse
import itertools
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository root: `research`

from research.execution import CONDITIONS, free_dof_experiment, summary_table
from thirdhand.synth import make_scene
from thirdhand.synth.task import truth_task


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--condition", action="append", choices=sorted(CONDITIONS))
    ap.add_argument("--runs", type=int, default=50)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--meshes", action="append", default=[])
    ap.add_argument("--step-time", type=float, default=20.0)
    args = ap.parse_args()
    task = truth_task(make_scene("bench", seed=0))
    out = []
    notes = []
    for cond in args.condition or list(CONDITIONS):
        runs: list = []
        skipped: list[int] = []
        for s in itertools.count(args.first_seed):
            if len(runs) >= args.runs:
                break
            got = free_dof_experiment(
                task, [s], search=args.meshes, step_time_limit=args.step_time,
                condition=cond, skipped=skipped,
            )  # fmt: skip
            for o in got:
                runs.append(o)
                print(
                    f"{cond} seed {s:3d} {o.constraint}: feasible {o.feasible_fraction:5.1%}  "
                    f"with {o.with_sampling!s:5} ({o.time_with_s:5.1f} s)  "
                    f"without {o.without_sampling!s:5} ({o.time_without_s:5.1f} s)",
                    flush=True,
                )
        last = runs[-1].seed if runs else args.first_seed
        notes.append(
            f"{cond}: {len(runs)} runs (seeds {args.first_seed}–{last}; {len(skipped)} seeds "
            "skipped: no spin reachable even in principle)"
        )
        out += runs
    print()
    print("\n".join(notes))
    print(summary_table(out))


if __name__ == "__main__":
    main()
