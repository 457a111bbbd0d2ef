"""Many seeded episodes into one LeRobot dataset: the kept ones in seed order, never half-written.

The episodes are computed by :func:`~thirdhand.generate.episodes.run_episode`
here, in local worker processes or as Dask tasks
(:func:`~thirdhand.batch.parallel_map`); this process writes the kept ones as
they arrive, in seed order, through :class:`~thirdhand.lerobot.writer.DatasetWriter`.
"""

from __future__ import annotations

import os
import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from thirdhand.errors import OptionError, ThirdhandError
from thirdhand.generate.episodes import (
    EpisodeJob,
    EpisodeOutcome,
    check_settings,
    episode_of,
    run_episode,
    task_text,
)
from thirdhand.lerobot.writer import DatasetSummary


@dataclass(frozen=True)
class GenerateSummary:
    """What :func:`generate_dataset` did.

    Attributes
    ----------
    dataset : DatasetSummary
    kept : tuple of int
        Seeds of the written episodes, in episode order.
    reasons : dict of str to int
        Every reason an episode was not kept, and in how many episodes.
    dropped : int
        Episodes not kept.
    timings : dict of str to float
        Wall-clock seconds summed over the episodes: ``planning``, ``physics``,
        ``rendering`` (in the workers) and ``encoding`` (writing, in this process).
    """

    dataset: DatasetSummary | None
    kept: tuple[int, ...]
    reasons: dict[str, int]
    dropped: int
    timings: dict[str, float]


def generate_dataset(
    jobs_: Sequence[EpisodeJob],
    root: str | os.PathLike[str],
    *,
    force: bool = False,
    jobs: int = 1,
    scheduler: str | None = None,
    on_outcome: Callable[[EpisodeOutcome], None] | None = None,
) -> GenerateSummary:
    """Run every job (in seed order), write the kept episodes as a LeRobot dataset at ``root``.

    Parameters
    ----------
    jobs_ : sequence of EpisodeJob
        One per seed, in the order the episodes are written.
    root : path-like
        The dataset folder to create.
    force : bool
        Replace an existing folder (kept as a numbered ``.bak``).
    jobs, scheduler
        Where the episodes are computed (:func:`~thirdhand.batch.parallel_map`).
    on_outcome : callable, optional
        Called with every outcome as it arrives (progress).

    Raises
    ------
    ThirdhandError
        No episode kept (with the reasons counted); nothing is written.
    OutputError
        ``root`` exists and ``force`` is not given.

    Notes
    -----
    Ctrl-C or SIGTERM leaves a dataset of the episodes written before it (or
    none), then goes on (:class:`~thirdhand.lerobot.writer.DatasetWriter`).
    """
    from thirdhand.batch import parallel_map
    from thirdhand.lerobot.writer import DatasetWriter

    if not jobs_:
        raise OptionError("no episode to generate")
    first = jobs_[0]
    check_settings(first.settings, first.simulate)
    fps = first.settings.fps
    text = task_text(first.task, first.name)
    reasons: Counter[str] = Counter()
    kept: list[int] = []
    totals = {"planning": 0.0, "physics": 0.0, "rendering": 0.0, "encoding": 0.0}
    writer = DatasetWriter(root, fps=fps, robot_type=first.robot or "panda", force=force)
    with writer:
        for out in parallel_map(run_episode, jobs_, jobs=jobs, scheduler=scheduler, spawn=True):
            for k, v in out.timings.items():
                totals[k] += v
            if out.recording is not None:
                t0 = time.perf_counter()
                writer.add_episode(episode_of(out.recording, fps=fps, task=text))
                totals["encoding"] += time.perf_counter() - t0
                kept.append(out.seed)
            else:
                reasons.update(out.reasons)
            if on_outcome is not None:
                on_outcome(out)
        if not kept:
            what = ", ".join(f"{r} ×{n}" for r, n in reasons.most_common())
            raise ThirdhandError(
                f"{Path(root)}: none of {len(jobs_)} episodes completed every step "
                f"({what}); nothing was written"
            )
    return GenerateSummary(
        dataset=writer.summary, kept=tuple(kept), reasons=dict(reasons),
        dropped=len(jobs_) - len(kept), timings=totals,
    )  # fmt: skip


def jobs_for(template: EpisodeJob, seed: int, n: int) -> list[EpisodeJob]:
    """``n`` copies of ``template`` with seeds ``seed``, ``seed + 1``, …"""
    return [replace(template, seed=seed + i) for i in range(n)]
