"""``python -m research``: the tables of the docs, from the repository (not the package).

Run from the repository root::

    python -m research experiment constraints|plan|corrections [--jobs J] [--scheduler ADDR]
    python -m research irl datasize|noise|transfer|dynamics|chair|large [--runs N] [--jobs J]
    python -m research primitives evaluate FILE.mat [--model hsmm --ends ...]

Each prints its table beside the report's (or the paper's) numbers. ``--scheduler``
runs the seeded units as Dask tasks (``tcp://HOST:PORT`` or ``local``; docs/how-to/cluster.md).
A bad option prints one ``research: error:`` line and exits 1.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.table import Table

from thirdhand import options
from thirdhand.config import JobsOption, SchedulerOption, check_batch
from thirdhand.errors import ThirdhandError
from thirdhand.fileops import check_output

#: ``--noise`` of the plan and corrections tables.
NoiseOption = Annotated[
    float, typer.Option(help="Sensor noise as a multiple of the default (0: noise-free).")
]

out = Console(highlight=False, soft_wrap=True)

app = typer.Typer(
    help="The docs' accuracy tables (research code; imports thirdhand like any user code).",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
experiment_app = typer.Typer(
    help="Accuracy experiments on synthetic scenes, beside the report's numbers.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
app.add_typer(experiment_app, name="experiment")
primitives_app = typer.Typer(
    help="Primitive-library parsers against human phase labels.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
app.add_typer(primitives_app, name="primitives")


@primitives_app.callback()
def _primitives() -> None:
    """Primitive-library parsers against human phase labels."""


def _mount_primitives() -> None:
    from research.primitives_evaluate import evaluate

    primitives_app.command("evaluate")(evaluate)


_mount_primitives()


def _check_scene(scene: str) -> None:
    from thirdhand.synth import SCENES

    if scene not in SCENES:
        raise ThirdhandError(
            f"--scene: unknown scene {scene!r}; expected one of {', '.join(SCENES)}"
        )


def _table(title: str, rows: list[Any], ours: str = "thirdhand") -> None:
    t = Table(title=title)
    t.add_column("case")
    t.add_column(ours)
    t.add_column("report (its own data)")
    for r in rows:
        t.add_row(r.label, r.ours, r.report)
    out.print(t)


@experiment_app.command("constraints")
def experiment_constraints(
    seeds: Annotated[int, typer.Option(help="Seeds per scene and noise level.")] = 5,
    jobs: JobsOption = 1,
    scheduler: SchedulerOption = None,
) -> None:
    """Constraint pose error on the synthetic chair and bench across noise levels."""
    from research.plan_accuracy import constraint_error_table

    options.integer("--seeds", seeds, low=1, high=100_000)
    check_batch(jobs, scheduler)
    rows = constraint_error_table(seeds=range(seeds), jobs=jobs, scheduler=scheduler)
    _table("Constraint pose error", rows)


@experiment_app.command("plan")
def experiment_plan(
    runs: Annotated[int, typer.Option(help="Seeded runs.")] = 96,
    scene: Annotated[str, typer.Option(help="Synthetic scene.")] = "chair",
    noise: NoiseOption = 1.0,
    jobs: JobsOption = 1,
    scheduler: SchedulerOption = None,
) -> None:
    """Plan success with 1–4 demonstrations."""
    from research.plan_accuracy import plan_success_table

    options.integer("--runs", runs, low=1, high=100_000)
    options.finite("--noise", noise, low=0.0, high=1000.0)
    _check_scene(scene)
    check_batch(jobs, scheduler)
    rows = plan_success_table(
        scene=scene,
        runs=runs,
        scale=noise if noise > 0 else None,
        jobs=jobs,
        scheduler=scheduler,
    )
    _table(f"Plan success ({scene}, noise x{noise:g})", rows)


@experiment_app.command("corrections")
def experiment_corrections(
    seeds: Annotated[int, typer.Option(help="Seeds per scene.")] = 4,
    noise: NoiseOption = 1.0,
    jobs: JobsOption = 1,
    scheduler: SchedulerOption = None,
) -> None:
    """Constraint parameters a user would still correct (chair of 30, bench of 24)."""
    from research.plan_accuracy import corrections_table

    options.integer("--seeds", seeds, low=1, high=100_000)
    options.finite("--noise", noise, low=0.0, high=1000.0)
    check_batch(jobs, scheduler)
    rows = corrections_table(
        seeds=range(seeds), scale=noise if noise > 0 else None, jobs=jobs, scheduler=scheduler
    )
    _table(f"Parameters to correct (noise x{noise:g})", rows)


@app.command()
def irl(
    name: Annotated[
        str, typer.Argument(help="datasize, noise, transfer, dynamics, chair or large.")
    ],
    runs: Annotated[int, typer.Option(help="Repetitions per row.")] = 100,
    jobs: JobsOption = 1,
    scheduler: SchedulerOption = None,
    json_out: Annotated[
        Path | None, typer.Option("--json", help="Output JSON (default irl_<name>.json).")
    ] = None,
    checkpoint: Annotated[
        Path | None,
        typer.Option(help="JSON-lines file: each trial appended when done; a rerun resumes."),
    ] = None,
    tabulate: Annotated[
        bool, typer.Option(help="Only tabulate the trials in --checkpoint, run nothing.")
    ] = False,
    force: Annotated[
        bool, typer.Option(help="Replace an existing JSON output (kept as a numbered .bak).")
    ] = False,
) -> None:
    """One of the relational IRL tables (Munzer et al., IJCAI 2015), ours beside the paper's."""
    from research.irl_tables import EXPERIMENTS, run_experiment
    from research.relational_irl import format_table
    from thirdhand.relational.logic import RelationalError

    if name not in EXPERIMENTS:
        raise RelationalError(
            f"unknown experiment {name!r}, expected one of {', '.join(EXPERIMENTS)}"
        )
    path = json_out if json_out is not None else Path(f"irl_{name}.json")
    check_output(path, force=force, inputs=[checkpoint] if checkpoint else [])
    options.integer("--runs", runs, low=2, high=100000)
    check_batch(jobs, scheduler)
    if tabulate and checkpoint is None:
        raise RelationalError("irl: --tabulate needs --checkpoint")
    start = time.perf_counter()
    result = run_experiment(
        name,
        runs=runs,
        jobs=jobs,
        out=path,
        checkpoint=checkpoint,
        tabulate_only=tabulate,
        scheduler=scheduler,
    )
    out.print(format_table(result))
    out.print(f"{time.perf_counter() - start:.1f} s; written {path}")


def main(argv: list[str] | None = None) -> int:
    """Run the research CLI; a user's bad input is one ``research: error:`` line, exit 1."""
    command = typer.main.get_command(app)
    try:
        code = command.main(args=argv, prog_name="python -m research", standalone_mode=False)
    except ThirdhandError as exc:
        sys.stderr.write(f"research: error: {' '.join(str(exc).split())}\n")
        return 1
    except typer.Exit as exc:
        return int(exc.exit_code)
    except Exception as exc:  # click's usage errors (typer's own copy of click)
        status = getattr(exc, "exit_code", None)
        if hasattr(exc, "format_message") and isinstance(status, int):
            sys.stderr.write(f"research: error: {' '.join(exc.format_message().split())}\n")
            return status
        raise
    return code if isinstance(code, int) else 0
