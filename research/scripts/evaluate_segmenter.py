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

3. with ``--audit``, on the noise-free recordings, a label audit per scene and
   pair kind: the steps of each kinematic class (B's pose in A's frame changing;
   constant while A or B moves; constant with both still, see
   :func:`research.segment_diagnose.kinematic_classes`), how many are labelled
   1 and 0, and the model's false positives and negatives in each.

See :mod:`research.segment_diagnose` for the definitions.

Usage: ``python research/scripts/evaluate_segmenter.py [--model M] [--test-seeds 2] [-k 1]
[--scenes chair,drawer] [--audit] [--no-geometry] [--json OUT]``
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository root: `research`

from research.segment_diagnose import (
    ERROR_CLASSES,
    KINEMATIC_CLASSES,
    ErrorBreakdown,
    breakdown_by_kind,
    kinematic_classes,
)
from thirdhand.segment.features import latent_axis
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
    audit: dict[tuple[str, str, str], np.ndarray] | None = None,
    geometry: bool = True,
) -> list[dict[str, Any]]:
    """One row per (condition, scene, seed, kind) with its :class:`ErrorBreakdown`.

    ``audit``, when given, receives per (scene, kind, kinematic class) the counts
    ``[labelled 1, labelled 0, false positives, false negatives]`` of the
    noise-free recordings. ``geometry=False`` removes ``meta["geometry"]`` before
    segmenting (recordings without bounding boxes: the contact feature falls back
    to the origin distance).
    """
    rows = []
    for noisy in (True, False):
        for scene in scenes:
            for seed in seeds:
                demo = make_scene(scene, seed=seed, sensor=SensorModel() if noisy else None)
                if not geometry:
                    demo = demo.replace(
                        meta={k: v for k, v in demo.meta.items() if k != "geometry"}
                    )
                res = segment_demonstration(demo, model)
                if audit is not None and not noisy:
                    _audit(demo, res, audit, model.features.latent_rate)
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


def _audit(demo: Any, res: Any, out: dict[tuple[str, str, str], np.ndarray], rate: float) -> None:
    axis = latent_axis(demo.t, rate)
    for p in res.pairs:
        if p.truth is None:
            continue
        cls = kinematic_classes(demo, p.a, p.b, axis)
        t, y = p.truth != 0, p.label != 0
        for code, name in enumerate(KINEMATIC_CLASSES):
            m = cls == code
            c = out.setdefault((demo.meta["scene"], p.kind, name), np.zeros(4, dtype=np.int64))
            c += [np.sum(m & t), np.sum(m & ~t), np.sum(m & ~t & y), np.sum(m & t & ~y)]


def print_audit(audit: dict[tuple[str, str, str], np.ndarray]) -> None:
    """Print the label audit of :func:`evaluate`."""
    print(
        f"{'scene':8s} {'kind':14s} {'kinematics':14s} {'label 1':>8s} {'label 0':>8s} "
        f"{'FP':>6s} {'FN':>6s}"
    )
    for (scene, kind, name), c in audit.items():
        print(f"{scene:8s} {kind:14s} {name:14s} {c[0]:8d} {c[1]:8d} {c[2]:6d} {c[3]:6d}")


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
    ap.add_argument("--no-geometry", action="store_true", help="drop the bounding boxes")
    ap.add_argument("--audit", action="store_true", help="label audit of noise-free scenes")
    ap.add_argument("--json", type=Path, default=None, help="write the summary as JSON")
    args = ap.parse_args()
    model = default_model() if args.model is None else load_model(args.model)
    audit: dict[tuple[str, str, str], np.ndarray] | None = {} if args.audit else None
    rows = evaluate(
        model,
        scenes=args.scenes.split(","),
        seeds=range(1000, 1000 + args.test_seeds),
        k=args.k,
        audit=audit,
        geometry=not args.no_geometry,
    )
    print_tables(rows, args.k)
    if audit:
        print()
        print_audit(audit)
    if args.json is not None:
        args.json.write_text(json.dumps(summary(rows), indent=1) + "\n")


if __name__ == "__main__":
    main()
