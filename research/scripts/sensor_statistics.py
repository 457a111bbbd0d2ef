"""Sensor and human statistics of real recordings beside synthetic ones (docs table).

For each recording: frame rate, time-stamp jitter (standard deviation of the
frame interval over its median), fraction of samples lost, runs of lost frames
(median, 95th percentile, longest, per second), the noise floor per sensor
(:mod:`thirdhand.segment.noise`, median over sensors), and the motion of a
resting finger (the 2nd percentile of the 0.25 s windowed position standard
deviation of the fingers: what a hand at rest does).

Real: ``toolbox_coop_4`` (Polhemus G4) and the IKEA bags (AR tags, ROS 1).
Synthetic: the default sensor, and the randomised sensor and person of the
training set (``SensorModel.random``, ``HumanModel.random``; seeds 0–4, chair).

Usage: ``python research/scripts/sensor_statistics.py [--data ../shared/data]``
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from thirdhand.demonstration import Demonstration
from thirdhand.io import load
from thirdhand.segment.features import body_stats, latent_axis
from thirdhand.segment.intervals import runs
from thirdhand.segment.noise import noise_floor
from thirdhand.synth import HumanModel, SensorModel, make_scene

ROOT = Path(__file__).resolve().parents[1]


def statistics(demo: Demonstration) -> dict[str, float]:
    """The row of one recording."""
    dt = np.diff(demo.t)
    lost, lengths, sigma, rot = [], [], [], []
    finger_std: list[float] = []
    axis = latent_axis(demo.t, 4.0)  # 0.25 s steps
    for b in demo.bodies:
        tr = demo.track(b.name)
        lost.append(1.0 - tr.valid.mean())
        lengths += [hi - lo for lo, hi in runs((~tr.valid).astype(np.int64))]
        f = noise_floor(tr.pos, tr.quat, tr.valid)
        if f.n:
            sigma.append(f.pos_sigma_m)
            rot.append(float(np.sqrt(f.rot / 3.0) * 2.0))
        if b.kind == "finger":
            st = body_stats(tr.pos, tr.quat, tr.valid, axis, 1)
            ok = st.count >= 5
            finger_std += list(np.sqrt(st.var_pos[ok] / 3.0))
    ln = np.array(lengths) if lengths else np.zeros(1)
    duration = float(demo.t[-1] - demo.t[0])
    return {
        "rate_hz": float(1.0 / np.median(dt)),
        "stamp_jitter": float(np.std(dt) / np.median(dt)),
        "lost": float(np.mean(lost)),
        "run_median": float(np.median(ln)),
        "run_p95": float(np.percentile(ln, 95)),
        "run_max": float(ln.max()),
        "runs_per_s": len(lengths) / len(demo.bodies) / duration,
        "noise_um": float(np.median(sigma)) * 1e6 if sigma else float("nan"),
        "rot_noise_deg": float(np.degrees(np.median(rot))) if rot else float("nan"),
        "rest_finger_um": float(np.percentile(finger_std, 2)) * 1e6 if finger_std else float("nan"),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data")
    args = ap.parse_args()
    rows: list[tuple[str, dict[str, float]]] = []
    coop = args.data / "3rdhand" / "toolbox_coop_4"
    if coop.is_dir():
        rows.append(("real: toolbox_coop_4 (Polhemus G4)", statistics(load(coop))))
    for part in (1, 3, 4):
        bag = args.data / "niekum" / "ikea_table_leg_pos_1" / f"part{part}.bag"
        if bag.is_file():
            rows.append((f"real: IKEA part{part} (AR tags)", statistics(load(bag))))
    rows.append(("synthetic: default sensor, chair", statistics(make_scene("chair", seed=0))))
    for k in range(5):
        rng = np.random.default_rng([k, 31337])
        sensor, human = SensorModel.random(rng), HumanModel.random(rng)
        demo = make_scene("chair", seed=k, sensor=sensor, human=human)
        rows.append((f"synthetic: random {k} (idle {human.idle:.2f})", statistics(demo)))
    keys = list(rows[0][1])
    print("| recording | " + " | ".join(keys) + " |")
    print("|---|" + "---:|" * len(keys))
    for name, r in rows:
        print(f"| {name} | " + " | ".join(f"{r[k]:.3g}" for k in keys) + " |")


if __name__ == "__main__":
    main()
