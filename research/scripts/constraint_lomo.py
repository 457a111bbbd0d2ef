"""Leave-one-mechanism-out accuracy of the joint type on the shared real tracks.

The choices of the detector that real tracks could inform are re-fitted with one
mechanism held out, and the held-out mechanism is scored with them: the largest
hinge radius (:data:`~thirdhand.constraints.select.MAX_HINGE_RADIUS`, a stated
physical prior of 1 m), the bow a straight stroke may have (as a fraction of its
chord, :data:`~thirdhand.constraints.select.MIN_SAGITTA_RATIO`, 3 %) and the
standard errors a bow, a slide or a flatter-than-a-hinge arc must stand out by
(:data:`~thirdhand.constraints.select.MIN_TURN_FLOORS`, 5) and the BIC lead a joint
with more parameters needs (:data:`~thirdhand.constraints.select.EVIDENCE_MARGIN`,
6.32). For each held-out
mechanism the grid point with the most tracks right on the other mechanisms is
taken (ties: the one nearest the shipped values, in grid steps). Prints a Markdown
table: per mechanism, the shipped detector's accuracy (in-sample: its values were
chosen with these tracks in view), the held-out accuracy with the choices fitted
on the other mechanisms, the choices, and the naive line-vs-circle fit (which has
no choices to fit). A mechanism is one physical object (one cabinet door, one
drawer, the stapler): ``scripts/constraint_type_table.py``'s ``real_tracks``.

The model fits do not depend on these choices (only the selection among them
does), so each track's fits are computed once and reused across the grid.

Usage: ``python scripts/constraint_lomo.py [--data DIR]``
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", os.environ.get("OMP_NUM_THREADS", "1"))

import argparse
import itertools
import math
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from thirdhand.constraints import select

sys.path.insert(0, str(Path(__file__).parent))
from constraint_type_table import naive_type, real_tracks

#: Grid of each choice; the shipped value is in every grid.
GRID: dict[str, tuple[float, ...]] = {
    "MAX_HINGE_RADIUS": (0.5, 0.75, 1.0, 1.5, 2.0, 3.0, math.inf),
    "MIN_SAGITTA_RATIO": (0.01, 0.02, 0.03, 0.04, 0.05),
    "MIN_TURN_FLOORS": (3.0, 4.0, 5.0, 6.0, 7.0),
    "EVIDENCE_MARGIN": (0.0, 2.0, 4.0, select.EVIDENCE_MARGIN, 10.0),
}
SHIPPED = {k: float(getattr(select, k)) for k in GRID}


@contextmanager
def cached_fits() -> Iterator[None]:
    """Memoise :func:`~thirdhand.constraints.robust.fit_model` within the block."""
    original = select.fit_model
    cache: dict[tuple[Any, ...], Any] = {}

    def fit_model(name: str, p: np.ndarray, q: np.ndarray | None, **kw: Any) -> Any:
        key = (name, p.tobytes(), None if q is None else q.tobytes())
        if key not in cache:
            cache[key] = original(name, p, q, **kw)
        return cache[key]

    select.fit_model = fit_model  # type: ignore[assignment]
    try:
        yield
    finally:
        select.fit_model = original


@contextmanager
def choices(values: dict[str, float]) -> Iterator[None]:
    """Set the selection constants of :mod:`thirdhand.constraints.select` within the block."""
    old = {k: getattr(select, k) for k in values}
    for k, v in values.items():
        setattr(select, k, v)
    try:
        yield
    finally:
        for k, v in old.items():
            setattr(select, k, v)


def _distance(point: dict[str, float]) -> int:
    """Grid steps from the shipped values."""
    return sum(abs(GRID[k].index(point[k]) - GRID[k].index(SHIPPED[k])) for k in GRID)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    default = Path(os.environ.get("THIRDHAND_DATA", Path(__file__).parents[2] / "shared/data"))
    parser.add_argument("--data", type=Path, default=default)
    args = parser.parse_args()

    tracks = list(real_tracks(args.data))
    mechanisms = list(dict.fromkeys(t[4] for t in tracks))
    points = [dict(zip(GRID, v, strict=True)) for v in itertools.product(*GRID.values())]
    # right[i][j]: track j right under grid point i.
    right = np.zeros((len(points), len(tracks)), dtype=bool)
    with cached_fits():
        for i, point in enumerate(points):
            with choices(point):
                for j, (_, kind, p, q, _) in enumerate(tracks):
                    right[i, j] = select.fit_constraint(p, q).type == kind
    mech = np.array([t[4] for t in tracks])
    naive = np.array([naive_type(t[2]) == t[1] for t in tracks])
    shipped = points.index(SHIPPED)

    print(
        "| held-out mechanism | tracks | shipped (in-sample) | held out, choices fitted "
        "on the others | hinge radius (m) | straight bow (% chord) | standard errors | "
        "evidence margin | naive line-vs-circle |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    total_held = 0
    for m in mechanisms:
        held = mech == m
        score = right[:, ~held].sum(axis=1)
        best = max(range(len(points)), key=lambda i: (score[i], -_distance(points[i])))
        n = int(held.sum())
        got = int(right[best, held].sum())
        total_held += got
        pt = points[best]
        tied = sorted(
            {
                q["MAX_HINGE_RADIUS"]
                for i, q in enumerate(points)
                if score[i] == score[best]
                and all(q[k] == pt[k] for k in GRID if k != "MAX_HINGE_RADIUS")
            }
        )
        radii = f"{pt['MAX_HINGE_RADIUS']:g} (tied: {', '.join(f'{r:g}' for r in tied)})"
        print(
            f"| {m} | {n} | {int(right[shipped, held].sum())}/{n} | **{got}/{n}** | "
            f"{radii} | {100 * pt['MIN_SAGITTA_RATIO']:g} | "
            f"{pt['MIN_TURN_FLOORS']:g} | {pt['EVIDENCE_MARGIN']:.3g} | "
            f"{int(naive[held].sum())}/{n} |"
        )
    n = len(tracks)
    print(
        f"| **all** | {n} | {int(right[shipped].sum())}/{n} | **{total_held}/{n}** | | | | | "
        f"{int(naive.sum())}/{n} |"
    )
    totals = right.sum(axis=1)
    best_all = int(totals.max())
    print(f"\nbest grid point in-sample: {best_all}/{n}; grid of {len(points)} points")
    top = min(
        (i for i in range(len(points)) if totals[i] == best_all),
        key=lambda i: _distance(points[i]),
    )
    wrong = [tracks[j][0] for j in np.flatnonzero(~right[top])]
    print(f"nearest the shipped values among them: {points[top]}, wrong: {wrong}")


if __name__ == "__main__":
    main()
