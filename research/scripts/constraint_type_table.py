"""Classify the real articulated-object tracks and print a table with the accuracy.

Tracks (``../shared/data`` or ``$THIRDHAND_DATA``): Sturm et al.'s ``door.txt``
(revolute), ``drawer.txt`` (prismatic), ``cabinet_one/*.log`` (revolute,
position-only), ``drawer_one/*.log`` (prismatic, position-only), and Niekum et
al.'s stapler (revolute): ``relative1`` (object2 in object1), ``relative2`` (its
exact inverse, object1 in object2) and the relative pose computed here from
``object1``/``object2``.

The fits use the default flags: the noise is estimated from each track (the
``noise`` column: per-axis white noise, position and rotation). The last two
columns repeat the prediction with the ``--noise camera`` override (1 cm floor,
the default position noise of Sturm et al.'s toolkit) and with ``--noise mocap``
(1 mm floor, the default before the noise was estimated).

Usage: ``python research/scripts/constraint_type_table.py [--data DIR]``
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from thirdhand import io, se3
from thirdhand.constraints import NoiseModel, demo_track, fit_constraint

FloatArray = NDArray[np.float64]


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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    default = Path(os.environ.get("THIRDHAND_DATA", Path(__file__).parents[2] / "shared/data"))
    parser.add_argument("--data", type=Path, default=default)
    args = parser.parse_args()

    header = (
        f"{'file':38s} {'true':10s} {'predicted':11s} {'conf':>6s} {'noise':>14s} "
        f"{'axis':>24s} {'range':>22s}  {'camera':10s} {'mocap':10s}"
    )
    print(header)
    print("-" * len(header))
    right = right_camera = right_mocap = total = 0
    for name, kind, pos, quat, _ in real_tracks(args.data):
        c = fit_constraint(pos, quat)
        c_camera = fit_constraint(pos, quat, noise=NoiseModel.camera())
        c_mocap = fit_constraint(pos, quat, noise=NoiseModel())
        axis = "-" if c.axis is None else " ".join(f"{v:+.3f}" for v in c.axis)
        free = [i for i in range(6) if c.ranges[i, 0] != c.ranges[i, 1]]
        rng = "locked"
        if free:
            i = free[0]
            unit = "m" if i < 3 else "deg"
            lo, hi = c.ranges[i] if i < 3 else np.degrees(c.ranges[i])
            rng = f"{('tx', 'ty', 'tz', 'rx', 'ry', 'rz')[i]} [{lo:+.3f}, {hi:+.3f}] {unit}"
            if unit == "deg":
                rng = f"rx [{lo:+.1f}, {hi:+.1f}] deg"
        rot = "" if quat is None else f" {np.degrees(c.noise_rot):.1f}°"
        noise = f"{1000 * c.noise_pos:.1f} mm{rot}"
        mark = "" if c.type == kind else "  <-- wrong"
        print(
            f"{name:38s} {kind:10s} {c.type:11s} {c.confidence:6.3f} {noise:>14s} {axis:>24s} "
            f"{rng:>22s}  {c_camera.type:10s} {c_mocap.type:10s}{mark}"
        )
        total += 1
        right += c.type == kind
        right_camera += c_camera.type == kind
        right_mocap += c_mocap.type == kind
    print("-" * len(header))
    print(f"accuracy (default, noise estimated):  {right}/{total} = {right / total:.1%}")
    print(
        f"accuracy (--noise camera, 1 cm floor): {right_camera}/{total} "
        f"= {right_camera / total:.1%}"
    )
    print(
        f"accuracy (--noise mocap, 1 mm floor):  {right_mocap}/{total} = {right_mocap / total:.1%}"
    )


if __name__ == "__main__":
    main()
