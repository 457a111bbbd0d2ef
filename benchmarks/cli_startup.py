"""Start-up time of the command line: ``thirdhand --help`` beside its floor.

The floor is ``python -c "import numpy, typer, rich"`` (what any typer command
line over numpy pays). Both run as fresh processes, alternated, ``--repeat``
times each (default 5); the medians and their ratio are printed. The issue's bar
is a ratio of at most 2.

Usage: ``python benchmarks/cli_startup.py [--repeat N]``
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time
from pathlib import Path


def _seconds(argv: list[str]) -> float:
    start = time.perf_counter()
    subprocess.run(argv, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="runs of each (median taken)")
    args = parser.parse_args()
    if args.repeat < 1:
        parser.error("--repeat must be at least 1")
    exe = Path(sys.executable).with_name("thirdhand")
    # The installed entry point beside this interpreter, else the module itself.
    ours = [str(exe), "--help"] if exe.exists() else [sys.executable, "-m", "thirdhand", "--help"]
    floor = [sys.executable, "-c", "import numpy, typer, rich"]
    _seconds(ours), _seconds(floor)  # warm the file cache
    t_ours: list[float] = []
    t_floor: list[float] = []
    for _ in range(args.repeat):
        t_ours.append(_seconds(ours))
        t_floor.append(_seconds(floor))
    m_ours, m_floor = statistics.median(t_ours), statistics.median(t_floor)
    print(f"{'command':<40} {'median s':>9}   runs")
    print(f"{'thirdhand --help':<40} {m_ours:9.3f}   " + " ".join(f"{t:.2f}" for t in t_ours))
    print(
        f"{'python -c import numpy, typer, rich':<40} {m_floor:9.3f}   "
        + " ".join(f"{t:.2f}" for t in t_floor)
    )
    print(f"ratio thirdhand / floor: {m_ours / m_floor:.2f} (bar: <= 2)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
