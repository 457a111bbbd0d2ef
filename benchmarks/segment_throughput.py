"""Throughput of ``segment_demonstration`` on a long recording.

A synthetic 1-hour, 120 Hz pick-and-place recording of 20 bodies (a carrier
and 19 parts: 19 hand–part and 171 part–part pairs, 190 in all) with sensor
noise and 20 % missing frames is segmented with the shipped model, on one
thread. Printed: wall time of the whole segmentation, pair-steps (latent) and
pair-frames per second. Target: the whole ``segment`` under 10 s on one core.

Usage: ``python benchmarks/segment_throughput.py [--minutes 60] [--bodies 20]``
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np

from thirdhand.datasets.pick_place import random_pick_place_demo
from thirdhand.segment.model import default_model
from thirdhand.segment.pipeline import segment_demonstration


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=60.0)
    ap.add_argument("--bodies", type=int, default=20)
    ap.add_argument("--rate", type=float, default=120.0)
    args = ap.parse_args()

    t0 = time.perf_counter()
    demo = random_pick_place_demo(
        np.random.default_rng(0),
        n_parts=args.bodies - 1,
        duration=60.0 * args.minutes,
        rate=args.rate,
        picks_per_part=5,
        noise_pos=1e-3,
        noise_rot=0.0087,
        missing=0.2,
    )
    print(f"generated {demo} in {time.perf_counter() - t0:.1f} s")
    model = default_model()
    # Compile the numba kernels outside the timing.
    segment_demonstration(demo.slice(0.0, 2.0), model)

    t0 = time.perf_counter()
    result = segment_demonstration(demo, model)
    wall = time.perf_counter() - t0
    n_pairs = len(result.pairs)
    steps = n_pairs * len(result.times)
    frames = n_pairs * demo.n_frames
    print(
        f"segment: {n_pairs} pairs x {len(result.times)} latent steps "
        f"({demo.n_frames} frames) in {wall:.2f} s"
    )
    print(f"{steps / wall:,.0f} pair-steps/s, {frames / wall:,.0f} pair-frames/s")
    print(f"target: whole segment under 10 s on one core -> {'met' if wall < 10 else 'NOT met'}")


if __name__ == "__main__":
    main()
