"""Accuracy experiments on synthetic scenes, printed beside the report's numbers.

- :func:`constraint_error_table`: constraint pose error (cm, degrees) on the chair
  and the bench across sensor-noise levels.
- :func:`plan_success_table`: plan success for 1–4 demonstrations over seeded runs.
- :func:`corrections_table`: constraint parameters a user would still correct.

A *parameter* and when it is wrong: see :mod:`thirdhand.metrics`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TypeVar

import numpy as np

from thirdhand.constraints.detect import ConstraintInstance, detect_constraints
from thirdhand.demonstration import Demonstration
from thirdhand.metrics import corrections, pose_errors

#: The report's figures (its own data; references, not targets).
REPORT_POSE_ERROR = {"chair": (0.8, 0.1, 4.7, 0.6), "bench": (2.0, 0.6, 14.0, 13.0)}
REPORT_PLAN_SUCCESS = {1: 0.52, 2: 0.75, 3: 0.75, 4: 0.88}
REPORT_CORRECTIONS = {"chair": (15.25, 30), "bench": (14.25, 28)}

R = TypeVar("R")


@dataclass
class Row:
    """One printed row: a label, our figures, the report's."""

    label: str
    ours: str
    report: str


def _make(scene: str, seed: int, scale: float | None) -> Demonstration:
    from thirdhand.synth import SensorModel, make_scene

    if scale is None:
        return make_scene(scene, seed=seed, sensor=None)
    base = SensorModel()
    sensor = SensorModel(pos_noise=base.pos_noise * scale, rot_noise=base.rot_noise * scale)
    return make_scene(scene, seed=seed, sensor=sensor)


@dataclass(frozen=True)
class SceneRun:
    """One independent unit: a synthetic scene, a seed, a noise scale (``None``: noise-free).

    ``max_demos`` > 1 makes a plan run: demonstrations of seeds
    ``seed·max_demos … seed·max_demos + max_demos − 1``.
    """

    scene: str
    seed: int
    scale: float | None
    max_demos: int = 1


def pose_error_unit(run: SceneRun) -> tuple[list[tuple[float, float]], int]:
    """Pose errors (cm, degrees) of the detected constraints of one scene, and the true count."""
    demo = _make(run.scene, run.seed, run.scale)
    det = detect_constraints(demo)
    errs = pose_errors(det.instances, demo.labels.constraints)
    n_true = len([e for e in demo.labels.constraints if not e.removed])
    return [(100 * e[0], e[1]) for e in errs], n_true


def plan_unit(run: SceneRun) -> list[int]:
    """Plan success (0/1) with 1…``max_demos`` demonstrations of one run."""
    from thirdhand.plan.assembly import plan_from_demos, plan_success
    from thirdhand.plan.symbols import assign_symbols

    dets = []
    truth = []
    for k in range(run.max_demos):
        demo = _make(run.scene, run.seed * run.max_demos + k, run.scale)
        dets.append(detect_constraints(demo, demo_name=f"demo{k + 1}").instances)
        truth = list(demo.labels.constraints)
    wins = []
    for n in range(1, run.max_demos + 1):
        use = [[_copy(i) for i in d] for d in dets[:n]]
        symbols = assign_symbols([i for d in use for i in d if i.end is None])
        plan = plan_from_demos(use, symbols)
        wins.append(int(plan_success(plan, symbols, truth)))
    return wins


def corrections_unit(run: SceneRun) -> tuple[int, int]:
    """Parameters to correct and parameters in all, for one scene."""
    demo = _make(run.scene, run.seed, run.scale)
    det = detect_constraints(demo)
    return corrections(det.instances, demo.labels.constraints)


def _units(
    fn: Callable[[SceneRun], R],
    runs: list[SceneRun],
    jobs: int,
    scheduler: str | None,
    progress: Callable[[str], None] | None,
) -> list[R]:
    """``fn`` over ``runs`` in order, wherever they run (:func:`thirdhand.batch.parallel_map`)."""
    from thirdhand.batch import parallel_map

    out = []
    for k, r in enumerate(parallel_map(fn, runs, jobs=jobs, scheduler=scheduler)):
        out.append(r)
        if progress:
            progress(f"{k + 1}/{len(runs)}")
    return out


def constraint_error_table(
    *,
    scenes: Sequence[str] = ("chair", "bench"),
    noise_scales: Sequence[float | None] = (None, 0.5, 1.0, 2.0, 4.0),
    seeds: Sequence[int] = range(5),
    jobs: int = 1,
    scheduler: str | None = None,
    progress: Callable[[str], None] | None = None,
) -> list[Row]:
    """Constraint pose error by scene and noise level (``None`` = noise-free).

    Noise scale 1 is :class:`thirdhand.synth.SensorModel`'s default (1 mm, 0.5° per
    sample, occlusion gaps). Each (scene, noise, seed) is a unit of its own, run in
    ``jobs`` processes or on ``scheduler`` (same table either way).
    """
    cells = [(scene, scale) for scene in scenes for scale in noise_scales]
    runs = [SceneRun(scene, seed, scale) for scene, scale in cells for seed in seeds]
    results = iter(_units(pose_error_unit, runs, jobs, scheduler, progress))
    rows = []
    for scene, scale in cells:
        pe: list[float] = []
        re: list[float] = []
        missing, total = 0, 0
        for _ in seeds:
            errs, n_true = next(results)
            total += n_true
            missing += n_true - len(errs)
            pe += [e[0] for e in errs]
            re += [e[1] for e in errs]
        ref = REPORT_POSE_ERROR.get(scene)
        label = f"{scene}, noise {'none' if scale is None else f'x{scale:g}'}"
        ours = (
            f"{np.mean(pe):.3f} ± {np.std(pe):.3f} cm, {np.mean(re):.2f} ± {np.std(re):.2f}°"
            f"  ({missing}/{total} missed)"
            if pe
            else f"no constraint found ({missing}/{total} missed)"
        )
        report = f"{ref[0]} ± {ref[1]} cm, {ref[2]} ± {ref[3]}°" if ref else "-"
        rows.append(Row(label, ours, report))
    return rows


def plan_success_table(
    *,
    scene: str = "chair",
    runs: int = 96,
    max_demos: int = 4,
    scale: float | None = 1.0,
    jobs: int = 1,
    scheduler: str | None = None,
    progress: Callable[[str], None] | None = None,
) -> list[Row]:
    """Plan success rate with 1…``max_demos`` demonstrations over ``runs`` seeded runs.

    Run ``r`` uses the demonstrations of seeds ``r·max_demos … r·max_demos + n − 1``
    (so ``n + 1`` demonstrations extend the ``n`` of the same run). A run succeeds
    when the plan learned from its demonstrations, executed symbolically, attaches
    every part to the base in a different true slot (:func:`~thirdhand.plan.plan_success`).
    Each run is a unit of its own, run in ``jobs`` processes or on ``scheduler``.
    """
    units = [SceneRun(scene, r, scale, max_demos) for r in range(runs)]
    per_run = _units(plan_unit, units, jobs, scheduler, progress)
    wins = {n: sum(w[n - 1] for w in per_run) for n in range(1, max_demos + 1)}
    return [
        Row(
            f"{scene}, {n} demonstration{'s' if n > 1 else ''}",
            f"{wins[n] / runs:.3f} ({wins[n]}/{runs})",
            f"{REPORT_PLAN_SUCCESS[n]:.2f}" if n in REPORT_PLAN_SUCCESS else "-",
        )
        for n in range(1, max_demos + 1)
    ]


def _copy(i: ConstraintInstance) -> ConstraintInstance:
    import dataclasses

    return dataclasses.replace(i, symbol=None)


def corrections_table(
    *,
    scenes: Sequence[str] = ("chair", "bench"),
    seeds: Sequence[int] = range(4),
    scale: float | None = 1.0,
    jobs: int = 1,
    scheduler: str | None = None,
    progress: Callable[[str], None] | None = None,
) -> list[Row]:
    """Constraint parameters a user would still correct, per scene, mean over seeds."""
    units = [SceneRun(scene, seed, scale) for scene in scenes for seed in seeds]
    results = iter(_units(corrections_unit, units, jobs, scheduler, progress))
    rows = []
    for scene in scenes:
        counts, total = [], 0
        for _ in seeds:
            wrong, total = next(results)
            counts.append(wrong)
        ref = REPORT_CORRECTIONS.get(scene)
        rows.append(
            Row(
                scene,
                f"{np.mean(counts):.2f} of {total} (max {max(counts)})",
                f"{ref[0]} of {ref[1]}" if ref else "-",
            )
        )
    return rows
