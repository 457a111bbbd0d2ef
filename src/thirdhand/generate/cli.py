"""``thirdhand generate TASK.json --episodes N -o DIR``: robot training data from simulation.

Episode ``i`` plans the task from the start layout of seed ``--seed + i`` (as
``thirdhand execute --seed`` does), runs it in MuJoCo (``thirdhand simulate``'s
physics, ``[simulate]`` of ``--config``) and is kept when every step is done.
The kept episodes, in seed order, become a LeRobot v3.0 dataset at ``DIR``:
joint state and commands, the parts' poses, a fixed and a wrist camera
(``[generate]`` of ``--config``: frame rate, image size). ``--jobs`` and
``--scheduler`` compute the episodes in other processes; the dataset is the
same. Needs the ``sim`` extra.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from thirdhand.config import ConfigOption, JobsOption, SchedulerOption, check_batch, load_settings
from thirdhand.errors import ThirdhandError

out = Console(highlight=False, soft_wrap=True)

#: Largest seed of an episode (the layout and planner seed's range).
MAX_SEED = 2**31 - 1


def generate_command(
    task: Annotated[Path, typer.Argument(help="Task file (thirdhand.task/2 JSON).")],
    episodes: Annotated[int, typer.Option("--episodes", "-n", help="Episodes to simulate.")],
    output: Annotated[Path, typer.Option("-o", "--output", help="Dataset folder to write.")],
    seed: Annotated[int, typer.Option(help="Seed of episode 0; episode i uses seed + i.")] = 0,
    robot: Annotated[
        str | None,
        typer.Option(help="Robot planned and simulated (default: the task's, else panda)."),
    ] = None,
    jobs: JobsOption = 1,
    scheduler: SchedulerOption = None,
    force: Annotated[
        bool, typer.Option(help="Replace an existing dataset folder (kept as numbered .bak).")
    ] = False,
    config: ConfigOption = None,
) -> None:
    """Simulate a task's plan from N start layouts and write the episodes as a LeRobot dataset.

    An episode is kept when every step is done in the physics; the others are
    counted with their reasons. Settings: ``[simulate]`` of ``--config`` (the
    physics; ``thirdhand config simulate``) and ``[generate]`` (frame rate,
    image size; ``thirdhand config generate``).
    """
    from thirdhand import options
    from thirdhand.simulate.cli import check_extra

    check_extra()
    options.integer("--episodes", episodes, low=1, high=1_000_000)
    options.integer("--seed", seed, low=0, high=MAX_SEED - episodes + 1)
    check_batch(jobs, scheduler)
    from thirdhand.fileops import check_output
    from thirdhand.generate.dataset import generate_dataset, jobs_for
    from thirdhand.generate.episodes import EpisodeJob, EpisodeOutcome, check_settings
    from thirdhand.generate.settings import GenerateSettings
    from thirdhand.simulate.plan import sim_robot
    from thirdhand.simulate.settings import SimulateSettings
    from thirdhand.task.store import load_task

    sim = load_settings(config, "simulate", SimulateSettings)
    gen = load_settings(config, "generate", GenerateSettings)
    check_settings(gen, sim)
    for folder in sim.meshes:
        if not Path(folder).is_dir():
            raise ThirdhandError(f"[simulate] meshes {folder}: not a folder of part meshes")
    inputs = [task, *([config] if config else [])]
    check_output(output, force=force, inputs=inputs)
    t = load_task(task)
    name = sim_robot(t, robot if robot is not None else sim.robot)
    template = EpisodeJob(
        task=t, task_path=str(task), name=task.name.split(".")[0], seed=seed, robot=name,
        search=tuple(sim.meshes), simulate=sim, settings=gen,
    )  # fmt: skip
    from thirdhand.progress import progress

    kept = 0
    with progress() as bar:
        row = bar.add_task(f"generate: 0 of {episodes} episodes", total=episodes)

        def say(outcome: EpisodeOutcome) -> None:
            nonlocal kept
            kept += outcome.kept
            done = int(bar.tasks[0].completed) + 1
            bar.update(row, advance=1, description=f"generate: {done} of {episodes}, {kept} kept")

        summary = generate_dataset(
            jobs_for(template, seed, episodes), output, force=force, jobs=jobs,
            scheduler=scheduler, on_outcome=say,
        )  # fmt: skip
    ds = summary.dataset
    assert ds is not None
    out.print(
        f"wrote {output}: LeRobot dataset, {ds.episodes} of {episodes} episodes kept "
        f"{_seeds(summary.kept)}, {ds.frames} frames at {gen.fps} fps, "
        f"front and wrist cameras {gen.width}×{gen.height}"
    )
    if summary.reasons:
        what = ", ".join(
            f"{r} ×{n}" for r, n in sorted(summary.reasons.items(), key=lambda i: -i[1])
        )
        out.print(f"not kept: {summary.dropped} episodes ({what})")


def _seeds(kept: tuple[int, ...]) -> str:
    if len(kept) > 10:
        return f"(seeds {kept[0]} to {kept[-1]})"
    return f"(seed{'s' if len(kept) > 1 else ''} {', '.join(map(str, kept))})"
