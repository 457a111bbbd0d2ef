"""Held-out evaluation of a segmentation model on the synthetic scenes, with an error breakdown.

For every scene of :mod:`thirdhand.synth` and held-out seeds ``1000 …``, noisy
(``SensorModel()`` defaults) and noise-free, segment with the model and print:

1. per scene and pair kind: strict frame F1, tolerant frame F1 (steps within
   ±k latent steps of a true boundary not scored), and where the wrong steps
   are: boundary shifts of at most k steps, whole missed true intervals, whole
   extra predicted intervals, other (bridged gaps, holes, long shifts); with
   the number of true intervals and how many were missed / predicted extra;
2. per pair kind, the mean over demonstrations of the per-demonstration frame
   F1 (the figure the targets are stated in) and of the tolerant F1.

See :mod:`thirdhand.segment.diagnose` for the definitions.

Usage: ``python scripts/evaluate_segmenter.py [--model M] [--test-seeds 2] [-k 1]
[--scenes chair,drawer] [--json OUT]``
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from thirdhand.segment.diagnose import ERROR_CLASSES, ErrorBreakdown, breakdown_by_kind
from thirdhand.segment.model import SegmentModel, default_model, load_model
from thirdhand.segment.pipeline import segment_demonstration
from thirdhand.synth import SCENES, SensorModel, make_scene

KINDS = ("finger-object", "hand-object (aggregated)", "tool-part", "part-part")


def evaluate(
    model: SegmentModel,
    *,
    scenes: Sequence[str] = SCENES,
    seeds: Sequence[int] = (1000, 1001),
    k: int = 1,
) -> list[dict[str, Any]]:
    """One row per (condition, scene, seed, kind) with its :class:`ErrorBreakdown`."""
    rows = []
    for noisy in (True, False):
        for scene in scenes:
            for seed in seeds:
                demo = make_scene(scene, seed=seed, sensor=SensorModel() if noisy else None)
                res = segment_demonstration(demo, model)
                for kind, b in breakdown_by_kind(res, k).items():
                    rows.append(
                        {
                            "condition": "noisy" if noisy else "noise-free",
                            "scene": scene,
                            "seed": seed,
                            "kind": kind,
                            "breakdown": b,
                        }
                    )
    return rows


def summary(rows: list[dict[str, Any]]) -> dict[str, dict[str, float]]:
    """Mean over demonstrations of frame F1 and tolerant F1, per condition and kind."""
    out: dict[str, dict[str, float]] = {}
    for cond in ("noisy", "noise-free"):
        for kind in KINDS:
            sel = [r["breakdown"] for r in rows if r["condition"] == cond and r["kind"] == kind]
            if sel:
                out[f"{cond} {kind}"] = {
                    "frame_f1": float(np.mean([b.f1 for b in sel])),
                    "collar_f1": float(np.mean([b.collar_f1 for b in sel])),
                }
    return out


def print_tables(rows: list[dict[str, Any]], k: int) -> None:
    """Print the per-scene table and the summary."""
    head = (
        f"{'condition':10s} {'scene':8s} {'kind':25s} {'F1':>6s} {f'F1±{k}':>6s} {'wrong':>6s} "
        + " ".join(f"{c[:6]:>6s}" for c in ERROR_CLASSES)
        + f" {'true':>5s} {'miss':>5s} {'pred':>5s} {'extra':>5s}"
    )
    print(head)
    for cond in ("noisy", "noise-free"):
        scenes = list(dict.fromkeys(r["scene"] for r in rows))
        for scene in scenes:
            for kind in KINDS:
                total = ErrorBreakdown()
                for r in rows:
                    if (r["condition"], r["scene"], r["kind"]) == (cond, scene, kind):
                        total += r["breakdown"]
                if total.steps == 0:
                    continue
                wrong = total.false_pos + total.false_neg
                shares = " ".join(f"{100 * total.share(c):5.0f}%" for c in ERROR_CLASSES)
                print(
                    f"{cond:10s} {scene:8s} {kind:25s} {total.f1:6.3f} {total.collar_f1:6.3f} "
                    f"{wrong:6d} {shares} {total.true_intervals:5d} {total.missed_intervals:5d} "
                    f"{total.pred_intervals:5d} {total.extra_intervals:5d}"
                )
    print()
    print(f"{'mean over demonstrations':40s} {'frame F1':>9s} {f'F1 ±{k}':>9s}")
    for key, v in summary(rows).items():
        print(f"{key:40s} {v['frame_f1']:9.3f} {v['collar_f1']:9.3f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", type=Path, default=None, help="model JSON (default: shipped)")
    ap.add_argument("--test-seeds", type=int, default=2, help="held-out seeds 1000…")
    ap.add_argument("-k", type=int, default=1, help="boundary tolerance, latent steps")
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--json", type=Path, default=None, help="write the summary as JSON")
    args = ap.parse_args()
    model = default_model() if args.model is None else load_model(args.model)
    rows = evaluate(
        model,
        scenes=args.scenes.split(","),
        seeds=range(1000, 1000 + args.test_seeds),
        k=args.k,
    )
    print_tables(rows, args.k)
    if args.json is not None:
        args.json.write_text(json.dumps(summary(rows), indent=1) + "\n")


if __name__ == "__main__":
    main()
