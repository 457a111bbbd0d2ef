"""Throughput of full constraint fits (every model + BIC selection), fits per second.

For each joint type, 1,000-sample tracks with 1 mm / 0.5° noise (oriented, and
position-only where the type is identifiable without orientations), each fitted
with :func:`thirdhand.constraints.fit_constraint` on one core. Prints fits/s and
the fraction classified correctly.

BLAS threads slow the small matrix products of a fit badly on a shared machine:
unless ``OPENBLAS_NUM_THREADS`` (or ``OMP_NUM_THREADS``) is set, the benchmark
sets it to 1 before numpy loads, and prints the setting. The first fit of a
fresh checkout compiles the numba kernels (cached on disk afterwards); the
warm-up fit keeps that out of the measurement.

Usage: ``python benchmarks/constraint_fit.py [--n 1000] [--tracks 20] [--seconds 2]``
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", os.environ.get("OMP_NUM_THREADS", "1"))

import argparse
import math
import time

import numpy as np

from thirdhand.constraints import fit_constraint
from thirdhand.datasets.joint_tracks import random_joint_track

CASES = (
    ("fixed", True),
    ("prismatic", True),
    ("revolute", True),
    ("cylindrical", True),
    ("free", True),
    ("fixed", False),
    ("prismatic", False),
    ("revolute", False),
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--n", type=int, default=1000, help="samples per track")
    parser.add_argument("--tracks", type=int, default=20, help="distinct tracks per type")
    parser.add_argument("--seconds", type=float, default=2.0, help="time budget per type")
    args = parser.parse_args()

    print(f"OPENBLAS_NUM_THREADS={os.environ['OPENBLAS_NUM_THREADS']}, {args.n} samples per track")
    print(f"{'type':12s} {'orient':7s} {'fits/s':>8s} {'ms/fit':>7s} {'correct':>8s}")
    total_fits = 0
    total_time = 0.0
    for kind, oriented in CASES:
        rng = np.random.default_rng(1)
        tracks = [
            random_joint_track(kind, rng, n=args.n, pos_noise=1e-3, rot_noise=math.radians(0.5))
            for _ in range(args.tracks)
        ]
        inputs = [(t.pos, t.quat if oriented else None) for t in tracks]
        fit_constraint(*inputs[0])  # warm-up
        correct = sum(fit_constraint(p, q).type == kind for p, q in inputs)
        fits = 0
        start = time.perf_counter()
        while time.perf_counter() - start < args.seconds:
            for p, q in inputs:
                fit_constraint(p, q)
            fits += len(inputs)
        elapsed = time.perf_counter() - start
        total_fits += fits
        total_time += elapsed
        print(
            f"{kind:12s} {'yes' if oriented else 'no':7s} {fits / elapsed:8.0f} "
            f"{1000 * elapsed / fits:7.2f} {correct:>4d}/{len(inputs)}"
        )
    rate = total_fits / total_time
    print(f"{'all':12s} {'':7s} {rate:8.0f} {1000 / rate:7.2f}")


if __name__ == "__main__":
    main()
