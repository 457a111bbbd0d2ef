"""Time of RCSI: one full run (5 blocks, 300 random + 15 expert episodes) and the noise experiment.

One run = drawing the data, boosting 40 trees of depth 4, the reward tree of
depth 4 and perf on 1000 states (the 501-state grounded world is built once and
timed apart). Prints the median over ``--repeats`` runs, then times the whole
noise experiment (8 rows × ``--noise-runs`` repetitions, BLMRIL + RCSI +
RCSI+cma-shaping + RCSI+shaping) with ``--jobs`` processes.

Usage: ``python benchmarks/rcsi.py [--repeats 10] [--noise-runs 100] [--jobs 2]``
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository root: `research`

from research.irl_tables import run_experiment
from research.relational_irl import (
    BALANCE,
    REWARD_DISTINCT_FROM_ARGS,
    REWARD_LOOKAHEAD,
    SHAPING,
)
from thirdhand.relational.csi import fit_rcsi
from thirdhand.relational.data import expert_pairs, random_pairs
from thirdhand.relational.domains.blocks import blocks_mdp, blocks_reward
from thirdhand.relational.evaluate import perf_of_reward


def one_run(seed: int, *, shaping: bool | str) -> tuple[float, float, float]:
    """Wall seconds, CPU seconds and perf of one RCSI run on stack (``shaping`` as in ``fit_rcsi``).

    The CPU time (this process's) is the figure to read on a shared machine,
    where the wall time grows with the load.
    """
    start, cpu = time.perf_counter(), time.process_time()
    mdp = blocks_mdp(5)
    r = blocks_reward(mdp, "stack")
    rng = np.random.default_rng(seed)
    e = expert_pairs(mdp, r, 15, rng)
    d = random_pairs(mdp, 300, rng)
    model = fit_rcsi(
        [(mdp, e)],
        [(mdp, d)],
        shaping=shaping,
        seed=seed,
        balance=BALANCE,
        reward_lookahead=REWARD_LOOKAHEAD,
        reward_distinct_from_args=REWARD_DISTINCT_FROM_ARGS,
    )
    perf = perf_of_reward(mdp, model.reward_of(mdp), r, 0.9, mdp.sample_states(1000, rng))
    return time.perf_counter() - start, time.process_time() - cpu, perf


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=10)
    ap.add_argument("--noise-runs", type=int, default=100)
    ap.add_argument("--jobs", type=int, default=2)
    args = ap.parse_args()
    start = time.perf_counter()
    blocks_mdp(5)
    print(f"grounding 5 blocks (501 states): {time.perf_counter() - start:.3f} s")
    for method in ("RCSI", "RCSI+cma-shaping", "RCSI+shaping"):
        runs = [one_run(k, shaping=SHAPING[method]) for k in range(args.repeats)]
        times = [t for t, _, _ in runs]
        cpu = [c for _, c, _ in runs]
        print(
            f"one {method} run: median {np.median(times):.2f} s, "
            f"max {np.max(times):.2f} s over {args.repeats} runs (target: well under 1 s); "
            f"CPU median {np.median(cpu):.2f} s, max {np.max(cpu):.2f} s"
        )
    if args.noise_runs:
        start = time.perf_counter()
        run_experiment("noise", runs=args.noise_runs, jobs=args.jobs)
        took = time.perf_counter() - start
        print(f"noise experiment, {args.noise_runs} runs per row, {args.jobs} jobs: {took:.1f} s")


if __name__ == "__main__":
    main()
