"""How much the position-only cabinet tracks bow: the doors called prismatic against the slides.

For each track of ``articulation/cabinet_two`` (a door, short openings) and
``articulation/second_set/sliding_cabinet`` (a door that slides), the path is
expressed in its principal axes; a parabola fitted to the lateral coordinate along
the first axis gives the bow (sagitta over the chord) and the radius of the
circle it approximates. A door whose path bows less than a slide's cannot be told
from the slide by its shape, whatever the detector.

Usage: ``python research/scripts/constraint_bow_overlap.py [--data DIR]``
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def bow(path: Path) -> tuple[int, float, float, float]:
    """(samples, chord m, bow as a fraction of the chord, radius m) of one ``x y z`` track."""
    p = np.loadtxt(path)
    c = p - p.mean(axis=0)
    _, _, vt = np.linalg.svd(c, full_matrices=False)
    q = c @ vt.T
    a = np.polyfit(q[:, 0], q[:, 1], 2)[0]
    chord = float(np.ptp(q[:, 0]))
    radius = 1.0 / (2.0 * abs(a))
    return len(p), chord, chord / (8.0 * radius), radius


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=Path("../shared/data"))
    args = ap.parse_args()
    root = args.data / "articulation"
    print("| track | label | samples | chord (m) | bow / chord | radius (m) |")
    print("|---|---|---|---|---|---|")
    for folder, label in (("cabinet_two", "revolute"), ("second_set/sliding_cabinet", "prismatic")):
        for f in sorted((root / folder).glob("*.log")):
            n, chord, ratio, radius = bow(f)
            print(
                f"| {folder}/{f.stem} | {label} | {n} | {chord:.3f} | {100 * ratio:.1f} % "
                f"| {radius:.2f} |"
            )


if __name__ == "__main__":
    main()
