"""Print the primitives stage's figures: imitation, 7-DMP vs quaternion DMP, generalisation,
DP vs brute force, the sine experiment, LASA join recovery, the chair constraints.

Run: ``.venv/bin/python research/scripts/primitives_experiments.py [--plots DIR]``.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import sys

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository root: `research`

from research.primitive_library import (
    dp_check,
    lasa_join_experiment,
    library_scaling,
    orientation_comparison,
    sine_experiment,
)
from thirdhand.primitives.segments import constraint_segments, group_segments
from thirdhand.primitives.stage import fit_constraint_primitive, generalisation_check

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


def main() -> None:
    ap = argparse.ArgumentParser(description="primitives experiments")
    ap.add_argument("--plots", type=Path, default=None, help="folder for PNG figures")
    ap.add_argument("--data", type=Path, default=DATA)
    args = ap.parse_args()

    oc = orientation_comparison()
    print("== imitation of a smooth 6-DoF demo (2 s, 120 Hz, 30 weights)")
    for k, v in oc["imitation"].items():
        print(f"  {k:10} position {v['pos_mm']:.4f} mm, orientation {v['rot_deg']:.4f} deg")
    print("== new goal orientation: error at 1.5 tau (deg), seven-DMP smallest |q|")
    for r in oc["new_goal"]:
        print(
            f"  goal moved {r['goal_change_deg']:5.0f} deg: quaternion DMP "
            f"{r['quaternion_final_deg']:.4f}, seven-DMP {r['seven_final_deg']:.4f}, "
            f"min |q| {r['seven_min_norm']:.3f}"
        )

    print("== new start orientation: error at 1.5 tau (deg), largest step (deg), seven min |q|")
    for r in oc["new_start"]:
        print(
            f"  start moved {r['start_change_deg']:5.0f} deg: quaternion DMP "
            f"{r['quaternion_final_deg']:.4f} (step {r['quaternion_max_step_deg']:.2f}), "
            f"seven-DMP {r['seven_final_deg']:.4f} (step {r['seven_max_step_deg']:.2f}), "
            f"min |q| {r['seven_min_norm']:.3f}"
        )

    from thirdhand.synth import make_scene

    demos = [make_scene("chair", seed=s, sensor=None) for s in range(3)]
    groups = group_segments([s for d in demos for s in constraint_segments(d)])
    print("== chair constraints (3 demos, child in parent frame), imitation of the average")
    grid = np.array(
        [[dx, dy, dz] for dx in (-0.2, 0, 0.2) for dy in (0, 0.2) for dz in (-0.2, 0, 0.2)]
    )
    for key, segs in groups.items():
        for orient in ("quaternion", "seven"):
            t0 = time.perf_counter()
            prim = fit_constraint_primitive(segs, orientation=orient)
            fit_s = time.perf_counter() - t0
            line = (
                f"  {key} {prim.child:5} {orient:10} {prim.dmp.position_.n_weights:3} weights: "
                f"{1000 * prim.imitation_pos_m:.3f} mm, {prim.imitation_rot_deg:.3f} deg "
                f"({fit_s:.2f} s)"
            )
            if orient == "quaternion":
                pe, re = generalisation_check(
                    prim.dmp,
                    goal_pos=prim.goal_pos,
                    goal_quat=prim.goal_quat,
                    offsets=grid,
                    run_factor=1.5,
                )
                line += (
                    f"; {len(grid)} starts ±0.2 m: worst final error {1000 * pe.max():.3f} mm, "
                    f"{np.degrees(re.max()):.4f} deg"
                )
                if args.plots is not None and key == "c3":
                    from thirdhand.primitives.plot import plot_generalisation

                    args.plots.mkdir(parents=True, exist_ok=True)
                    _, p_demo, _ = prim.dmp.rollout()
                    plot_generalisation(
                        prim.dmp,
                        args.plots / "primitives_generalisation.png",
                        goal_pos=prim.goal_pos,
                        goal_quat=prim.goal_quat,
                        offsets=grid,
                        demo_pos=p_demo,
                        title=f"{key}: {prim.child} into {prim.parent}, {len(grid)} starts",
                    )
            print(line)

    dp = dp_check()
    print("== forward-backward segment marginals vs brute-force enumeration")
    for r in dp["rows"]:
        print(
            f"  M={r['M']:2}: max |u_dp - u_bf| = {r['max_abs_diff']:.1e}, "
            f"|logZ diff| = {r['logz_diff']:.1e}, dp {1000 * r['dp_s']:.1f} ms, "
            f"brute {1000 * r['brute_s']:.1f} ms"
        )
    print(f"  M={dp['big_M']}: marginals in {1000 * dp['big_s']:.1f} ms")

    ls = library_scaling()
    print(
        f"== library parser on one track of {ls['n_samples']} samples, {ls['n_candidates']} "
        f"candidate cuts: fit {ls['fit_s']:.2f} s ({ls['n_init']} restarts), "
        f"parse {ls['parse_s']:.3f} s, "
        f"{ls['n_cuts']} cuts kept ({ls['true_cuts']} true)"
    )
    se = sine_experiment()
    print("== sine experiment (10 training tracks, 10 test tracks)")
    print(
        f"  skills found {se['skills_found']}, boundaries exact on {se['boundaries_exact']}/"
        f"{se['n_test']} test tracks, labels consistent {se['labels_consistent']}, "
        f"{se['n_cuts']} cuts kept of {se['n_candidates']} candidates, fit {se['fit_s']:.2f} s"
    )
    lasa = args.data / "lasa"
    if lasa.is_dir():
        le = lasa_join_experiment(lasa)
        print("== LASA concatenations (Worm, GShape, PShape; 8 train / 4 test tracks)")
        print(
            f"  joins recovered {le['joins_recovered']}/{le['joins']}, extra cuts "
            f"{le['extra_cuts']}, {le['n_candidates']} candidates, labels consistent "
            f"{le['labels_consistent']} {le['mapping']}, fit {le['fit_s']:.2f} s"
        )
    if args.plots is not None:
        from thirdhand.primitives.plot import plot_library

        args.plots.mkdir(parents=True, exist_ok=True)
        from thirdhand.datasets.primitive_shapes import sine_tracks

        plot_library(
            se["library"],
            args.plots / "primitives_sine.png",
            tracks=[(t, y) for t, y, _, _ in sine_tracks(2, seed=1000)],
        )
        if lasa.is_dir():
            plot_library(
                le["library"],
                args.plots / "primitives_lasa.png",
                tracks=[(t, y) for t, y, _, _ in le["test"][:2]],
            )
        print(f"figures in {args.plots}")


if __name__ == "__main__":
    main()
