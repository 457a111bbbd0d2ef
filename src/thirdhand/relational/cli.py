"""``thirdhand irl``: relational inverse reinforcement learning (RCSI, BLMRIL).

The paper's tables (Munzer et al., IJCAI 2015) are reproduced by the repository's
``research/`` folder (``python -m research irl NAME``), not by the package.
``thirdhand irl learn TASK.json...`` learns a relational reward from the plans of
task files (or of synthetic chairs with ``--synth``) and plans a bench and chairs
with other numbers of legs with it.
"""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from thirdhand import jsontext, options
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
    for n in legs or []:
        options.integer("--legs", n, low=1, high=MAX_LEGS)
    trajectories = [load_trajectory(p) for p in tasks or []]
    trajectories += synth_trajectories("chair", range(seed, seed + synth)) if synth else []
    if not trajectories:
        raise RelationalError("irl learn: no demonstration (give task files or --synth N)")
    model = learn_assembly(trajectories, seed=seed)
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
            json_out,
            jsontext.dumps(
                {"reward": str(model.rcsi.reward), "plans": plans}, what=str(json_out), indent=1
            ),
        )
