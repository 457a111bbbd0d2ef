"""Train the segmentation model shipped with thirdhand (``thirdhand/data/segment_default.json``).

Training set (seeded, reproducible):

- every synthetic scene of :mod:`thirdhand.synth` (chair, bench, toolbox,
  drawer, lid), seeds ``0 … n_seeds − 1``, each seen through a sensor and done
  by a person drawn at random (``SensorModel.random``: 10 µm–1 mm noise,
  20–120 Hz, hub dropouts, stamp jitter; ``HumanModel.random``: a third of the
  people rest truly still), **with the part geometry withheld in every other
  scene** (real recordings rarely come with meshes: the contact feature must
  mean the same with and without them);
- seeds ``100 …`` through the default sensor (1 mm, 120 Hz) and ``200 …``
  without noise;
- the real labelled pairs of ``../shared/data/3rdhand/toolbox_coop_4`` — the
  left hand's three fingers with both boards, the only public labels — entered
  ``--real-repeat`` times (``--no-real``: the synthetic-only model).

The synthetic labels follow the report's definition (a hand interacts with an
object while it moves it; :mod:`thirdhand.synth.script`), and the model carries
the rest gate (:mod:`thirdhand.segment.noise`) and noise-adaptive ``ε``.

Features: 20 latent steps per second, windows of 5 steps (0.25 s), 10 and 2
steps, the origin distance and the contact distance (see
:mod:`thirdhand.segment.design`).

Then the model is scored on held-out seeds (``1000 …``) — default sensor,
noise-free and randomised — per pair kind, and on the real left-hand pairs.

Usage: ``python research/scripts/train_default_segmenter.py [--seeds 4] [--default-seeds 1]
[--clean 1] [--test-seeds 2] [--no-real] [--real-repeat 20] [--leave-out-board NAME] [-o PATH]``
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from thirdhand.demonstration import Demonstration
from thirdhand.segment.assembly import ClosureConfig
from thirdhand.segment.design import FeatureConfig
from thirdhand.segment.features import RAW_FEATURE_NAMES as RAW
from thirdhand.segment.model import SegmentModel
from thirdhand.segment.pipeline import scores_by_kind, segment_demonstration

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository root: `research`

from research.segment_real import TOOLBOX_COOP_4, hand_scores, load_labelled, score_model
from thirdhand.segment.training import fit_model
from thirdhand.synth import SCENES, make_scene, random_scene

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OUT = ROOT / "src" / "thirdhand" / "data"
SHARED = ROOT.parent / "shared" / "data"


def without_board(demo: Demonstration, board: str) -> Demonstration:
    """The labelled recording without ``board`` (leave-one-board-out).

    The board is dropped with its labels, so its pairs are neither positives nor
    negatives in training.
    """
    if board not in demo.body_names:
        raise SystemExit(f"no body {board!r} in {demo!r}")
    return demo.select([n for n in demo.body_names if n != board])


def hand_exclusions(cfg: FeatureConfig, windows: str) -> dict[str, list[str]]:
    """Feature names of the windows the finger/hand–object weights leave out.

    The 0.1 s window resolves the short pauses of part–part and tool–part chains
    (a drawer held in one hand and slid by the other); for a hand moving an object
    it reads noise on a real tracker (6–10 samples, a fifth of them lost).
    """
    keep = {int(w) for w in windows.split(",") if w}
    names = cfg.feature_names
    dropped = [f"log_eps_w{w}_{n}" for w in cfg.extra_windows if w not in keep for n in RAW]
    if cfg.long_window and cfg.long_window not in keep:
        dropped += [f"log_eps_long_{n}" for n in RAW]
    return {"finger-object": [n for n in dropped if n in names]} if dropped else {}


def training_set(args: argparse.Namespace) -> tuple[list[Demonstration], list[Any], list[int]]:
    demos: list[Demonstration] = []
    for k in range(args.seeds):
        demos += [random_scene(s, k, geometry=k % 2 == 0) for s in SCENES]
    demos += [make_scene(s, seed=100 + k) for s in SCENES for k in range(args.default_seeds)]
    demos += [make_scene(s, seed=200 + k, sensor=None) for s in SCENES for k in range(args.clean)]
    hands: list[Any] = [None] * len(demos)
    repeat = [1] * len(demos)
    if not args.no_real:
        real = load_labelled(args.real)
        if args.leave_out_board:
            real = without_board(real, args.leave_out_board)
        demos.append(real)
        hands.append("left")
        repeat.append(args.real_repeat)
    return demos, hands, repeat


def evaluate(model: SegmentModel, args: argparse.Namespace) -> dict[str, Any]:
    rows: dict[str, list[float]] = {}
    conds = () if args.real_only_eval else ("default sensor", "noise-free", "random sensor")
    for cond in conds:
        for scene in SCENES:
            for k in range(args.test_seeds):
                seed = 1000 + k
                if cond == "default sensor":
                    demo = make_scene(scene, seed=seed)
                elif cond == "noise-free":
                    demo = make_scene(scene, seed=seed, sensor=None)
                else:
                    demo = random_scene(scene, seed, geometry=k % 2 == 0)
                for kind, s in scores_by_kind(segment_demonstration(demo, model)).items():
                    rows.setdefault(f"{cond} {kind}", []).append(s["frame_f1"])
    out: dict[str, Any] = {k: round(float(np.mean(v)), 4) for k, v in sorted(rows.items())}
    if args.real.exists():
        real = load_labelled(args.real)
        if args.leave_out_board:
            held = hand_scores(segment_demonstration(real, model), objects=[args.leave_out_board])
            out[f"real left hand, held-out board {args.leave_out_board}"] = {
                "frame_f1": round(held.frame_f1, 4),
                "interval_recall": round(held.interval_recall, 4),
            }
        sc = score_model(model, real)
        out["real toolbox_coop_4 left hand"] = {
            "frame_f1": round(sc.frame_f1, 4),
            "interval_recall": round(sc.interval_recall, 4),
            "per_pair": {f"{a} · {b}": round(v, 4) for (a, b), v in sc.per_pair.items()},
        }
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=4, help="randomised training seeds per scene")
    ap.add_argument("--default-seeds", type=int, default=1, help="default-sensor seeds per scene")
    ap.add_argument("--clean", type=int, default=1, help="noise-free training seeds per scene")
    ap.add_argument("--test-seeds", type=int, default=2, help="held-out seeds per scene")
    ap.add_argument("--real", type=Path, default=SHARED / TOOLBOX_COOP_4)
    ap.add_argument("--no-real", action="store_true", help="synthetic scenes only")
    ap.add_argument("--real-repeat", type=int, default=20, help="weight of the real sequences")
    ap.add_argument("--leave-out-board", default="", help="drop this board's real labels")
    ap.add_argument("--l2", type=float, default=1.0)
    ap.add_argument("--extra-windows", default="2", help="latent steps, comma-separated")
    ap.add_argument(
        "--hand-windows",
        default="5,10",
        help="windows (latent steps) the finger/hand-object weights use; others are excluded",
    )
    ap.add_argument("--long-window", type=int, default=10, help="latent steps (0: none)")
    ap.add_argument("--no-distance", action="store_true", help="no origin-distance feature")
    ap.add_argument("--no-contact", action="store_true", help="no contact-distance feature")
    ap.add_argument("--fill-gaps", type=float, default=5.0, help="static gap filling, s")
    ap.add_argument("--real-only-eval", action="store_true", help="score on the real pairs only")
    ap.add_argument("-o", "--output", type=Path, default=DEFAULT_OUT / "segment_default.json")
    args = ap.parse_args()

    t0 = time.perf_counter()
    demos, hands, repeat = training_set(args)
    cfg = FeatureConfig(
        latent_rate=20.0,
        window=5,
        long_window=args.long_window,
        eps_pos=3e-5,
        eps_rot=3e-4,
        distance=not args.no_distance,
        extra_windows=tuple(int(w) for w in args.extra_windows.split(",") if w),
        contact=not args.no_contact,
        adaptive_eps=True,
        fill_gaps_s=args.fill_gaps,
    )
    real = "" if args.no_real else f" + {args.real.name} left hand x{args.real_repeat}"
    if args.leave_out_board:
        real += f" (without {args.leave_out_board})"
    model = fit_model(
        demos,
        cfg,
        l2=args.l2,
        hand=hands,
        repeat=repeat,
        closure=ClosureConfig(0.01),
        rest_gate=True,
        exclude=dict(hand_exclusions(cfg, args.hand_windows)),
        training={
            "data": f"thirdhand.synth scenes {', '.join(SCENES)}: seeds 0..{args.seeds - 1} "
            f"random sensor and person (geometry withheld on odd seeds), "
            f"{args.default_seeds} default-sensor and {args.clean} noise-free seed(s){real}",
            "script": "research/scripts/train_default_segmenter.py",
        },
    )
    print(f"trained on {len(demos)} recordings in {time.perf_counter() - t0:.1f} s")
    model.training["held_out"] = evaluate(model, args)
    for k, v in model.training["held_out"].items():
        print(f"{k:45s} {v}")
    args.output.parent.mkdir(parents=True, exist_ok=True)
    model.save(args.output)
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
