"""``thirdhand irl``: relational inverse reinforcement learning (RCSI, BLMRIL).

``thirdhand irl experiment {datasize,noise,transfer,dynamics,chair} [--runs N] [--jobs J]
[--scheduler tcp://HOST:PORT] [--checkpoint FILE]`` reproduces a table of Munzer et al.
(IJCAI 2015), ours beside the paper's, and writes it as JSON (``--scheduler``: the
trials as Dask tasks, the same table; see ``docs/cluster.md``). ``thirdhand irl
experiment large`` plans rewards learned on 4+5 blocks (and the 4-legged chair) on
10, 15 and 20 blocks (6, 7, 8 legs) over relational configurations.
``thirdhand irl learn TASK.json...`` learns a relational reward from the plans of
task files (or of synthetic chairs with ``--synth``) and plans a bench and chairs
with other numbers of legs with it.
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from thirdhand import options
from thirdhand.experiments.relational_irl import EXPERIMENTS, format_table, run_experiment
from thirdhand.fileops import check_output, write_text
from thirdhand.relational.assembly import (
    learn_assembly,
    load_trajectory,
    part_names,
    plan_with_reward,
    synth_trajectories,
)
from thirdhand.relational.logic import RelationalError

app = typer.Typer(
    help="Relational inverse reinforcement learning (RCSI, BLMRIL).",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
out = Console(highlight=False, soft_wrap=True)


#: Most legs ``irl learn --legs`` plans a chair with (planning grows with the part count).
MAX_LEGS = 12
#: Most synthetic chairs ``irl learn --synth`` generates.
MAX_SYNTH = 100


@app.callback()
def _group() -> None:
    """Relational inverse reinforcement learning (RCSI, BLMRIL)."""


@app.command()
def experiment(
    name: Annotated[str, typer.Argument(help=f"One of: {', '.join(EXPERIMENTS)}.")],
    runs: Annotated[int, typer.Option(help="Repetitions per row.", min=2)] = 100,
    jobs: Annotated[int, typer.Option(help="Worker processes.", min=1)] = 1,
    scheduler: Annotated[
        str | None,
        typer.Option(
            help="Run the trials as Dask tasks: tcp://HOST:PORT of a 'dask scheduler', or "
            "'local' (a local cluster of --jobs workers). Needs the dask extra."
        ),
    ] = None,
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
    """Run one of the paper's experiments and print its table beside the paper's."""
    if name not in EXPERIMENTS:
        raise RelationalError(
            f"unknown experiment {name!r}, expected one of {', '.join(EXPERIMENTS)}"
        )
    path = json_out if json_out is not None else Path(f"irl_{name}.json")
    check_output(path, force=force, inputs=[checkpoint] if checkpoint else [])
    options.integer("--runs", runs, low=2, high=100000)
    options.integer("--jobs", jobs, low=1, high=1024)
    if scheduler is not None:
        from thirdhand.batch import check_scheduler

        check_scheduler(scheduler)
    start = time.perf_counter()
    if tabulate and checkpoint is None:
        raise RelationalError("irl experiment: --tabulate needs --checkpoint")
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


@app.command()
def learn(
    tasks: Annotated[
        list[Path] | None, typer.Argument(help="Task files whose plans are demonstrations.")
    ] = None,
    synth: Annotated[
        int, typer.Option(help="Also use the plans of N synthetic chairs.", min=0)
    ] = 0,
    legs: Annotated[
        list[int] | None, typer.Option(help="Plan chairs with these numbers of legs.")
    ] = None,
    n_random: Annotated[
        int, typer.Option(help="Random one-step transitions per MDP.", min=0)
    ] = 300,
    seed: Annotated[int, typer.Option(help="Random seed.")] = 0,
    json_out: Annotated[
        Path | None, typer.Option("--json", help="Write the result as JSON.")
    ] = None,
    force: Annotated[
        bool, typer.Option(help="Replace an existing --json file (kept as a numbered .bak).")
    ] = False,
) -> None:
    """Learn a reward from demonstrated plans; plan a bench and chairs with it."""
    if json_out is not None:
        check_output(json_out, force=force, inputs=tasks or [])
    options.seed(seed)
    options.integer("--synth", synth, low=0, high=MAX_SYNTH)
    options.integer("--n-random", n_random, low=0, high=100000)
    for n in legs or []:
        options.integer("--legs", n, low=1, high=MAX_LEGS)
    trajectories = [load_trajectory(p) for p in tasks or []]
    trajectories += synth_trajectories("chair", range(seed, seed + synth)) if synth else []
    if not trajectories:
        raise RelationalError("irl learn: no demonstration (give task files or --synth N)")
    model = learn_assembly(trajectories, n_random=n_random, seed=seed)
    out.print(f"[bold]learned reward[/bold] ({len(trajectories)} demonstrations)")
    out.print(str(model.rcsi.reward))
    targets = {"bench": {"seating": 1, "leg": 4}}
    for n in legs if legs else [3, 5]:
        targets[f"chair with {n} legs"] = {"seating": 1, "leg": n, "back": 1}
    plans = {}
    for label, counts in targets.items():
        plan = plan_with_reward(model, part_names(counts))
        plans[label] = asdict(plan)
        status = "complete" if plan.complete else "INCOMPLETE"
        out.print(f"[bold]{label}[/bold] ({status}, perf {plan.perf:.3f})")
        for i, step in enumerate(plan.steps):
            out.print(f"  {i + 1}. {step}")
    if json_out is not None:
        write_text(
            json_out, json.dumps({"reward": str(model.rcsi.reward), "plans": plans}, indent=1)
        )
