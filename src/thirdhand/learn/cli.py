"""``thirdhand learn``: recordings to one task file (every stage that needs no robot).

The command line mounts :data:`learn_command` as ``thirdhand learn``: it checks the
inputs and outputs, reads the recordings, runs :func:`~thirdhand.learn.run.learn_task`
and saves the task file it built.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from thirdhand import options
from thirdhand.config import ConfigOption, JobsOption, SchedulerOption, check_batch, load_settings
from thirdhand.demonstration import Demonstration
from thirdhand.errors import TaskFileError, ThirdhandError
from thirdhand.fileops import check_distinct_inputs, check_output, check_outputs
from thirdhand.progress import stage_status

out = Console(highlight=False, soft_wrap=True)

app = typer.Typer(
    help="Learn a task file from recordings.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


@contextlib.contextmanager
def _kinds_hint(demos: Sequence[Demonstration], paths: Sequence[Path]) -> Iterator[None]:
    """Name the likely cause when a task learned from Motive exports without kinds is invalid."""
    try:
        yield
    except TaskFileError as exc:
        from thirdhand.io.motive import sidecar_path

        bare = [
            p
            for d, p in zip(demos, paths, strict=True)
            if d.meta.get("format") == "motive" and not d.bodies_of_kind("finger", "hand")
        ]
        if not bare:
            raise
        raise TaskFileError(
            f"{exc}; {bare[0]} states no body kinds (a Motive export), so every body, fingers "
            f"too, was read as a part: state them in {sidecar_path(bare[0])} "
            '({"format": "thirdhand.motive-extra/1", "bodies": [{"name": ..., "kind": '
            '"finger", "hand": "right"}, ...]})'
        ) from None


@app.command("learn")
def learn_command(
    demos: Annotated[
        list[Path],
        typer.Argument(
            help="Recordings (any format thirdhand.io reads; a folder of ROS 1 .bag parts "
            "is read as one recording)."
        ),
    ],
    output: Annotated[Path, typer.Option("-o", "--output", help="Task file to write.")],
    report: Annotated[
        Path | None, typer.Option("--report", help="Folder for the HTML report.")
    ] = None,
    seed: Annotated[int, typer.Option(help="Seed of the reward stage and the skill library.")] = 0,
    force: Annotated[
        bool,
        typer.Option(help="Replace an existing task file / report (kept as numbered .bak)."),
    ] = False,
    scene: Annotated[
        Path | None,
        typer.Option(
            "--scene",
            help="3rdHand scene file (scene_*.json): each part's mesh and its pose on the "
            "sensor. Default: the one on THIRDHAND_MESH_PATH that lists every part, if any.",
        ),
    ] = None,
    jobs: JobsOption = 1,
    scheduler: SchedulerOption = None,
    config: ConfigOption = None,
) -> None:
    """Learn a task from recordings: every stage that needs no robot, into one task file.

    Interaction phases (CRF), constraints, keyframes, symbols, the assembly plan,
    the motor primitives of every learned constraint and the relational reward
    (with the plans it makes for other part sets). Errors are
    :class:`~thirdhand.errors.ThirdhandError`; ``thirdhand.cli.main`` prints them as
    one ``thirdhand: error:`` line. Settings (``[learn]`` of ``--config``): which stages
    run, the skill library's size, the plan's vote, the segmentation model.
    """
    from thirdhand import io
    from thirdhand.learn.recordings import check_one_task
    from thirdhand.learn.run import learn_task
    from thirdhand.learn.settings import LearnSettings
    from thirdhand.task.meshes import anchor_meshes
    from thirdhand.taskfile import save_task

    options.seed(seed)
    cfg = load_settings(config, "learn", LearnSettings)
    no_segment, min_support = not cfg.segment, cfg.min_support
    check_batch(jobs, scheduler)
    check_distinct_inputs(demos, what="recording")
    library_path = Path(cfg.skill_library) if cfg.skill_library else None
    inputs = [*demos, *([config] if config else []), *([library_path] if library_path else [])]
    check_output(output, force=force, inputs=inputs)
    if report is not None:
        if report.exists() and not report.is_dir():
            raise ThirdhandError(f"--report {report}: expected a folder, it is a file")
        check_outputs(
            [("-o", output), ("--report", report / "index.html")], force=force, inputs=inputs
        )
    seg_model = None
    if cfg.segment_model is not None and not no_segment:
        from thirdhand.segment.model import resolve_model

        seg_model = resolve_model(cfg.segment_model)
    skill_library = None
    if library_path is not None and cfg.primitives:
        from thirdhand.primitives.skill_library import read_skill_library

        skill_library = read_skill_library(library_path)
    loaded = [io.load(p) for p in demos]
    for path, d in zip(demos, loaded, strict=True):
        options.body_pairs(len(d), str(path))
    check_one_task(loaded, demos)
    if scene is not None and not scene.is_file():
        raise ThirdhandError(f"--scene {scene}: no such file")
    with stage_status() as say, _kinds_hint(loaded, demos):
        result = learn_task(
            loaded,
            names=[p.name for p in demos],
            segment=not no_segment,
            segment_model=seg_model,
            primitives=cfg.primitives,
            skills=cfg.skills or None,
            skill_library=skill_library,
            reward=cfg.reward,
            seed=seed,
            inputs=demos,
            progress=say,
            min_support=min_support,
            scene="auto" if scene is None else scene,
            jobs=jobs,
            scheduler=scheduler,
        )
    if result.task.stages.scene is not None:
        out.print(f"meshes: {result.task.stages.scene.file}")
    check_output(output, force=force, inputs=demos)
    task = anchor_meshes(result.task, output)
    save_task(task, output)
    plan = result.learned.plan
    out.print(f"root: {plan.root}")
    for line in plan.lines():
        out.print(f"  {line}")
    for k in plan.silent:
        out.print(f"  {demos[k]}: no constraint found; it does not vote on the plan's steps")
    for symbol, seen in plan.left_out.items():
        out.print(
            f"  slot {symbol} seen in {seen} of {plan.voters} recordings: not a step "
            f"(needs more than {min_support:g}; the setting min_support keeps it)"
        )
    blocks = ", ".join(task.stages.names())
    out.print(f"{len(task.constraints)} constraints, {len(task.plan)} steps → {output} ({blocks})")
    if result.reward is not None:
        for label, p in result.reward.plans.items():
            state = "complete" if p.complete else "incomplete"
            out.print(f"  reward plan for {label}: {len(p.steps)} steps, {state}")
    for reason in result.skipped:
        out.print(f"  {reason}")
    if report is not None:
        from thirdhand.learn.report import write_report

        out.print(f"report → {write_report(result.learned, report, task, output)}")
