"""Synthetic sweep of constraint fits: type accuracy and axis error by condition, calibration.

Every joint type (fixed, prismatic, revolute, cylindrical, free; oriented and
position-only) under each condition — white noise 10 µm … 2 cm (rotation 0.5°
per mm), a precise tracker (0.05 mm) with a 1-2 mm calibration error, 20 to
1,000 samples, 10 % gross outliers, noise correlated over 2 samples (2.5 times
the white level: the colour of the real camera tracks), an error that varies
with the pose (twice and four times the white level: a camera's distortion), an
error that wanders with time on still parts too (twice), a 10° opening — fitted
with the default flags (noise estimated from the track). Prints Markdown
tables: accuracy where the motion is at least 5× the noise (the extent, and the
motion of the degree of freedom that sets the type apart), median and
95th-percentile axis errors, then the confidence's reliability: the temperature
of least log loss on the calibration seeds, and the reliability table and
expected calibration error (ECE) on the held-out seeds, with plain BIC weights
and with the shipped calibration (the 10° openings left out of both:
position-only, they are prismatic by design).

Usage: ``python research/scripts/constraint_sweep.py [--seeds 10] [--first-seed N]``: the
held-out seeds are ``N`` to ``N + seeds - 1`` (default ``N = seeds``: 10-19), the
calibration seeds always ``0`` to ``seeds - 1``.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", os.environ.get("OMP_NUM_THREADS", "1"))

import argparse
import math
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

from thirdhand.constraints.select import (
    CONFIDENCE_FLOOR,
    CONFIDENCE_TEMPERATURE,
    PASSED_OVER_WEIGHT,
)

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository root: `research`

from research.constraint_sweep import (
    CASES,
    Condition,
    Trial,
    fit_calibration,
    log_loss,
    reliability,
    run_sweep,
)

NOISE = (1e-5, 1e-4, 1e-3, 3e-3, 1e-2, 2e-2)
#: Bows of the bowed-rail conditions, fractions of the chord.
BOWS = (0.01, 0.03)


def conditions() -> list[Condition]:
    """Every condition of the sweep."""
    out = [Condition(f"white {1e3 * s:g} mm", s) for s in NOISE]
    # A precise tracker with a calibration error (a robot's encoders): 0.05 mm of
    # jitter, a pose-dependent error of 1 and 2 mm (0.5° and 1°).
    out += [
        Condition(f"0.05 mm, pose bias {1e3 * b * 5e-5:g} mm", 5e-5, bias=b) for b in (20.0, 40.0)
    ]
    for s in (1e-3, 1e-2):
        tag = f"{1e3 * s:g} mm"
        out += [
            Condition(f"20 samples, {tag}", s, n=20),
            Condition(f"50 samples, {tag}", s, n=50),
            Condition(f"1000 samples, {tag}", s, n=1000),
            Condition(f"10 % outliers, {tag}", s, outliers=0.1),
            Condition(f"coloured 2.5x, {tag}", s, colour=2.5),
            Condition(f"pose bias 2x, {tag}", s, bias=2.0),
            Condition(f"pose bias 4x, {tag}", s, bias=4.0),
            Condition(f"time drift 2x, {tag}", s, drift=2.0),
            Condition(f"10° opening, {tag}", s, span=math.radians(10.0)),
        ]
    # Bowed rails / calibration warps as measured on the real prismatic tracks:
    # the median (1 %) and the upper end (3 %) of their bow, as a fraction of the chord.
    out += [Condition(f"bowed rail {100 * b:g} %, 1 mm", 1e-3, rail_bow=b) for b in BOWS]
    return out


def _label(kind: str, oriented: bool) -> str:
    return kind[:4] + ("" if oriented else "·p")


def accuracy_table(trials: list[Trial]) -> None:
    """Accuracy (motion >= 5x noise) per condition and case, Markdown."""
    cells: dict[tuple[str, str], list[bool]] = defaultdict(list)
    every: dict[str, list[bool]] = defaultdict(list)
    by_dof: dict[str, list[bool]] = defaultdict(list)
    names = list(dict.fromkeys(t.condition.name for t in trials))
    for t in trials:
        every[t.condition.name].append(t.correct)
        if t.dof_ratio >= 5.0:
            by_dof[t.condition.name].append(t.correct)
        if t.motion_ratio >= 5.0:
            cells[(t.condition.name, _label(t.kind, t.oriented))].append(t.correct)
    labels = [_label(k, o) for k, o in CASES]
    print("| condition | " + " | ".join(labels) + " | ≥ 5× noise | ≥ 5× per DOF | all |")
    print("|---" * (len(labels) + 4) + "|")
    for name in names:
        row = []
        ok_all: list[bool] = []
        for lab in labels:
            v = cells.get((name, lab), [])
            ok_all += v
            row.append(f"{100 * np.mean(v):.0f}" if v else "–")
        acc = f"{100 * np.mean(ok_all):.1f} %" if ok_all else "–"
        dof = by_dof.get(name, [])
        acc_dof = f"{100 * np.mean(dof):.1f} % ({len(dof)})" if dof else "–"
        print(
            f"| {name} | " + " | ".join(row) + f" | {acc} | {acc_dof} | "
            f"{100 * np.mean(every[name]):.1f} % |"
        )
    ok = [t.correct for t in trials if t.motion_ratio >= 5.0]
    print(f"\nOverall, motion ≥ 5× noise: {sum(ok)}/{len(ok)} = {100 * np.mean(ok):.1f} %")
    ok = [t.correct for t in trials if t.dof_ratio >= 5.0]
    print(
        f"Overall, distinguishing motion ≥ 5× noise: {sum(ok)}/{len(ok)} "
        f"= {100 * np.mean(ok):.1f} %"
    )
    ok = [t.correct for t in trials]
    print(f"Overall, every track: {sum(ok)}/{len(ok)} = {100 * np.mean(ok):.1f} %\n")


def dof_table(trials: list[Trial]) -> None:
    """Accuracy per condition and case where the distinguishing motion is >= 5x the noise."""
    cells: dict[tuple[str, str], list[bool]] = defaultdict(list)
    for t in trials:
        if t.dof_ratio >= 5.0:
            cells[(t.condition.name, _label(t.kind, t.oriented))].append(t.correct)
    labels = [_label(k, o) for k, o in CASES]
    print("| condition (per DOF) | " + " | ".join(labels) + " |")
    print("|---" * (len(labels) + 1) + "|")
    for name in dict.fromkeys(t.condition.name for t in trials):
        row = []
        for lab in labels:
            v = cells.get((name, lab), [])
            row.append(
                f"{100 * np.mean(v):.0f} ({len(v)})"
                if v and len(v) < 10
                else (f"{100 * np.mean(v):.0f}" if v else "–")
            )
        print(f"| {name} | " + " | ".join(row) + " |")
    print()


def axis_table(trials: list[Trial]) -> None:
    """Axis error (degrees) of correctly typed joints, per condition, Markdown."""
    print("| condition | prismatic median / p95 (°) | revolute | cylindrical |")
    print("|---|---|---|---|")
    for name in dict.fromkeys(t.condition.name for t in trials):
        row = []
        for kind in ("prismatic", "revolute", "cylindrical"):
            e = [t.axis_error for t in trials if t.condition.name == name and t.kind == kind]
            e = [x for x in e if math.isfinite(x)]
            row.append(f"{np.median(e):.3f} / {np.percentile(e, 95):.3f}" if e else "–")
        print(f"| {name} | " + " | ".join(row) + " |")
    print()


def calibration(fit_on: list[Trial], held_out: list[Trial]) -> None:
    """Fitted calibration and reliability tables on the held-out seeds, Markdown."""
    temp, floor, weight = fit_calibration(fit_on)
    print(
        f"Calibration of least log loss on the calibration seeds: temperature {temp:.2f}, "
        f"floor {floor:g}, passed-over weight {weight:g} (shipped: "
        f"{CONFIDENCE_TEMPERATURE:g}, {CONFIDENCE_FLOOR:g}, {PASSED_OVER_WEIGHT:g})\n"
    )
    plain = [
        t
        for t in held_out
        if t.condition.drift == 0.0 and t.condition.bias == 0.0 and t.condition.colour == 0.0
    ]
    for label, trials in (("every condition", held_out), ("without the slow error", plain)):
        for t_name, t, f, e in (
            ("plain BIC weights", 1.0, 0.0, 0.0),
            (
                "shipped calibration",
                CONFIDENCE_TEMPERATURE,
                CONFIDENCE_FLOOR,
                PASSED_OVER_WEIGHT,
            ),
        ):
            table, ece = reliability(trials, temperature=t, floor=f, passed_over_weight=e)
            print(
                f"Held-out seeds, {label}, {t_name}: ECE {ece:.3f}, "
                f"log loss {log_loss(trials, t, f, e):.3f}\n"
            )
            print("| confidence bin | mean confidence | accuracy | tracks |")
            print("|---|---|---|---|")
            for lo, conf, acc, count in table:
                print(f"| ≥ {lo:.2f} | {conf:.3f} | {acc:.3f} | {count} |")
            print()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=10, help="seeds per cell and split")
    parser.add_argument(
        "--first-seed",
        type=int,
        default=None,
        help="first held-out seed (default: --seeds; the calibration seeds are 0 to seeds-1)",
    )
    args = parser.parse_args()
    conds = conditions()
    first = args.seeds if args.first_seed is None else args.first_seed
    if first < args.seeds:
        parser.error(f"--first-seed {first} overlaps the calibration seeds 0-{args.seeds - 1}")
    held_out = list(run_sweep(conds, range(first, first + args.seeds)))
    print(
        f"{len(held_out)} tracks ({args.seeds} per cell, seeds {first}-{first + args.seeds - 1})\n"
    )
    accuracy_table(held_out)
    old_world = [t.correct for t in held_out if t.dof_ratio >= 5.0 and not t.condition.rail_bow]
    print(
        "Distinguishing motion ≥ 5× noise, without the bowed rails: "
        f"{sum(old_world)}/{len(old_world)} = {100 * np.mean(old_world):.1f} %\n"
    )
    dof_table(held_out)
    axis_table(held_out)
    # The 10° openings are left out of the calibration: position-only, they are
    # called prismatic by design (the turn guard), a choice and not noise.
    # The bowed rails are left out too: the calibration stays that of the sweep it was
    # fitted on (their tracks are in the accuracy tables above).
    typical = [c for c in conds if c.span is None and not c.rail_bow]
    fit_on = list(run_sweep(typical, range(args.seeds)))
    calibration(fit_on, [t for t in held_out if t.condition.span is None])


if __name__ == "__main__":
    main()
