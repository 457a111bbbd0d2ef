"""Merge recovery figures: synthetic pairs by condition, and the IKEA bags against moved copies.

Synthetic (``research.merge_synthetic.make_pair``): reference at 120 Hz, other
system at 100 Hz, 60 s, random world rotation per seed, offset 3.2571 s, drift
150 ppm; conditions: noise-free; 0.5 mm noise; 2 mm noise; 0.5 mm noise + 10 %
gross outliers (5-20 cm) on one body + 0.5 s gaps. Real: Niekum's IKEA table-leg
bags (parts 1-4, AR tags ar_0 and ar_13, 23 Hz) against a copy starting 2.5 s
later on a clock 80 ppm fast in a moved world frame, written by our writers as a
3rdHand poses.dat folder (same samples), a 30 Hz C3D and a 30 Hz Motive CSV
(resampled), and a 30 Hz copy with 1 mm noise added. Prints Markdown tables of
the errors (median and worst over seeds) and writes ``docs/images/merge_errors.png``.

Usage::

    python research/scripts/merge_figures.py [--seeds 10] [--plot docs/images/merge_errors.png]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from thirdhand import io, se3
from thirdhand.io import rosbag
from thirdhand.merge import merge

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository root: `research`

from research.merge_synthetic import make_pair

CONDITIONS = {
    "noise-free": {},
    "0.5 mm noise": {"noise_m": 0.5e-3},
    "2 mm noise": {"noise_m": 2e-3},
    "0.5 mm + 10 % outliers + gaps": {"noise_m": 0.5e-3, "outliers": 0.1, "gaps": True},
    "0.5 mm noise, --smooth": {"noise_m": 0.5e-3, "smooth": True},
    "2 mm noise, --smooth": {"noise_m": 2e-3, "smooth": True},
    "0.5 mm + outliers + gaps, --smooth": {
        "noise_m": 0.5e-3,
        "outliers": 0.1,
        "gaps": True,
        "smooth": True,
    },
}


def errors(al, offset, drift, p_r, q_r):
    return (
        1e3 * abs(al.offset_s - offset),
        1e6 * abs(al.drift - drift),
        1e3 * float(np.linalg.norm(np.asarray(al.translation) - p_r)),
        float(np.degrees(se3.quat_angle(np.asarray(al.rotation), q_r))),
        1e3 * max(r.rms_m for r in al.residuals),
    )


def synthetic(seeds: int) -> dict[str, np.ndarray]:
    out = {}
    for name, kw in CONDITIONS.items():
        rows = []
        pair = {k: v for k, v in kw.items() if k != "smooth"}
        for seed in range(seeds):
            ref, other, truth = make_pair(seed=seed, **pair)  # type: ignore[arg-type]
            _, (al,) = merge([ref, other], smooth=bool(kw.get("smooth", False)))
            rows.append(errors(al, truth.offset_s, truth.drift, truth.translation, truth.rotation))
        out[name] = np.asarray(rows)
    return out


def moved_copy(demo, off, drift, p_r, q_r, rate=None, noise=0.0, seed=0):
    d = demo.slice(start=off)
    pi, qi = se3.pose_invert(p_r, q_r)
    rng = np.random.default_rng(seed)
    tracks = {}
    for n in d.body_names:
        p, q = se3.pose_compose(pi, qi, d.pos(n), d.quat(n))
        tracks[n] = (p, q, d.valid(n))
    out = d.replace(t=(d.t - off) / (1 + drift), tracks=tracks, meta={})
    if rate:
        out = out.resample(rate, max_gap=0.2)
    if noise:
        tr = {
            n: (
                out.pos(n) + rng.normal(scale=noise, size=out.pos(n).shape),
                out.quat(n),
                out.valid(n),
            )
            for n in out.body_names
        }
        out = out.replace(tracks=tr)
    return out


def real(data: Path) -> list[tuple[str, tuple[float, ...], float]]:
    bags = sorted((data / "niekum" / "ikea_table_leg_pos_1").glob("part*.bag"))
    ref = rosbag.read(bags)
    off, drift = 2.5, 80e-6
    q_r = se3.random_quat(np.random.default_rng(7))
    p_r = np.array([0.4, -0.9, 1.1])
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for label, name, rate, noise in (
            ("poses.dat folder, same samples", "copy", None, 0.0),
            ("C3D, resampled to 30 Hz", "copy.c3d", 30.0, 0.0),
            ("Motive CSV, resampled to 30 Hz", "copy.csv", 30.0, 0.0),
            ("C3D, 30 Hz + 1 mm noise", "noisy.c3d", 30.0, 1e-3),
        ):
            copy = moved_copy(ref, off, drift, p_r, q_r, rate, noise)
            path = Path(tmp) / name
            io.save(copy, path)
            back = io.load(path)
            want = off + (1 + drift) * (copy.t[0] - back.t[0])
            for smooth in (False, True):
                start = time.perf_counter()
                _, (al,) = merge([ref, back], smooth=smooth)
                rows.append(
                    (
                        label + (", --smooth" if smooth else ""),
                        errors(al, want, drift, p_r, q_r),
                        time.perf_counter() - start,
                    )
                )
    return rows


def plot(res: dict[str, np.ndarray], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(11, 3.2))
    titles = ("clock offset error, ms", "translation error, mm", "rotation error, °")
    limits = (1.0, 1.0, 0.1)
    for ax, col, title, lim in zip(axes, (0, 2, 3), titles, limits, strict=True):
        data = [np.maximum(r[:, col], 1e-9) for r in res.values()]
        ax.boxplot(data, orientation="horizontal")
        ax.set_yticks(range(1, len(res) + 1), list(res) if ax is axes[0] else [""] * len(res))
        ax.set_xscale("log")
        ax.axvline(lim, color="r", ls="--", lw=1)
        ax.set_title(title, fontsize=9)
    fig.suptitle(
        "thirdhand merge on synthetic pairs (red: the 1 ms / 1 mm / 0.1° target)", fontsize=10
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument(
        "--data", type=Path, default=Path(__file__).parents[1] / ".." / "shared" / "data"
    )
    ap.add_argument("--plot", type=Path, default=None)
    args = ap.parse_args()
    if args.data.is_dir():
        print("Real: IKEA bags against a moved copy (offset 2.5 s, drift 80 ppm)\n")
        print(
            "| copy | offset err (ms) | drift err (ppm) | translation err (mm) | "
            "rotation err (°) | residual rms (mm) | time (s) |"
        )
        print("|---|---|---|---|---|---|---|")
        for label, e, secs in real(args.data):
            print(
                f"| {label} | {e[0]:.2e} | {e[1]:.2e} | {e[2]:.2e} | {e[3]:.2e} | {e[4]:.3f} "
                f"| {secs:.1f} |"
            )
    res = synthetic(args.seeds)
    print(f"\nSynthetic, {args.seeds} seeds: median / worst\n")
    print(
        "| condition | offset err (ms) | drift err (ppm) | translation err (mm) | "
        "rotation err (°) | residual rms (mm) |"
    )
    print("|---|---|---|---|---|---|")
    for name, r in res.items():
        cells = " | ".join(f"{np.median(r[:, j]):.2g} / {r[:, j].max():.2g}" for j in range(5))
        print(f"| {name} | {cells} |")
    if args.plot:
        plot(res, args.plot)
        print(f"\nwrote {args.plot}")


if __name__ == "__main__":
    main()
