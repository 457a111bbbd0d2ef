"""thirdhand's DMP vs the ``movement-primitives`` package on LASA, in one run.

For every LASA shape (``../shared/data/lasa``, demos 0–2 of each file) both
libraries fit a 2-D DMP with the same number of weights per dimension to the
demonstration and roll it out over the demonstrated duration at the
demonstration's time step; we time fit + rollout (best of ``--repeat``) and
measure the reproduction error against the demonstration.

Run: ``.venv/bin/python benchmarks/dmp_vs_movement_primitives.py [--weights 30]``.

The peer's ``movement_primitives.dmp`` package imports ``pytransform3d`` for its
Cartesian DMPs; if that optional dependency is missing, an empty stand-in module
is registered so that its plain ``DMP`` (which does not use it) can load.
"""

from __future__ import annotations

import os

# Small matrices: BLAS threads only add contention on a shared machine (a 30x1000
# product took 70 ms with OpenBLAS threads on a loaded 2-core box, 0.1 ms without).
# Both libraries run under the same setting; export OPENBLAS_NUM_THREADS to override.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import sys
import time
import types
from pathlib import Path

import numpy as np

from thirdhand.datasets.primitive_shapes import lasa_shapes
from thirdhand.primitives import DMP

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "lasa"


def _peer() -> type:
    try:
        import pytransform3d  # noqa: F401
    except ImportError:
        for name in (
            "pytransform3d",
            "pytransform3d.rotations",
            "pytransform3d.transformations",
            "pytransform3d.batch_rotations",
            "pytransform3d.trajectories",
        ):
            sys.modules.setdefault(name, types.ModuleType(name))
    from movement_primitives.dmp import DMP as PeerDMP

    return PeerDMP


def best_time(fn, repeat: int) -> tuple[float, np.ndarray]:
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    assert out is not None
    return best, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--weights", type=int, default=30, help="weights per dimension")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--demos", type=int, default=3, help="demonstrations per shape")
    ap.add_argument("--data", type=Path, default=DATA)
    args = ap.parse_args()
    peer_cls = _peer()
    files = sorted(args.data.glob("*.mat"))
    if not files:
        raise SystemExit(f"no LASA .mat files in {args.data}")
    t_th, t_pe, e_th, e_pe, e_th_mean, e_pe_mean = [], [], [], [], [], []
    for f in files:
        for t, y in lasa_shapes(args.data, f.stem)[: args.demos]:
            dt = float(np.median(np.diff(t)))
            duration = float(t[-1] - t[0])

            def ours(t: np.ndarray = t, y: np.ndarray = y) -> np.ndarray:
                return DMP(args.weights).fit(t, y).rollout()[1]

            def theirs(
                t: np.ndarray = t, y: np.ndarray = y, dt: float = dt, duration: float = duration
            ) -> np.ndarray:
                d = peer_cls(
                    n_dims=2, execution_time=duration, dt=dt, n_weights_per_dim=args.weights
                )
                d.imitate(t - t[0], y)
                d.configure(start_y=y[0], goal_y=y[-1])
                return d.open_loop()[1]

            a, ya = best_time(ours, args.repeat)
            b, yb = best_time(theirs, args.repeat)
            n = min(len(ya), len(yb), len(y))
            t_th.append(a)
            t_pe.append(b)
            e_th.append(np.linalg.norm(ya[:n] - y[:n], axis=1).max())
            e_pe.append(np.linalg.norm(yb[:n] - y[:n], axis=1).max())
            e_th_mean.append(np.linalg.norm(ya[:n] - y[:n], axis=1).mean())
            e_pe_mean.append(np.linalg.norm(yb[:n] - y[:n], axis=1).mean())
    n = len(t_th)
    threads = os.environ.get("OPENBLAS_NUM_THREADS")
    print(f"BLAS threads: {threads}")
    print(f"{n} LASA demonstrations ({len(files)} shapes), {args.weights} weights per dimension")
    print(f"{'':22}{'thirdhand':>12}{'movement-primitives':>22}")
    print(f"{'fit+rollout, total s':22}{sum(t_th):12.4f}{sum(t_pe):22.4f}")
    print(f"{'max error, median mm':22}{np.median(e_th):12.4f}{np.median(e_pe):22.4f}")
    print(f"{'max error, worst mm':22}{np.max(e_th):12.4f}{np.max(e_pe):22.4f}")
    print(f"{'mean error, mean mm':22}{np.mean(e_th_mean):12.4f}{np.mean(e_pe_mean):22.4f}")
    print(f"speed ratio (peer time / thirdhand time): {sum(t_pe) / sum(t_th):.1f}x")
    wins = sum(a <= b for a, b in zip(e_th, e_pe, strict=True))
    print(f"thirdhand error <= peer error on {wins}/{n} demonstrations")


if __name__ == "__main__":
    main()
