"""``thirdhand transfer TASK.json --to SCENE|MESHES -o NEW.json``."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer

from thirdhand.errors import ThirdhandError


def transfer_command(
    task: Annotated[Path, typer.Argument(help="The task file to transfer.")],
    to: Annotated[
        str,
        typer.Option(
            "--to",
            help="Target objects: a synthetic scene name (bench, chair...), a 3rdHand "
            "scene_*.json, or a folder with one scene_*.json or one STL file per object.",
        ),
    ],
    output: Annotated[Path, typer.Option("-o", "--output", help="The new task file.")],
    force: Annotated[
        bool,
        typer.Option("--force", help="Replace OUTPUT if it exists (kept as a numbered .bak)."),
    ] = False,
) -> None:
    """Map a task onto another object set (chair -> bench) as a start for the person's adaptation.

    Objects are matched by name and role; positions are scaled by the parents'
    bounding boxes; orientations, free DOFs and the plan of the remaining steps are
    kept. Prints what was dropped or scaled.
    """
    from thirdhand.fileops import check_output
    from thirdhand.review.transfer import transfer
    from thirdhand.taskfile import load_task, save_task

    try:
        inputs = [task, *([Path(to)] if Path(to).exists() else [])]
        check_output(output, force=force, inputs=inputs)
        result = transfer(load_task(task), to)
        output.parent.mkdir(parents=True, exist_ok=True)
        save_task(result.task, output)
    except ThirdhandError as exc:
        sys.stderr.write(f"thirdhand: error: {exc}\n")
        raise typer.Exit(1) from None
    block = result.task.stages.transfer
    assert block is not None  # transfer_task writes it
    pairs = ", ".join(f"{a}->{b}" for a, b in block.mapping.items())
    typer.echo(f"{task} -> {output} ({to}): {pairs}")
    for note in result.notes:
        typer.echo(f"  {note}")
    typer.echo(
        f"{len(result.task.constraints)} constraints, {len(result.task.plan)} steps; "
        "review it with: thirdhand review " + str(output)
    )
