"""``thirdhand live RECORDING --task TASK.json``: follow a recording as a live stream.

Replays the recording at its real rate (``--speed``), runs the live loop on
every frame and prints each plan step as it is recognised (or undone), each
dropped stream, and the per-frame latency at the end; ``--json OUT`` writes the
report (``docs/live.md``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from thirdhand import jsontext
from thirdhand.errors import ThirdhandError


def live_command(
    recording: Annotated[
        Path,
        typer.Argument(help="A recording in any format thirdhand reads, replayed as a stream."),
    ],
    task: Annotated[Path, typer.Option(help="Task file with a plan (thirdhand learn).")],
    speed: Annotated[
        float,
        typer.Option(help="Replay speed: 1 real time, 2 twice as fast, 0 as fast as possible."),
    ] = 1.0,
    json_out: Annotated[
        Path | None, typer.Option("--json", help="Write the report (steps, latency, assists).")
    ] = None,
    segment_model: Annotated[
        str | None,
        typer.Option(help="Segmentation model JSON or built-in name (default: the shipped one)."),
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
            "(the arm's joints, the recognised steps, the assists); see docs/live.md."
        ),
    ] = None,
    force: Annotated[
        bool,
        typer.Option(help="Replace existing --json/--record files (kept as numbered .bak)."),
    ] = False,
) -> None:
    """Follow a person through a task's plan, live: the step they are in, done, and next."""
    from thirdhand import io
    from thirdhand.fileops import check_output, write_text
    from thirdhand.live.assist import AssistOptions
    from thirdhand.live.loop import LiveLoop, LiveOptions
    from thirdhand.live.mcap_source import being_written
    from thirdhand.live.source import FrameLog, FrameSource, ReplaySource, check_speed
    from thirdhand.live.state import StateEvent
    from thirdhand.segment.model import resolve_model
    from thirdhand.task.store import load_task

    check_speed(speed)
    if json_out is not None:
        check_output(json_out, force=force, inputs=[recording, task])
    if record is not None:
        from thirdhand.execute.record import record_paths

        targets = record_paths(record)
        if json_out is not None and json_out.resolve() in {p.resolve() for p in targets}:
            raise ThirdhandError(f"--record {record}: would write over --json {json_out}")
        for target in targets:
            check_output(target, force=force, inputs=[recording, task])
    t = load_task(task)
    model = resolve_model(segment_model)
    source: FrameSource
    if being_written(recording):  # a recorder is appending to it: follow it as it grows
        from thirdhand.live.mcap_source import McapSource

        if speed != 1.0:
            raise ThirdhandError(
                f"--speed: {recording} is being written; it is followed as it grows "
                "(leave --speed out)"
            )
        source = log = FrameLog(McapSource(recording))
        t0 = 0.0
    else:
        log = None
        demo = io.load(recording)
        source = ReplaySource(demo, speed)
        t0 = float(demo.t[0])
    opts = LiveOptions(assist=AssistOptions() if assist else None)
    loop = LiveLoop(t, source.bodies, source.meta, model, opts, source_name=str(recording))
    console = Console(highlight=False, stderr=False)

    def show(now: float, events: list[StateEvent]) -> None:
        for e in events:
            verb = "recognised" if e.kind == "formed" else "undone"
            console.print(
                f"{now - t0:8.2f} s  step {e.step + 1} {verb}: {e.constraint} "
                f"({e.parent} <- {e.child})"
            )

    report = loop.run(source, on_events=show)
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
        write_text(json_out, jsontext.dumps(doc, what=str(json_out), indent=1) + "\n")
        console.print(f"wrote {json_out}")
    if record is not None:
        from thirdhand.live.record import write_live_record

        streamed = log.demonstration() if log is not None else demo
        replay, traj = write_live_record(streamed, report, loop.assist, record)
        console.print(f"wrote {replay} and {traj}")
