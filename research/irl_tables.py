"""The relational IRL tables by name: the paper's five and the large-world one.

``run_experiment(name)`` runs one of :data:`EXPERIMENTS` (each a function of
``runs`` and ``jobs`` returning the table's JSON-ready dict). Kept apart from
:mod:`research.relational_irl` and :mod:`research.relational_large` so that
neither imports the other's caller (no import cycle).
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from typing import Any

from research.relational_irl import chair, datasize, dynamics, noise, transfer
from research.relational_large import large_experiment
from thirdhand.relational.logic import RelationalError


def large(runs: int, jobs: int, *, scheduler: str | None = None, **grid: Any) -> dict[str, Any]:
    """Beyond the paper: stack/unstack learned on 4+5 blocks planned on 10, 15, 20 blocks,
    build learned on the 4-legged chair planned with 6, 7, 8 legs (see
    :mod:`research.relational_large`).

    Checkpoints are not supported (``--checkpoint``/``--tabulate`` raise);
    ``scheduler`` runs the trials on a Dask cluster.
    """
    if grid.get("checkpoint") is not None or grid.get("tabulate_only"):
        raise RelationalError("irl experiment large: --checkpoint and --tabulate are not supported")

    return large_experiment(runs, jobs, scheduler=scheduler)


EXPERIMENTS: dict[str, Callable[..., dict[str, Any]]] = {
    "datasize": datasize,
    "noise": noise,
    "transfer": transfer,
    "dynamics": dynamics,
    "chair": chair,
    "large": large,
}


def run_experiment(
    name: str,
    *,
    runs: int = 100,
    jobs: int = 1,
    out: str | os.PathLike[str] | None = None,
    checkpoint: str | os.PathLike[str] | None = None,
    tabulate_only: bool = False,
    scheduler: str | None = None,
) -> dict[str, Any]:
    """Run one experiment, write its JSON to ``out`` when given, return the result.

    ``checkpoint``: a JSON-lines file where each trial's result is appended as it
    is done, and from which a stopped run resumes; ``tabulate_only``: only
    tabulate the trials the checkpoint holds.
    """
    if name not in EXPERIMENTS:
        raise RelationalError(
            f"unknown experiment {name!r}, expected one of {', '.join(EXPERIMENTS)}"
        )
    result = EXPERIMENTS[name](
        runs, jobs, checkpoint=checkpoint, tabulate_only=tabulate_only, scheduler=scheduler
    )
    if out is not None:
        from thirdhand.fileops import write_text

        write_text(out, json.dumps(result, indent=1))
    return result
