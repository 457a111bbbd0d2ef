"""The parser's exact E-step: forward–backward over cuts vs brute-force enumeration, and scale.

Printed, in one run: for M = 4, 8, 12 candidate cuts the largest difference
between the DP's segment marginals and the enumeration of all ``2^M``
segmentations, the time of each and their ratio; the DP's time for M = 200;
and a whole library fit + parse on one track with about 200 candidate cuts.

Usage: ``python benchmarks/library_dp.py``
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository root: `research`

from research.primitive_library import dp_check, library_scaling


def main() -> None:
    r = dp_check(sizes=(4, 8, 12), big=200)
    print("== segment marginals: DP vs brute force")
    for row in r["rows"]:
        print(
            "  "
            + ", ".join(
                f"{k} {v:.3g}" if isinstance(v, float) else f"{k} {v}" for k, v in row.items()
            )
        )
    print(f"  DP with M = {r['big_M']} cuts: {r['big_s']:.3f} s")
    s = library_scaling()
    print(
        f"== library on one track: {s['n_samples']} samples, {s['n_candidates']} candidate cuts: "
        f"fit {s['fit_s']:.1f} s ({s['n_init']} restarts), parse {s['parse_s']:.2f} s, "
        f"{s['n_cuts']} cuts kept of {s['true_cuts']} true"
    )


if __name__ == "__main__":
    main()
