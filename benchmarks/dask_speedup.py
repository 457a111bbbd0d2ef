"""Speed-up of ``irl experiment noise`` on a Dask cluster of 2 workers against the serial run.

Starts a ``dask scheduler`` and two single-threaded ``dask worker`` processes on
127.0.0.1 (as in docs/cluster.md), runs the noise experiment with ``--runs N``
serially in this process and then with ``--scheduler`` on the cluster (the same
trials as Dask tasks), checks that both tables are identical, and prints both wall
times and their ratio. The cluster's start-up is timed apart. Also runs the same
trials on ``--jobs 2`` local processes, the peer the cluster is compared with.

Usage: ``python benchmarks/dask_speedup.py [--runs 4]``
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from thirdhand.experiments.relational_irl import run_experiment


def start_cluster(folder: Path, workers: int) -> tuple[str, list[subprocess.Popen[bytes]]]:
    info = folder / "scheduler.json"
    quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL, "cwd": folder}
    procs = [
        subprocess.Popen(
            [sys.executable, "-m", "dask", "scheduler", "--host", "127.0.0.1", "--port", "0",
             "--scheduler-file", str(info), "--no-dashboard"],
            **quiet,  # type: ignore[arg-type]
        )
    ]  # fmt: skip
    while not info.exists() or not info.read_text().strip():
        time.sleep(0.2)
    address = json.loads(info.read_text())["address"]
    for _ in range(workers):
        procs.append(
            subprocess.Popen(
                [sys.executable, "-m", "dask", "worker", address, "--nthreads", "1",
                 "--no-nanny", "--host", "127.0.0.1", "--no-dashboard"],
                **quiet,  # type: ignore[arg-type]
            )
        )  # fmt: skip
    from distributed import Client

    with Client(address, timeout=30) as client:
        client.wait_for_workers(workers, timeout=300)
    return address, procs


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=4)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    print(f"cores: {os.cpu_count()}; load average: {os.getloadavg()[0]:.1f}")
    start = time.perf_counter()
    serial = run_experiment("noise", runs=args.runs)
    t_serial = time.perf_counter() - start
    print(f"serial: {t_serial:.1f} s ({8 * args.runs} trials)")
    start = time.perf_counter()
    local = run_experiment("noise", runs=args.runs, jobs=args.workers)
    t_local = time.perf_counter() - start
    print(f"--jobs {args.workers} (local processes): {t_local:.1f} s")
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        address, procs = start_cluster(Path(tmp), args.workers)
        t_up = time.perf_counter() - start
        try:
            start = time.perf_counter()
            dask = run_experiment("noise", runs=args.runs, scheduler=address)
            t_dask = time.perf_counter() - start
        finally:
            for p in reversed(procs):
                p.terminate()
            for p in procs:
                try:
                    p.wait(timeout=30)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait()
    print(f"cluster start-up ({args.workers} workers): {t_up:.1f} s")
    print(f"--scheduler ({args.workers} Dask workers): {t_dask:.1f} s")
    # Compared as JSON text: a standard error of one run is NaN, and NaN != NaN.
    same = json.dumps(serial) == json.dumps(dask) == json.dumps(local)
    print(f"tables identical: {same}")
    print(f"speed-up, Dask {args.workers} workers vs serial: {t_serial / t_dask:.2f}x")
    print(f"speed-up, --jobs {args.workers} vs serial: {t_serial / t_local:.2f}x")
    print(f"ratio Dask / local processes: {t_dask / t_local:.2f}")
    if not same:
        raise SystemExit("the tables differ")


if __name__ == "__main__":
    main()
