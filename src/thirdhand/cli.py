"""The ``thirdhand`` command line.

Every command turns a user's bad input into one line on stderr and a non-zero
exit status, never a traceback. Long work shows progress on a terminal only.
"""

from __future__ import annotations

import signal
import sys

from thirdhand import jsontext
from thirdhand.errors import Terminated


def _interrupted_at_start_up(signum: int, frame: object) -> None:
    word = "terminated" if signum == signal.SIGTERM else "interrupted"
    sys.stderr.write(f"thirdhand: error: {word}; no output was written\n")
    sys.stderr.flush()
    raise SystemExit(143 if signum == signal.SIGTERM else 130)


# Ctrl-C or SIGTERM while the (heavy) imports below run: one line, exit 130 or 143.
if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
    signal.signal(signal.SIGINT, _interrupted_at_start_up)
if __name__ == "__main__" or (sys.argv[:1] and sys.argv[0].endswith(("thirdhand", "__main__.py"))):
    if signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
        signal.signal(signal.SIGTERM, _interrupted_at_start_up)

import json  # noqa: E402
import math  # noqa: E402
import time  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Annotated, Any  # noqa: E402

import typer  # noqa: E402
from rich.console import Console  # noqa: E402
from rich.table import Table  # noqa: E402
from typer.core import TyperCommand, TyperGroup  # noqa: E402

from thirdhand import options  # noqa: E402
from thirdhand._version import __version__  # noqa: E402
from thirdhand.config import ConfigOption, load_settings  # noqa: E402
from thirdhand.errors import ThirdhandError  # noqa: E402
from thirdhand.fileops import check_output, check_outputs, interrupted_message  # noqa: E402


@dataclass(frozen=True)
class LazyCommand:
    """A command or command group whose module is imported only when it runs.

    Attributes
    ----------
    module : str
        Module defining it (imported on first use: its dependencies stay unloaded
        for ``thirdhand --help`` and every other command).
    attr : str
        A typer ``Typer`` (a command group) or a command function in ``module``.
    help : str
        One line for the command list of ``thirdhand --help``.
    """

    module: str
    attr: str
    help: str


#: Stage commands, imported when they run: name -> where they live. The order is
#: the order of ``thirdhand --help`` after the commands defined in this module.
LAZY: dict[str, LazyCommand] = {
    "learn": LazyCommand(
        "thirdhand.learn.cli", "learn_command", "Learn a task file from recordings (every stage)."
    ),
    "segment": LazyCommand(
        "thirdhand.segment.cli", "app", "Interaction phases per body pair (linear-chain CRF)."
    ),
    "constraints": LazyCommand(
        "thirdhand.constraints.cli",
        "app",
        "Kinematic constraints (fixed, prismatic, revolute, cylindrical, free) of a track.",
    ),
    "primitives": LazyCommand(
        "thirdhand.primitives.cli",
        "app",
        "Motor primitives: DMPs and ProMPs per constraint, primitive libraries.",
    ),
    "irl": LazyCommand(
        "thirdhand.relational.cli",
        "app",
        "Relational inverse reinforcement learning (RCSI, BLMRIL).",
    ),
    "execute": LazyCommand(
        "thirdhand.execute.cli",
        "execute_command",
        "Execute a task's plan on a simulated robot arm with a motion planner.",
    ),
    "simulate": LazyCommand(
        "thirdhand.simulate.cli",
        "simulate_command",
        "Run a task's plan in a physics simulator (MuJoCo) and say per step whether it works.",
    ),
    "generate": LazyCommand(
        "thirdhand.generate.cli",
        "generate_command",
        "Simulate a task's plan from many start layouts and write a LeRobot dataset.",
    ),
    "live": LazyCommand(
        "thirdhand.live.cli",
        "live_command",
        "Follow a person through a task's plan, live (a recording replayed as a stream).",
    ),
    "merge": LazyCommand(
        "thirdhand.merge.cli",
        "merge_command",
        "Merge recordings of one session by several capture systems (clock and frame aligned).",
    ),
    "review": LazyCommand(
        "thirdhand.review.cli",
        "review_command",
        "Open a task in the review GUI (a local web app): see, animate and correct it.",
    ),
    "transfer": LazyCommand(
        "thirdhand.review.transfer_cli",
        "transfer_command",
        "Map a task onto another object set (chair -> bench) as a start for adaptation.",
    ),
    "headpose": LazyCommand(
        "thirdhand.perception.cli",
        "headpose_command",
        "Head pose (yaw, pitch, roll) per frame of a video, relative to a calibration pose.",
    ),
    "gestures": LazyCommand(
        "thirdhand.perception.cli",
        "gestures_command",
        "Pointing gestures (hand, target object, interval) in a recording.",
    ),
    "attention": LazyCommand(
        "thirdhand.perception.cli",
        "attention_command",
        "Which object a tracked head attends to, as intervals.",
    ),
}


def load_command(name: str) -> Any:
    """Import the stage command ``name`` of :data:`LAZY` and return it as a click command.

    Raises
    ------
    ThirdhandError
        When a package the command needs is not installed (one line naming it).
    """
    import importlib

    entry = LAZY[name]
    try:
        mod = importlib.import_module(entry.module)
    except ModuleNotFoundError as exc:
        if exc.name is None or exc.name.split(".")[0] == "thirdhand":
            raise
        raise ThirdhandError(
            f"'thirdhand {name}' needs the Python package {exc.name!r}, which is not installed; "
            "install thirdhand with its extras: pip install 'thirdhand[dev]'"
        ) from None
    obj = getattr(mod, entry.attr)
    command: Any
    if isinstance(obj, typer.Typer):
        command = typer.main.get_group(obj)
    else:
        single = typer.Typer(add_completion=False, pretty_exceptions_enable=False)
        single.command(name, help=entry.help)(obj)
        command = typer.main.get_command(single)
    command.name = name
    return command


class _LazyGroup(TyperGroup):
    """The root group: lists :data:`LAZY` commands by their one line, imports one when it runs."""

    def list_commands(self, ctx: Any) -> list[str]:
        return [*super().list_commands(ctx), *(n for n in LAZY if n not in self.commands)]

    def get_command(self, ctx: Any, cmd_name: str) -> Any:
        if cmd_name in self.commands or cmd_name not in LAZY:
            return super().get_command(ctx, cmd_name)
        # Listing (help): a stand-in with the one line, no import.
        return TyperCommand(cmd_name, help=LAZY[cmd_name].help, callback=None)

    def format_commands(self, ctx: Any, formatter: Any) -> None:
        """The command list with each command's whole first paragraph (wrapped, not cut)."""
        rows = []
        for name in self.list_commands(ctx):
            command = self.get_command(ctx, name)
            if command is None or command.hidden:
                continue
            text = command.short_help or (command.help or "").split("\n\n")[0]
            rows.append((name, " ".join(text.split())))
        if rows:
            with formatter.section("Commands"):
                formatter.write_dl(rows)

    def resolve_command(self, ctx: Any, args: list[str]) -> Any:
        if args and args[0] in LAZY and args[0] not in self.commands:
            return args[0], load_command(args[0]), args[1:]
        return super().resolve_command(ctx, args)


app = typer.Typer(
    cls=_LazyGroup,
    # Plain help for the root: typer's rich help imports markdown rendering (~0.1 s),
    # the largest part of `thirdhand --help` after numpy (benchmarks/cli_startup.py).
    rich_markup_mode=None,
    name="thirdhand",
    help="Teach a robot an assembly task from human demonstrations.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
out = Console(highlight=False, soft_wrap=True)


def _fail(message: str, code: int = 1) -> None:
    sys.stderr.write(f"thirdhand: error: {message}\n")
    raise typer.Exit(code)


def _version(value: bool) -> None:
    if value:
        out.print(f"thirdhand {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: Annotated[
        bool, typer.Option("--version", callback=_version, is_eager=True, help="Print the version.")
    ] = False,
) -> None:
    """Teach a robot an assembly task from human demonstrations."""


@app.command()
def synth(
    scene: Annotated[str, typer.Argument(help="Scene: chair, bench, toolbox, drawer or lid.")],
    output: Annotated[Path, typer.Option("-o", "--output", help="File to write (any format).")],
    seed: Annotated[int, typer.Option(help="Random seed.")] = 0,
    noise_free: Annotated[
        bool, typer.Option("--noise-free", help="No sensor noise, gaps or sign flips.")
    ] = False,
    rate: Annotated[float | None, typer.Option(help="Capture rate, Hz.")] = None,
    force: Annotated[
        bool, typer.Option(help="Replace an existing output (kept as a numbered .bak).")
    ] = False,
    config: ConfigOption = None,
) -> None:
    """Generate a synthetic assembly demonstration with ground-truth labels.

    Settings (``[synth]`` of ``--config``): ``head`` (track the person's head),
    ``pointing`` (open with N pointing gestures).
    """
    from thirdhand import io
    from thirdhand.synth import SCENES, SensorModel, make_scene

    if scene not in SCENES:
        _fail(f"unknown scene {scene!r}; scenes are {', '.join(SCENES)}")
    options.seed(seed)
    if rate is not None:
        options.finite("--rate", rate, low=1.0, high=10000.0)
    from thirdhand.synth.settings import SynthSettings

    cfg = load_settings(config, "synth", SynthSettings)
    head, pointing = cfg.head, cfg.pointing
    check_output(output, force=force, inputs=[config] if config else [])
    sensor = None
    if not noise_free:
        sensor = SensorModel() if rate is None else SensorModel(rate=rate)
    scene_options: dict[str, Any] = {"head": True} if head else {}
    if pointing:
        scene_options["pointing"] = pointing
    demo = make_scene(scene, seed=seed, sensor=sensor, **scene_options)
    check_output(output, force=force)
    io.save(demo, output)
    out.print(f"wrote {output}: {demo}")


@app.command()
def info(
    path: Annotated[Path, typer.Argument(help="A recording of any supported format.")],
    as_json: Annotated[bool, typer.Option("--json", help="Print JSON instead of a table.")] = False,
) -> None:
    """Describe a recording: bodies, kinds, duration, rate, missing data, labels."""
    from thirdhand import io

    fmt = io.detect(path)
    demo = io.load(path, format=fmt)
    summary = describe(demo, fmt=fmt, path=path)
    if as_json:
        # Strict JSON: a rate or duration that does not exist (one frame) is null, never NaN.
        out.print_json(json.dumps(json_safe(summary), allow_nan=False))
        return
    out.print(
        f"{path} ({fmt}): {len(demo)} bodies, {demo.n_frames} frames, "
        f"{demo.duration:.3f} s, {demo.rate:.2f} Hz"
    )
    table = Table("body", "kind", "hand", "missing")
    for b in summary["bodies"]:
        table.add_row(b["name"], b["kind"], b.get("hand") or "", f"{100 * b['missing']:.1f} %")
    out.print(table)
    lab = summary["labels"]
    out.print(
        f"labels: {lab['interactions']} interaction intervals, "
        f"{lab['constraints']} constraint events, {lab['plan']} plan steps"
    )
    tracker = summary.get("tracker")
    if tracker and tracker["dropped_samples"]:
        resets = ", ".join(f"{s:.2f} s" for s in tracker["frame_resets_s"])
        out.print(
            f"tracker: {tracker['dropped_samples']} samples dropped as reports at the source "
            "or from before a frame reset" + (f" (reset at {resets})" if resets else "")
        )


def json_safe(value: Any) -> Any:
    """``value`` with every non-finite float replaced by None (strict JSON has no NaN)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    return value


def describe(demo: Any, *, fmt: str | None = None, path: Path | None = None) -> dict[str, Any]:
    """JSON-able summary of a demonstration (what ``thirdhand info`` prints)."""
    return {
        "path": None if path is None else str(path),
        "format": fmt,
        "n_bodies": len(demo),
        "n_frames": demo.n_frames,
        "duration_s": demo.duration,
        "rate_hz": demo.rate,
        "bodies": [
            {
                "name": b.name,
                "kind": b.kind,
                "hand": b.hand,
                "oriented": b.oriented,
                "missing": demo.missing_fraction(b.name),
            }
            for b in demo.bodies
        ],
        "labels": {
            "interactions": len(demo.labels.interactions),
            "constraints": len(demo.labels.constraints),
            "plan": len(demo.labels.plan),
        },
        **_tracker_summary(demo),
    }


def _tracker_summary(demo: Any) -> dict[str, Any]:
    """What the reader dropped (MLR: samples at the G4's source, frame resets)."""
    mlr = demo.meta.get("mlr") if isinstance(demo.meta, dict) else None
    if not isinstance(mlr, dict) or "dropped_samples" not in mlr:
        return {}
    t0 = float(demo.t[0]) if demo.n_frames else 0.0
    return {
        "tracker": {
            "dropped_samples": int(mlr["dropped_samples"]),
            "frame_resets_s": [float(s) - t0 for s in mlr.get("frame_resets_s", [])],
        }
    }


@app.command()
def convert(
    source: Annotated[Path, typer.Argument(help="Recording to read (any supported format).")],
    target: Annotated[Path, typer.Argument(help="File to write; format from the extension.")],
    to: Annotated[
        str | None, typer.Option("--to", help="Output format, if not by extension.")
    ] = None,
    force: Annotated[
        bool, typer.Option(help="Replace an existing output (kept as a numbered .bak).")
    ] = False,
    with_: Annotated[
        list[Path] | None,
        typer.Option(
            "--with",
            help=".rrd: also show this file (repeatable): a task file, a recording (from a "
            "TASK source), a phases file (segment --json) or a run (execute --record OUT.json).",
        ),
    ] = None,
    lossy: Annotated[
        bool,
        typer.Option(
            "--lossy",
            help="Write even when the target format cannot carry all the recording holds "
            "(meta, exact label times, body kinds); what is lost is printed.",
        ),
    ] = False,
    fps: Annotated[
        int | None,
        typer.Option(
            "--fps",
            help="--to lerobot: frames per second of the dataset (default: the recording's "
            "rate, rounded).",
        ),
    ] = None,
) -> None:
    """Convert a recording between formats, or export a task or a run to a robot or a viewer.

    ``convert REC|TASK out.rrd`` writes the bodies' poses on a timeline, the
    interaction phases, keyframes, learned constraints and an execution replay
    (needs the ``rerun`` extra); see ``thirdhand.export.rrd``.
    ``convert RUN.json out.mcap`` writes an executed run (``execute --record``)
    as a ROS 2 bag; ``convert TASK out.xml`` the plan as a BehaviorTree.CPP v4
    tree; ``convert TASK out.pddl`` a PDDL problem and its domain
    (``out.domain.pddl``); see docs/how-to/robot.md.
    ``convert REC DIR --to lerobot`` writes the recording as a one-episode
    LeRobot dataset (v3.0): every body's pose per frame at ``--fps``, the
    interaction labels as per-frame text; see docs/reference/lerobot.md.

    A recording is read back from what would be written before it replaces
    anything: a format that cannot carry the recording exactly (its meta, label
    times to the nanosecond, body kinds, poses to the format's precision) is
    refused with what it would lose, unless ``--lossy``; one that thirdhand
    cannot read back is always refused.
    """
    from thirdhand import io

    if to is not None and to.lower() == "lerobot":
        if with_ or lossy:
            _fail("--with, --lossy: not for --to lerobot")
        _convert_lerobot(source, target, force=force, fps=fps)
        return
    if fps is not None:
        _fail("--fps: only for --to lerobot")
    suffix = target.suffix.lower()
    if suffix == ".rrd":
        _convert_rrd(source, target, force=force, **_classify_extras(with_ or []))
        return
    given = ["--with"] if with_ else []
    if lossy and (suffix in (".rrd", ".xml", ".pddl") or source.suffix.lower() == ".json"):
        _fail("--lossy: only for converting a recording to another recording format")
    if suffix in (".xml", ".pddl") or (suffix == ".mcap" and source.suffix.lower() == ".json"):
        if given or to is not None:
            _fail(f"{', '.join(given + ['--to'] * (to is not None))}: not for a {suffix} target")
        _convert_robot(source, target, force=force)
        return
    if given:
        _fail(f"{', '.join(given)}: only for a .rrd target")
    check_output(target, force=force, inputs=[source])
    recording = io.load(source)
    check_output(target, force=force, inputs=[source])
    lost = _save_checked(recording, target, fmt=to, lossy=lossy)
    out.print(f"wrote {target}: {recording}")
    if lost:
        out.print(f"not carried by the format (--lossy): {'; '.join(lost)}")


def _convert_lerobot(source: Path, target: Path, *, force: bool, fps: int | None) -> None:
    """A recording as a one-episode LeRobot dataset folder (``thirdhand.lerobot.human``)."""
    from thirdhand import io
    from thirdhand.lerobot.human import recording_episode
    from thirdhand.lerobot.writer import write_dataset

    check_output(target, force=force, inputs=[source])
    recording = io.load(source)
    rate = fps if fps is not None else max(1, round(recording.rate))
    task = str(recording.meta.get("task") or f"human demonstration {source.name}")
    human = recording_episode(recording, fps=rate, task=task)
    summary = write_dataset([human.episode], target, fps=rate, robot_type=None, force=force)
    out.print(
        f"wrote {target}: LeRobot dataset, {summary.frames} frames at {rate} fps, "
        f"{len(human.episode.names['observation.state']) // 7} bodies"
    )
    if human.dropped:
        out.print(f"left out (never tracked): {', '.join(human.dropped)}")


def _save_checked(recording: Any, target: Path, *, fmt: str | None, lossy: bool) -> list[str]:
    """Write ``recording`` to ``target`` only once it reads back (and, unless ``lossy``, equal).

    Returns what the written file does not carry (empty unless ``lossy``).
    """
    from thirdhand import io
    from thirdhand.errors import FormatError
    from thirdhand.fileops import atomic_output
    from thirdhand.io.roundtrip import losses

    lost: list[str] = []

    def verify(built: Path) -> None:
        try:
            back = io.load(built)
        except ThirdhandError as exc:
            text = " ".join(str(exc).replace(str(built), str(target)).split())
            raise FormatError(
                target,
                f"thirdhand could not read back what it would write ({text}); nothing was written",
            ) from None
        lost[:] = losses(recording, back)
        if lost and not lossy:
            raise FormatError(
                target,
                f"the {fmt or io.detect(built)} format cannot carry {'; '.join(lost)}: nothing "
                "was written (pass --lossy to write it without them, or choose .parquet)",
            )

    with atomic_output(target, verify=verify) as tmp:
        try:
            io.save(recording, tmp, format=fmt)
        except FormatError as exc:  # name the target, not the temporary path
            raise FormatError(target, exc.message.replace(str(tmp), str(target))) from None
    return lost


def _convert_robot(source: Path, target: Path, *, force: bool) -> None:
    """A run to a ROS 2 MCAP, or a task to a behaviour tree or a PDDL problem and domain."""
    from thirdhand.errors import TaskFileError
    from thirdhand.fileops import write_text

    suffix = target.suffix.lower()
    if suffix == ".mcap":
        from thirdhand.export.ros2 import replay_path, write_mcap

        check_output(target, force=force, inputs=[source, replay_path(source)])
        if not target.parent.is_dir():
            _fail(f"{target}: the folder {target.parent} does not exist")
        counts = write_mcap(source, target)
        shown = ", ".join(f"{n} {topic}" for topic, n in counts.items())
        out.print(f"wrote {target}: {shown}")
        return
    from thirdhand.export.pddl_task import domain_path
    from thirdhand.taskfile import load_task

    outputs = [target, domain_path(target)] if suffix == ".pddl" else [target]
    check_outputs(
        list(zip(("TARGET", "its domain"), outputs, strict=False)), force=force, inputs=[source]
    )
    if not target.parent.is_dir():
        _fail(f"{target}: the folder {target.parent} does not exist")
    task = load_task(source)
    try:
        if suffix == ".xml":
            from thirdhand.export.behavior_tree import tree_xml

            texts = [tree_xml(task)]
        else:
            from thirdhand.export.pddl_task import DOMAIN, problem_pddl

            texts = [problem_pddl(task, name=source.stem.removesuffix(".task")), DOMAIN]
    except TaskFileError as exc:
        _fail(f"{source}: {exc}")
    for o, text in zip(outputs[::-1], texts[::-1], strict=True):
        write_text(o, text)
    steps = f"{len(task.plan)} plan step{'s' * (len(task.plan) != 1)}"
    out.print(f"wrote {' and '.join(map(str, outputs))}: {steps}")


def _classify_extras(paths: list[Path]) -> dict[str, Path | None]:
    """``--with`` files by what they hold: ``task``, ``phases``, ``execution`` or ``demo``.

    A JSON file is recognised by its ``schema``/``format`` key; anything else is a
    recording. Each kind may be given once.
    """
    from thirdhand.errors import FormatError
    from thirdhand.readlimits import loads_json, read_text_input

    kinds: dict[str, Path | None] = dict.fromkeys(("task", "demo", "phases", "execution"))
    for path in paths:
        kind = "demo"
        if path.suffix.lower() == ".json":

            def error(message: str, path: Path = path) -> FormatError:
                return FormatError(path, message)

            doc = loads_json(
                read_text_input(path, what="JSON file", error=error), error=error, strict=True
            )
            tag = str(doc.get("schema") or doc.get("format") or "") if isinstance(doc, dict) else ""
            if tag.startswith("thirdhand.task/"):
                kind = "task"
            elif tag == "thirdhand.phases/1":
                kind = "phases"
            elif tag == "thirdhand.trajectory/1" or (
                isinstance(doc, dict) and "t" in doc and "q" in doc  # records before the schema
            ):
                kind = "execution"
            else:
                _fail(
                    f"--with {path}: not a task, phases or run file (no thirdhand schema); "
                    "a recording is given in its own format"
                )
        if kinds[kind] is not None:
            _fail(f"--with {path}: a second {kind} file (the first: {kinds[kind]})")
        kinds[kind] = path
    return kinds


def _convert_rrd(
    source: Path,
    target: Path,
    *,
    force: bool,
    task: Path | None,
    demo: Path | None,
    phases: Path | None,
    execution: Path | None,
) -> None:
    from thirdhand import io
    from thirdhand.export.rrd import missing_extra

    message = missing_extra()
    if message:
        _fail(message)
    from thirdhand.export.rrd import write_rrd
    from thirdhand.taskfile import load_task

    inputs = [p for p in (source, task, demo, phases, execution) if p is not None]
    check_output(target, force=force, inputs=inputs)
    if not target.parent.is_dir():
        _fail(f"{target}: the folder {target.parent} does not exist")
    task_path = task
    if source.suffix.lower() == ".json" and source.is_file():
        if task is not None:
            _fail(f"{source} is a task file already; --with a second task is not shown")
        task_path = source
        recording = demo
    else:
        if demo is not None:
            _fail("--with a recording is for a TASK source; the source is the recording")
        recording = source
    task_file = load_task(task_path) if task_path is not None else None
    if recording is None and task_file is not None and task_path is not None:
        from thirdhand.execute.cli import learned_from

        recording = learned_from(task_file, task_path)
    demo_obj = io.load(recording) if recording is not None else None
    if demo_obj is not None and task_file is not None:
        problem = task_file.foreign_recording_problem(demo_obj.body_names)
        if problem is not None:
            _fail(f"--with {recording}: {problem}")
    counts = write_rrd(
        target,
        demo_obj,
        task=task_file,
        task_path=task_path,
        phases=phases,
        execution=execution,
    )
    shown = ", ".join(f"{v} {k.replace('_', ' ')}" for k, v in counts.items() if v)
    out.print(f"wrote {target}: {shown or 'nothing to show'}")


@app.command()
def demo(
    output: Annotated[Path, typer.Option("-o", "--output", help="Output folder.")] = Path(
        "out/chair"
    ),
    seed: Annotated[int, typer.Option(help="Random seed of the synthetic demonstration.")] = 0,
) -> None:
    """The main job: a synthetic chair assembly through every stage that exists."""
    from thirdhand.demo import run_demo
    from thirdhand.fileops import write_text

    options.seed(seed)
    start = time.perf_counter()
    summary = run_demo(output, seed=seed)
    out.print(f"[bold]thirdhand demo[/bold] (chair, seed {seed}) → {output}")
    for line in summary["lines"]:
        out.print(f"  {line}")
    out.print(f"done in {time.perf_counter() - start:.1f} s")
    write_text(
        output / "summary.json",
        jsontext.dumps(summary, what=str(output / "summary.json"), indent=2, default=str),
    )


@app.command("config")
def config_command(
    command: Annotated[
        str | None,
        typer.Argument(help="A command (e.g. execute, 'segment evaluate'); default: every one."),
    ] = None,
) -> None:
    """The settings of the commands, with their defaults, as a file for --config (TOML)."""
    from thirdhand.config import REGISTRY, defaults_toml

    if command is None:
        names = list(REGISTRY)
    else:
        key = ".".join(command.split())
        if key not in REGISTRY:
            raise ThirdhandError(
                f"config: {command!r} has no settings; commands with settings: "
                + ", ".join(k.replace(".", " ") for k in REGISTRY)
            )
        names = [key]
    typer.echo("\n\n".join(defaults_toml(n) for n in names))


# The imports are done: a program that imports this module (and never calls
# main) keeps Python's own Ctrl-C behaviour.
if signal.getsignal(signal.SIGINT) is _interrupted_at_start_up:
    signal.signal(signal.SIGINT, signal.default_int_handler)
if signal.getsignal(signal.SIGTERM) is _interrupted_at_start_up:
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _on_signal(signum: int, frame: object) -> None:
    """Ctrl-C or SIGTERM: KeyboardInterrupt or Terminated, once a write's step is over."""
    from thirdhand.fileops import defer_signal, signal_exception

    if not defer_signal(signum):
        raise signal_exception(signum)


def _one_line(exc: BaseException | str) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return f"thirdhand: error: {text}\n"


def _is_usage_error(exc: Exception) -> bool:
    """A click usage error (bad option value, unknown option, missing argument)."""
    return all(hasattr(exc, a) for a in ("format_message", "exit_code", "show"))


def _usage_error(exc: Any) -> int:
    """Print a click usage error as one line (help for a bare group); return its status."""
    if type(exc).__name__ == "NoArgsIsHelpError":
        exc.show()  # a group called without a command prints its help, as standalone does
        return int(exc.exit_code)
    ctx = getattr(exc, "ctx", None)
    hint = f" (see '{ctx.command_path} --help')" if ctx is not None else ""
    sys.stderr.write(_one_line(exc.format_message() + hint))
    return int(exc.exit_code)


def main(argv: list[str] | None = None) -> int:
    """Entry point: run the CLI, print user errors on one line, return the exit status.

    Usage errors are reported by typer itself (standalone mode exits through
    ``SystemExit``); a user's bad input raises a ``ThirdhandError`` that ends here.
    Ctrl-C (SIGINT) and SIGTERM stop the command whatever disposition the process
    inherited (a background job starts with SIGINT ignored): one line on stderr,
    exit status 130 or 143, temporary files removed and servers stopped by the
    ``finally`` blocks on the way out.
    """
    from thirdhand.fileops import forget_checked_outputs, remove_leftovers, signals_deferred

    forget_checked_outputs()
    previous: dict[signal.Signals, Any] = {}
    for sig, handler in (
        (signal.SIGINT, _on_signal),
        (signal.SIGTERM, _on_signal),
    ):
        try:
            previous[sig] = signal.signal(sig, handler)
        except ValueError:
            pass  # not the main thread (an embedding application): leave signals alone
    try:
        # Not standalone: usage errors come back here and are printed as one line.
        code = app(args=argv, prog_name="thirdhand", standalone_mode=False)
    except ThirdhandError as exc:
        sys.stderr.write(_one_line(exc))
        return 1
    except (OSError, MemoryError) as exc:
        sys.stderr.write(_one_line(exc))
        return 1
    except KeyboardInterrupt:
        sys.stderr.write(_one_line(interrupted_message("interrupted")))
        return 130
    except Terminated:
        sys.stderr.write(_one_line(interrupted_message("terminated")))
        return 143
    except Exception as exc:
        if not _is_usage_error(exc):
            raise
        return _usage_error(exc)
    finally:
        try:
            with signals_deferred():  # a second signal waits until the clean-up is done
                remove_leftovers()
        except (KeyboardInterrupt, Terminated):
            pass  # the command is ending already
        done_when_interrupted = interrupted_message("interrupted")
        forget_checked_outputs()
        for signum, old in previous.items():
            signal.signal(signum, old)
    if isinstance(code, int) and code == 130:
        # typer turns Ctrl-C inside a command into exit status 130; say why in one line.
        sys.stderr.write(_one_line(done_when_interrupted))
    return code if isinstance(code, int) else 0


if __name__ == "__main__":
    raise SystemExit(main())
