"""Classify the real articulated-object tracks and print a table with the accuracy.

Tracks (``../shared/data`` or ``$THIRDHAND_DATA``), 56 in all: Sturm et al.'s
``door.txt`` (revolute), ``drawer.txt`` (prismatic), ``cabinet_one``,
``second_set/left_door``, ``second_set/right_door``, ``cabinet_two`` (revolute,
position-only), ``drawer_one``, ``second_set/drawer``, ``second_set/sliding_cabinet``
(prismatic, position-only) (:data:`ARTICULATION_SETS`), and Niekum et al.'s stapler
(revolute): ``relative1`` (object2 in object1), ``relative2`` (its exact inverse,
object1 in object2) and the relative pose computed here from ``object1``/``object2``.
Prints every track (with the runner-up type and its probability, and the naive
line-vs-circle fit's call, :func:`naive_type`), the accuracy per mechanism of both,
and the reliability of the confidence on these tracks.

The fits use the default flags: the noise is estimated from each track (the
``noise`` column: per-axis white noise, position and rotation). The last two
columns repeat the prediction with the ``--noise camera`` override (1 cm floor,
the default position noise of Sturm et al.'s toolkit) and with ``--noise mocap``
(1 mm floor, the default before the noise was estimated).

Usage: ``python research/scripts/constraint_type_table.py [--data DIR]``
"""

from __future__ import annotations

import argparse
import itertools
import os
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from thirdhand import io, se3
from thirdhand.arrays import FloatArray
from thirdhand.constraints import NoiseModel, demo_track, fit_constraint

#: The shared real articulation tracks: folder (or file) under ``articulation/``, the
#: mechanism it records, and the joint type of that mechanism.
ARTICULATION_SETS: tuple[tuple[str, str, str], ...] = (
    ("door.txt", "door", "revolute"),
    ("drawer.txt", "drawer", "prismatic"),
    ("cabinet_one", "cabinet_one", "revolute"),
    ("drawer_one", "drawer_one", "prismatic"),
    ("second_set/drawer", "drawer_two", "prismatic"),
    ("second_set/left_door", "left_door", "revolute"),
    ("second_set/right_door", "right_door", "revolute"),
    ("second_set/sliding_cabinet", "sliding_cabinet", "prismatic"),
    ("cabinet_two", "cabinet_two", "revolute"),
)


def real_tracks(
    data: Path,
) -> Iterator[tuple[str, str, FloatArray, FloatArray | None, str]]:
    """``(name, true type, pos (n, 3), quat (n, 4) or None, mechanism)`` of every real track.

    The mechanism names the physical object a track records (one cabinet door, one
    drawer, the stapler): the unit of the leave-one-mechanism-out figures.
    """
    art = data / "articulation"
    for folder, mechanism, kind in ARTICULATION_SETS:
        paths = [art / folder] if folder.endswith(".txt") else sorted((art / folder).glob("*.log"))
        for path in paths:
            pos, quat, _ = demo_track(io.load(path))
            yield str(path.relative_to(data)), kind, pos, quat, mechanism
    z = np.load(data / "niekum" / "stapler_revolute.npz")
    for key in ("relative1", "relative2"):
        yield f"niekum/stapler {key}", "revolute", z[key][:, :3], z[key][:, 3:], "stapler"
    o1, o2 = z["object1"], z["object2"]
    p, q = se3.relative_pose(o1[:, :3], o1[:, 3:], o2[:, :3], o2[:, 3:])
    yield "niekum/stapler object2 in object1", "revolute", p, q, "stapler"


def naive_type(pos: FloatArray) -> str:
    """Line or circle, whichever leaves the smaller rms residual (``fixed`` under 1 cm)."""
    p = pos[np.all(np.isfinite(pos), axis=1)]
    c = p - p.mean(axis=0)
    if np.ptp(p, axis=0).max() < 0.01:
        return "fixed"
    _, _, vt = np.linalg.svd(c, full_matrices=False)
    line = c - np.outer(c @ vt[0], vt[0])
    rms_line = float(np.sqrt(np.mean(np.sum(line**2, axis=1))))
    u, v = c @ vt[0], c @ vt[1]
    a = np.column_stack([2 * u, 2 * v, np.ones_like(u)])
    sol, *_ = np.linalg.lstsq(a, u**2 + v**2, rcond=None)
    r = np.sqrt(sol[2] + sol[0] ** 2 + sol[1] ** 2)
    radial = np.hypot(u - sol[0], v - sol[1]) - r
    off = c @ vt[2]
    rms_circle = float(np.sqrt(np.mean(radial**2 + off**2)))
    return "revolute" if rms_circle < rms_line else "prismatic"


#: Confidence bins of the reliability table (the sweep's).
EDGES = (0.0, 0.6, 0.8, 0.9, 0.99, 1.01)


def reliability_rows(
    conf: list[float], right: list[bool], edges: tuple[float, ...] = EDGES
) -> list[tuple[str, float, float, int]]:
    """``(bin, mean confidence, accuracy, tracks)`` per confidence bin (empty bins left out)."""
    rows = []
    c = np.asarray(conf)
    r = np.asarray(right, dtype=float)
    for lo, hi in itertools.pairwise(edges):
        m = (c >= lo) & (c < hi)
        if m.any():
            label = f"{lo:g}-{min(hi, 1.0):g}" if hi <= 1.0 else f">= {lo:g}"
            rows.append((label, float(c[m].mean()), float(r[m].mean()), int(m.sum())))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    default = Path(os.environ.get("THIRDHAND_DATA", Path(__file__).parents[2] / "shared/data"))
    parser.add_argument("--data", type=Path, default=default)
    args = parser.parse_args()

    header = (
        f"{'file':50s} {'true':10s} {'predicted':11s} {'conf':>6s} {'runner-up':>17s} "
        f"{'noise':>14s} {'range':>24s}  {'naive':10s} {'camera':10s} {'mocap':10s}"
    )
    print(header)
    print("-" * len(header))
    per: dict[str, list[int]] = {}
    conf: list[float] = []
    right_all: list[bool] = []
    right_camera = right_mocap = 0
    for name, kind, pos, quat, mech in real_tracks(args.data):
        c = fit_constraint(pos, quat)
        c_camera = fit_constraint(pos, quat, noise=NoiseModel.camera())
        c_mocap = fit_constraint(pos, quat, noise=NoiseModel())
        naive = naive_type(pos)
        free = [i for i in range(6) if c.ranges[i, 0] != c.ranges[i, 1]]
        rng = "locked"
        if free:
            i = free[0]
            lo, hi = c.ranges[i] if i < 3 else np.degrees(c.ranges[i])
            unit = "m" if i < 3 else "deg"
            rng = f"{('tx', 'ty', 'tz', 'rx', 'ry', 'rz')[i]} [{lo:+.3f}, {hi:+.3f}] {unit}"
            if unit == "deg":
                rng = f"rx [{lo:+.1f}, {hi:+.1f}] deg"
        rot = "" if quat is None else f" {np.degrees(c.noise_rot):.1f}°"
        noise = f"{1000 * c.noise_pos:.1f} mm{rot}"
        ru = "-" if c.runner_up is None else f"{c.runner_up.type} {c.runner_up.confidence:.3f}"
        mark = "" if c.type == kind else "  <-- wrong"
        print(
            f"{name:50s} {kind:10s} {c.type:11s} {c.confidence:6.3f} {ru:>17s} {noise:>14s} "
            f"{rng:>24s}  {naive:10s} {c_camera.type:10s} {c_mocap.type:10s}{mark}"
        )
        row = per.setdefault(mech, [0, 0, 0])
        row[0] += c.type == kind
        row[1] += naive == kind
        row[2] += 1
        conf.append(c.confidence)
        right_all.append(c.type == kind)
        right_camera += c_camera.type == kind
        right_mocap += c_mocap.type == kind
    total = len(conf)
    print()
    print("| mechanism | tracks | thirdhand (default flags) | naive line-vs-circle |")
    print("|---|---|---|---|")
    for mech, (ours, naive_right, n) in per.items():
        print(f"| {mech} | {n} | {ours}/{n} | {naive_right}/{n} |")
    ours_all = sum(v[0] for v in per.values())
    naive_all = sum(v[1] for v in per.values())
    print(f"| **all** | {total} | **{ours_all}/{total}** | {naive_all}/{total} |")
    print()
    print("Reliability of the confidence on the real tracks (default flags):")
    print()
    print("| confidence | mean confidence | accuracy | tracks |")
    print("|---|---|---|---|")
    for label, mc, acc, n in reliability_rows(conf, right_all):
        print(f"| {label} | {mc:.3f} | {acc:.3f} | {n} |")
    ece = sum(n * abs(mc - acc) for _, mc, acc, n in reliability_rows(conf, right_all)) / max(
        total, 1
    )
    print(f"ECE {ece:.3f}, mean confidence {np.mean(conf):.3f}, accuracy {np.mean(right_all):.3f}")
    print()
    print(f"accuracy (default, noise estimated):  {ours_all}/{total} = {ours_all / total:.1%}")
    print(
        f"accuracy (--noise camera, 1 cm floor): {right_camera}/{total} "
        f"= {right_camera / total:.1%}"
    )
    print(
        f"accuracy (--noise mocap, 1 mm floor):  {right_mocap}/{total} = {right_mocap / total:.1%}"
    )


if __name__ == "__main__":
    main()
