"""``thirdhand learn``: recordings to one task file (every stage that needs no robot).

The integrator mounts :data:`learn_command` as ``thirdhand learn``. The accuracy
experiments that used to live here are in the repository's ``research/`` folder.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from thirdhand import options
from thirdhand.demonstration import Demonstration
from thirdhand.errors import OptionError, TaskFileError, ThirdhandError
from thirdhand.fileops import check_distinct_inputs, check_output
from thirdhand.progress import stage_status

out = Console(highlight=False, soft_wrap=True)

app = typer.Typer(
    help="Learn a task file from recordings.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


#: ``--jobs`` and ``--scheduler`` of ``learn``: each recording's own stages are a unit.
JobsOption = Annotated[int, typer.Option(help="Run the units in this many local processes.")]
SchedulerOption = Annotated[
    str | None,
    typer.Option(
        help="Run the units as Dask tasks: tcp://HOST:PORT of a 'dask scheduler', or 'local' "
        "(a local cluster of --jobs workers; docs/cluster.md; needs the dask extra)."
    ),
]


def _check_batch(jobs: int, scheduler: str | None) -> None:
    """Refuse a nonsense ``--jobs`` or a malformed ``--scheduler`` before any work."""
    options.integer("--jobs", jobs, low=1, high=1024)
    if scheduler is not None:
        from thirdhand.batch import check_scheduler

        check_scheduler(scheduler)


def check_one_task(demos: Sequence[Demonstration], paths: Sequence[Path]) -> None:
    """Refuse recordings of different tasks: groups of recordings that share no part.

    Recordings of one task show (some of) the same parts; a recording whose parts
    appear in no other recording of the group is of another task, and learning
    from both gives an empty or mixed-up task.

    Raises
    ------
    ThirdhandError
        Naming the groups and their parts.
    """
    parts = [{b.name for b in d.bodies if b.kind == "part"} for d in demos]
    group = list(range(len(demos)))

    def root(i: int) -> int:
        while group[i] != i:
            i = group[i]
        return i

    for i in range(len(demos)):
        for j in range(i):
            if parts[i] & parts[j]:
                group[root(i)] = root(j)
    groups: dict[int, list[int]] = {}
    for i in range(len(demos)):
        groups.setdefault(root(i), []).append(i)
    if len(groups) > 1:
        listed = []
        for members in groups.values():
            names = sorted(set().union(*(parts[i] for i in members)))
            files = ", ".join(str(paths[i]) for i in members)
            listed.append(f"{files} (parts: {', '.join(names) or 'none'})")
        desc = "; ".join(listed)
        raise ThirdhandError(
            f"the recordings show different tasks: no part is shared between {desc}; "
            "learn each task from its own recordings"
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


def _load(path: Path) -> Demonstration:
    from thirdhand import io

    if path.is_dir() and sorted(path.glob("*.bag")) and not (path / "metadata.yaml").exists():
        from thirdhand.io import rosbag

        return rosbag.read(sorted(path.glob("*.bag")))
    return io.load(path)


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
    no_segment: Annotated[
        bool, typer.Option("--no-segment", help="Skip the interaction segmentation.")
    ] = False,
    no_primitives: Annotated[
        bool, typer.Option("--no-primitives", help="Skip the motor primitives (DMP + ProMP).")
    ] = False,
    no_reward: Annotated[
        bool, typer.Option("--no-reward", help="Skip the relational reward (RCSI).")
    ] = False,
    skills: Annotated[
        int,
        typer.Option(
            help="Skills of the library that explains the constraint motions "
            "(stages.primitives.skill_library; 0: no library)."
        ),
    ] = 4,
    seed: Annotated[int, typer.Option(help="Seed of the reward stage and the skill library.")] = 0,
    segment_model: Annotated[
        Path | None,
        typer.Option(
            "--segment-model",
            help="Segmentation model JSON (e.g. from `segment calibrate`) or built-in name.",
        ),
    ] = None,
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
    min_support: Annotated[
        float,
        typer.Option(
            help="A slot becomes a plan step when more than this fraction of the recordings "
            "that show any constraint have it (0.5: a majority; 0: every slot seen once)."
        ),
    ] = 0.5,
    jobs: JobsOption = 1,
    scheduler: SchedulerOption = None,
) -> None:
    """Learn a task from recordings: every stage that needs no robot, into one task file.

    Interaction phases (CRF), constraints, keyframes, symbols, the assembly plan,
    the motor primitives of every learned constraint and the relational reward
    (with the plans it makes for other part sets). Errors are
    :class:`~thirdhand.errors.ThirdhandError`; ``thirdhand.cli.main`` prints them as
    one ``thirdhand: error:`` line.
    """
    from thirdhand.task.meshes import anchor_meshes
    from thirdhand.task_learning import learn_task
    from thirdhand.taskfile import save_task

    options.seed(seed)
    options.integer("--skills", skills, low=0, high=20)
    if not 0.0 <= min_support < 1.0:  # also NaN
        raise OptionError(
            f"--min-support: expected a finite number >= 0 and < 1, got {min_support:g}"
        )
    _check_batch(jobs, scheduler)
    check_distinct_inputs(demos, what="recording")
    check_output(output, force=force, inputs=demos)
    if report is not None:
        if report.exists() and not report.is_dir():
            raise ThirdhandError(f"--report {report}: expected a folder, it is a file")
        check_output(report / "index.html", force=force, inputs=[*demos, output])
    seg_model = None
    if segment_model is not None and not no_segment:
        from thirdhand.segment.model import resolve_model

        seg_model = resolve_model(segment_model)
    loaded = [_load(p) for p in demos]
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
            primitives=not no_primitives,
            skills=skills or None,
            reward=not no_reward,
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
            f"(needs more than {min_support:g}; --min-support to keep it)"
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
        from thirdhand.plan.report import write_report

        out.print(f"report → {write_report(result.learned, report, task, output)}")
