"""The segmentation table of research/notes/segmentation_results.md: real left-hand pairs first.

Models compared: the synthetic-only one (``-m synthetic``), the shipped default
(synthetic scenes plus the real left-hand pairs), and the synthetic-only model
calibrated (:mod:`thirdhand.segment.calibrate`) on the first ``--calibrate-s``
seconds of the real recording — scored on the rest of it only, which it did not
see — plus any model files given with ``--model NAME=PATH`` (e.g. the one shipped
before, or a leave-one-board-out model).

Rows: the real left hand of ``toolbox_coop_4`` (frame F1 and interval recall,
the whole recording and after the calibration span), then held-out synthetic
seeds (1000–1001) of every scene through the default sensor, without noise and
through a random sensor and person, per pair kind.

Usage: ``python research/scripts/segmentation_real_table.py [--model NAME=PATH …] [--calibrate-s 33]
[--no-synthetic]``
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from thirdhand.segment.calibrate import calibrate
from thirdhand.segment.model import SegmentModel, builtin_model, load_model
from thirdhand.segment.pipeline import scores_by_kind, segment_demonstration

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository root: `research`

from research.segment_real import TOOLBOX_COOP_4, hand_scores, load_labelled
from thirdhand.synth import SCENES, make_scene, random_scene

ROOT = Path(__file__).resolve().parents[1]


def after(result: object, t_cut: float) -> object:
    """The result restricted to latent steps after ``t_cut`` seconds (copy)."""
    import copy

    res = copy.deepcopy(result)
    keep = res.times > t_cut  # type: ignore[attr-defined]
    for p in res.pairs:  # type: ignore[attr-defined]
        p.label = p.label[keep]
        if p.truth is not None:
            p.truth = p.truth[keep]
    return res


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", action="append", default=[], help="NAME=PATH")
    ap.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data")
    ap.add_argument("--calibrate-s", type=float, default=33.0)
    ap.add_argument("--no-synthetic", action="store_true")
    args = ap.parse_args()

    real = load_labelled(args.data / TOOLBOX_COOP_4)
    t_cut = float(real.t[0]) + args.calibrate_s
    models: dict[str, SegmentModel] = {}
    for spec in args.model:
        name, _, path = spec.partition("=")
        models[name] = load_model(path)
    models["synthetic only"] = builtin_model("synthetic")
    models["shipped (synthetic + real)"] = builtin_model("default")
    calibrated, report = calibrate(builtin_model("synthetic"), [real], span=(0.0, args.calibrate_s))
    models[f"synthetic only, calibrated on 0–{args.calibrate_s:g} s"] = calibrated
    print(f"calibration: {report}")

    rows: dict[str, dict[str, str]] = {}
    for name, model in models.items():
        res = segment_demonstration(real, model)
        whole, rest = hand_scores(res), hand_scores(after(res, t_cut))  # type: ignore[arg-type]
        rows.setdefault("real left hand, whole recording: frame F1 (interval recall)", {})[name] = (
            f"{whole.frame_f1:.3f} ({whole.interval_recall:.2f})"
        )
        rows.setdefault(f"real left hand, after {args.calibrate_s:g} s", {})[name] = (
            f"{rest.frame_f1:.3f} ({rest.interval_recall:.2f})"
        )
        if args.no_synthetic:
            continue
        acc: dict[str, list[float]] = {}
        for cond in ("default sensor", "noise-free", "random sensor"):
            for scene in SCENES:
                for k in range(2):
                    if cond == "default sensor":
                        demo = make_scene(scene, seed=1000 + k)
                    elif cond == "noise-free":
                        demo = make_scene(scene, seed=1000 + k, sensor=None)
                    else:
                        demo = random_scene(scene, 1000 + k, geometry=k % 2 == 0)
                    for kind, s in scores_by_kind(segment_demonstration(demo, model)).items():
                        acc.setdefault(f"synthetic {cond}, {kind}", []).append(s["frame_f1"])
        for key, v in acc.items():
            rows.setdefault(key, {})[name] = f"{np.mean(v):.3f}"
    names = list(models)
    print("| | " + " | ".join(names) + " |")
    print("|---|" + "---:|" * len(names))
    for key, r in rows.items():
        print(f"| {key} | " + " | ".join(r.get(n, "") for n in names) + " |")


if __name__ == "__main__":
    main()
