"""``thirdhand live RECORDING --task TASK.json``: follow a recording as a live stream.

Replays the recording at its real rate (``--speed``), runs the live loop on
every frame and prints each plan step as it is recognised (or undone), each
dropped stream, and the per-frame latency at the end; ``--json OUT`` writes the
report (``docs/explanation/live.md``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from thirdhand import jsontext
from thirdhand.config import ConfigOption
from thirdhand.errors import Terminated, ThirdhandError


def live_command(
    recording: Annotated[
        Path,
        typer.Argument(help="A recording in any format thirdhand reads, replayed as a stream."),
    ],
    task: Annotated[Path, typer.Option(help="Task file with a plan (thirdhand learn).")],
    speed: Annotated[
        float,
        typer.Option(
            help="Replay speed: 1 real time, 2 twice as fast, 0 as fast as possible "
            "(otherwise 0.01 to 1000)."
        ),
    ] = 1.0,
    json_out: Annotated[
        Path | None, typer.Option("--json", help="Write the report (steps, latency, assists).")
    ] = None,
    assist: Annotated[
        bool,
        typer.Option(
            help="Simulate the robot assist: fetch the next step's part to a hand-over pose."
        ),
    ] = False,
    record: Annotated[
        Path | None,
        typer.Option(
            help="Write the run as OUT.parquet (the stream, the robot's tool) and OUT.json "
            "(the arm's joints, the recognised steps, the assists); see docs/explanation/live.md."
        ),
    ] = None,
    force: Annotated[
        bool,
        typer.Option(help="Replace existing --json/--record files (kept as numbered .bak)."),
    ] = False,
    config: ConfigOption = None,
) -> None:
    """Follow a person through a task's plan, live: the step they are in, done, and next.

    Ctrl-C (or SIGTERM) stops the stream: the report of what was seen so far is
    printed and written (``--json``, ``--record``, marked ``interrupted``), then the
    command exits with 130 (143). Settings (``[live]`` of ``--config``): the
    segmentation model and the assist's arm, base and timing.
    """
    from thirdhand import io
    from thirdhand.config import load_settings
    from thirdhand.fileops import check_outputs, write_text
    from thirdhand.live.loop import LiveLoop, LiveOptions
    from thirdhand.live.mcap_source import McapSource, being_written
    from thirdhand.live.settings import LiveSettings
    from thirdhand.live.source import FrameLog, FrameSource, ReplaySource, check_speed
    from thirdhand.live.state import StateEvent
    from thirdhand.segment.model import resolve_model
    from thirdhand.task.store import load_task

    check_speed(speed)
    cfg = load_settings(config, "live", LiveSettings)
    outputs: list[tuple[str, Path | None]] = [("--json", json_out)]
    if record is not None:
        from thirdhand.execute.record import record_paths

        outputs += [("--record", p) for p in record_paths(record)]
    check_outputs(outputs, force=force, inputs=[recording, task, *([config] if config else [])])
    t = load_task(task)
    model = resolve_model(cfg.segment_model)
    source: FrameSource
    mcap: McapSource | None = None
    if being_written(recording):  # a recorder is appending to it: follow it as it grows
        if speed != 1.0:
            raise ThirdhandError(
                f"--speed: {recording} is being written; it is followed as it grows "
                "(leave --speed out)"
            )
        mcap = McapSource(recording, idle_s=cfg.follow_idle_s)
        source = log = FrameLog(mcap)
        t0 = 0.0
    else:
        log = None
        demo = io.load(recording)
        source = ReplaySource(demo, speed)
        t0 = float(demo.t[0])
    opts = LiveOptions(assist=cfg.assist_options() if assist else None)
    loop = LiveLoop(t, source.bodies, source.meta, model, opts, source_name=str(recording))
    console = Console(highlight=False, stderr=False, soft_wrap=True)

    def show(now: float, events: list[StateEvent]) -> None:
        for e in events:
            verb = "recognised" if e.kind == "formed" else "undone"
            console.print(
                f"{now - t0:8.2f} s  step {e.step + 1} {verb}: {e.constraint} "
                f"({e.parent} <- {e.child})"
            )

    interrupted: BaseException | None = None
    try:
        report = loop.run(source, on_events=show)
    except (KeyboardInterrupt, Terminated) as stop:
        # The loop closed its report where the stream stopped: say it, write it.
        interrupted, report = stop, loop.report
        console.print(f"interrupted: the report covers the stream up to {report.t1 - t0:.2f} s")
    if mcap is not None and mcap.unclosed:
        console.print(
            f"{recording}: the stream ended without the file's closing record (its recorder "
            "stopped); followed to the last complete message"
        )
    for a, b in report.dropped:
        console.print(f"dropped stream: no frame from {a - t0:.2f} s to {b - t0:.2f} s")
    doc = report.to_dict()
    lat = doc["latency_ms"]
    console.print(
        f"{doc['frames']} frames; update latency median {lat['median']} ms, p99 {lat['p99']} ms, "
        f"max {lat['max']} ms; done {doc['done']} of {len(t.plan)} steps; next {doc['next']}"
    )
    for a in doc["assists"]:
        console.print(
            f"assist step {a['step']}: {a['part']} from {a['start']:.2f} s, ready "
            f"{a['ready']}, end {a['end']}: {a['outcome']} ({a['collisions']} of "
            f"{a['checked']} configurations in collision)"
        )
    if speed > 0:
        late = doc["late_ms"]
        console.print(f"kept up: latest frame processed {late['max']} ms after it arrived")
    if json_out is not None:
        doc["recording"] = str(recording)
        doc["task"] = str(task)
        doc["speed"] = speed
        doc["interrupted"] = interrupted is not None
        write_text(json_out, jsontext.dumps(doc, what=str(json_out), indent=1) + "\n")
        console.print(f"wrote {json_out}")
    if record is not None:
        from thirdhand.live.record import write_live_record

        streamed = log.demonstration() if log is not None else demo
        replay, traj = write_live_record(streamed, report, loop.assist, record)
        console.print(f"wrote {replay} and {traj}")
    if interrupted is not None:
        raise interrupted
