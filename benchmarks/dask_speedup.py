"""Speed-up of ``python -m research irl noise`` on a Dask cluster of 2 workers against serial.

Starts a ``dask scheduler`` and two single-threaded ``dask worker`` processes on
127.0.0.1 (:func:`thirdhand.batch.dask_processes`, as in docs/how-to/cluster.md), runs
``python -m research irl noise --runs N --json …`` serially and then with
``--scheduler tcp://127.0.0.1:PORT`` on the cluster (the same trials as Dask
tasks), checks that both JSON tables and both printed tables are identical, and
prints both wall times and their ratio. The cluster's start-up is timed apart.
Unless ``--no-local``, also runs the same command with ``--jobs 2`` (local
processes), the peer the cluster is compared with.

Usage: ``python benchmarks/dask_speedup.py [--runs 4] [--no-local]``
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from thirdhand.batch import dask_processes


def run_cli(runs: int, target: Path, *extra: str) -> tuple[str, list[str], float]:
    """The JSON text, the printed table rows and the wall time of one CLI run."""
    cmd = [sys.executable, "-m", "research", "irl", "noise", "--runs", str(runs)]
    start = time.perf_counter()
    done = subprocess.run(
        [*cmd, "--json", str(target), *extra],
        capture_output=True,
        text=True,
        check=False,
        cwd=Path(__file__).resolve().parents[1],  # the repository root: `python -m research`
    )
    seconds = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(cmd + list(extra))} failed: {done.stderr.strip()}")
    rows = [line for line in done.stdout.splitlines() if "noise" in line and "%" in line]
    return target.read_text(), rows, seconds


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=4, help="seeds per row (at least 2)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--no-local", action="store_true", help="skip the --jobs run")
    args = ap.parse_args()
    print(f"cores: {os.cpu_count()}; load average: {os.getloadavg()[0]:.1f}")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        serial, rows, t_serial = run_cli(args.runs, folder / "serial.json")
        print(f"serial: {t_serial:.1f} s ({8 * args.runs} trials)")
        runs = {"serial": (serial, rows)}
        t_local = float("nan")
        if not args.no_local:
            text, local_rows, t_local = run_cli(
                args.runs, folder / "local.json", "--jobs", str(args.workers)
            )
            runs["local"] = (text, local_rows)
            print(f"--jobs {args.workers} (local processes): {t_local:.1f} s")
        start = time.perf_counter()
        with dask_processes(args.workers) as address:
            t_up = time.perf_counter() - start
            text, dask_rows, t_dask = run_cli(
                args.runs, folder / "dask.json", "--scheduler", address
            )
            runs["dask"] = (text, dask_rows)
    print(f"cluster start-up ({args.workers} workers): {t_up:.1f} s")
    print(f"--scheduler ({args.workers} Dask workers): {t_dask:.1f} s")
    same = all(v == runs["serial"] for v in runs.values())
    print(f"JSON and printed tables identical ({', '.join(runs)}): {same}")
    for row in rows:
        print("  " + row.strip())
    print(f"speed-up, Dask {args.workers} workers vs serial: {t_serial / t_dask:.2f}x")
    if not args.no_local:
        print(f"speed-up, --jobs {args.workers} vs serial: {t_serial / t_local:.2f}x")
        print(f"ratio Dask / local processes: {t_dask / t_local:.2f}")
    if not same:
        raise SystemExit("the tables differ")


if __name__ == "__main__":
    main()
