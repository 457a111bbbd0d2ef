"""What ``articulation/drawer_one/004`` holds: its end-stop slide as a regime, and more.

A close call: revolute until a turn's bow had to be resolved.

The gripper slides sideways along the handle at the end stop (frames 83-90). The
script models that as a real artefact: the track is split at a change point
``k``; frames ``[0, k)`` are one joint model (prismatic or revolute, the
estimated noise, outliers allowed) and frames ``[k, n)`` a separate regime, a
still pose of its own (the grasp shifted). The change point is a parameter of
the BIC. It prints, for each joint model, the best change point and the BIC of
the two-regime fit, then the fits of the frames before the slide alone, the
sideways coordinate's flat stretches (the grasp creeping along the handle) and the
whole track's call for position ceilings (the largest error the fits may put
down to the tracker) from 3 mm to 2.5 cm.

Usage: ``python research/scripts/drawer_one_004.py [--data DIR]``
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", os.environ.get("OMP_NUM_THREADS", "1"))

import argparse
import dataclasses
import math
from pathlib import Path

import numpy as np

from thirdhand import io
from thirdhand.constraints import demo_track, fit_constraint
from thirdhand.constraints.noise import estimate_noise
from thirdhand.constraints.robust import fit_model, prepare_track


def two_regimes(pos: np.ndarray, name: str, lo: int) -> tuple[int, float]:
    """Best change point ``k >= lo`` and the BIC of ``name`` on ``[0, k)`` plus a still tail."""
    nm = estimate_noise(pos).noise_model()
    n = pos.shape[0]
    best = (0, math.inf)
    for k in range(lo, n - 4):
        head = fit_model(name, pos[:k], None, noise=nm)
        tail = fit_model("fixed", pos[k:], None, noise=nm)
        if head is None or tail is None:
            continue
        # Both regimes' likelihoods, their parameters and the change point, n samples.
        ll = head.log_likelihood + tail.log_likelihood
        bic = -2.0 * ll + (head.n_params + tail.n_params + 1) * math.log(n)
        if bic < best[1]:
            best = (k, bic)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    default = Path(os.environ.get("THIRDHAND_DATA", Path(__file__).parents[2] / "shared/data"))
    parser.add_argument("--data", type=Path, default=default)
    args = parser.parse_args()
    p, _, _ = demo_track(io.load(args.data / "articulation/drawer_one/004.log"))
    pos, _ = prepare_track(p, None)
    n = pos.shape[0]
    c = fit_constraint(pos)
    print(f"whole track ({n} frames): {c.type} at {c.confidence:.2f}; BIC", end=" ")
    print(", ".join(f"{k} {v:.1f}" for k, v in c.scores.items()))
    for name in ("prismatic", "revolute"):
        k, bic = two_regimes(pos, name, n // 2)
        print(f"two regimes, {name:9s}: change point at frame {k}, BIC {bic:.1f}")
    for end in (84, 60):
        c = fit_constraint(pos[:end])
        note = f" ({c.notes[0]})" if c.notes else ""
        print(f"frames 0-{end - 1}: {c.type} at {c.confidence:.2f}{note}; BIC", end=" ")
        print(", ".join(f"{k} {v:.1f}" for k, v in c.scores.items()))
        for name in ("prismatic", "revolute"):
            f = fit_model(name, pos[:end], None, noise=estimate_noise(pos[:end]).noise_model())
            assert f is not None
            rms = math.sqrt(float(np.mean(f.proj.d2_pos[f.inlier])) / 3.0)
            print(f"    {name:9s} rms {1e3 * rms:.2f} mm, outliers {f.outlier_fraction:.0%}")
    # The sideways coordinate: flat stretches and steps (the grasp creeping along the handle).
    y = pos[:, 1]
    for a, b in ((0, 40), (47, 58), (58, 64), (64, 76), (76, 82), (90, n)):
        print(
            f"frames {a:3d}-{b - 1:3d}: x {pos[a, 0]:+.3f}..{pos[b - 1, 0]:+.3f} m, "
            f"y {1e3 * y[a:b].mean():+.1f} mm ± {1e3 * y[a:b].std():.1f}"
        )
    nm = estimate_noise(pos).noise_model()
    for ceiling in (0.003, 0.004, 0.005, 0.0075, 0.009, 0.01, 0.015, 0.025):
        capped = dataclasses.replace(nm, pos_ceiling=max(ceiling, nm.pos_floor))
        c = fit_constraint(pos, noise=capped)
        fit = fit_model(c.type, pos, None, noise=capped)
        assert fit is not None
        out = np.flatnonzero(~fit.inlier)
        where = f"frames {out.min()}-{out.max()}" if out.size else "none"
        print(
            f"ceiling {1e3 * ceiling:4.1f} mm: {c.type:9s} at {c.confidence:.2f} "
            f"({out.size} outliers: {where})"
        )


if __name__ == "__main__":
    main()
