"""Run the three planning experiments and print Markdown tables beside the report's numbers.

Usage::

    .venv/bin/python research/scripts/plan_experiments.py [--runs 96] [--seeds 5]

The same tables as ``python -m research experiment constraints|plan|corrections``, in one
go and in Markdown (for a report). The 96-run plan experiment takes minutes.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository root: `research`

from research.plan_accuracy import (
    Row,
    constraint_error_table,
    corrections_table,
    plan_success_table,
)


def markdown(title: str, rows: list[Row]) -> str:
    """A Markdown table of experiment rows."""
    lines = [f"### {title}", "", "| case | thirdhand | report |", "|---|---|---|"]
    lines += [f"| {r.label} | {r.ours} | {r.report} |" for r in rows]
    return "\n".join(lines) + "\n"


def main() -> None:
    """Parse the arguments and print the tables."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=96, help="seeded runs of the plan experiment")
    parser.add_argument("--seeds", type=int, default=5, help="seeds per scene and noise level")
    args = parser.parse_args()
    print(markdown("Constraint pose error", constraint_error_table(seeds=range(args.seeds))))
    print(markdown("Parameters to correct", corrections_table(seeds=range(args.seeds))))
    for scene in ("chair", "bench"):
        print(markdown(f"Plan success ({scene})", plan_success_table(scene=scene, runs=args.runs)))


if __name__ == "__main__":
    main()
