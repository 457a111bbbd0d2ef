"""Perception commands: ``headpose VIDEO``, ``gestures REC``, ``attention REC``.

The module's ``app`` mounts them as ``thirdhand perception <command>``; the
functions :func:`headpose_command`, :func:`gestures_command` and
:func:`attention_command` can also be registered as top-level commands
(``app.command("headpose")(headpose_command)``).
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated, Any, NoReturn

import numpy as np
import typer
from rich.console import Console

from thirdhand import jsontext
from thirdhand.config import ConfigOption, load_settings
from thirdhand.errors import ThirdhandError
from thirdhand.perception.settings import AttentionSettings, GestureSettings, HeadposeSettings

app = typer.Typer(
    help="Head pose from video; attention and pointing gestures from motion capture.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
out = Console(highlight=False, soft_wrap=True)


def _fail(message: str) -> NoReturn:
    sys.stderr.write(f"thirdhand: error: {message}\n")
    raise typer.Exit(1)


def _check_outputs(
    outputs: list[tuple[str, Path | None]], force: bool, inputs: list[Path | None]
) -> None:
    """Refuse outputs naming one file, an input, or an existing file without ``--force``.

    ``-`` (standard output) is no file.
    """
    from thirdhand.fileops import check_outputs

    files = [(name, p) for name, p in outputs if p is not None and str(p) != "-"]
    check_outputs(files, force=force, inputs=inputs)


def _write_json(data: Any, path: Path | None, force: bool) -> None:
    """``-`` prints to stdout; a path is written atomically, an old file kept as a numbered .bak."""
    if path is None:
        return
    text = jsontext.dumps(data, what="the perception report", indent=2)
    if str(path) == "-":
        sys.stdout.write(text + "\n")
        return
    from thirdhand.fileops import write_bytes

    write_bytes(path, text.encode())


def _load(path: Path) -> Any:
    from thirdhand import io

    return io.load(path)


JsonOpt = Annotated[
    Path | None,
    typer.Option("--json", help="Write the results as JSON to this file ('-': stdout)."),
]
ForceOpt = Annotated[bool, typer.Option(help="Replace existing outputs (kept as numbered .bak).")]
TaskOpt = Annotated[
    Path | None,
    typer.Option("--task", help="Task file whose stages.perception block receives the events."),
]


@app.command("headpose")
def headpose_command(
    video: Annotated[Path, typer.Argument(help="Video (or image) with a face.")],
    json_out: JsonOpt = None,
    overlay: Annotated[
        Path | None,
        typer.Option("--overlay", help="Annotated video (.mp4, .avi) or image strip (.png)."),
    ] = None,
    force: ForceOpt = False,
    config: ConfigOption = None,
) -> None:
    """Per-frame head yaw, pitch and roll (degrees from a calibration frame) of a video.

    Settings (``[headpose]`` of ``--config``): ``calibrate``, ``start``, ``stop``, ``step``,
    ``focal``, ``static``.
    """
    from thirdhand.perception.track import track_head

    try:
        cfg = load_settings(config, "headpose", HeadposeSettings)
        _check_outputs([("--json", json_out), ("--overlay", overlay)], force, [video, config])
        track = track_head(
            video, calibrate=cfg.calibrate, start=cfg.start, stop=cfg.stop, step=cfg.step,
            static=cfg.static, focal_px=cfg.focal,
        )  # fmt: skip
        _write_json(track.to_dict(), json_out, force)
        if track.n_found == 0:
            raise ThirdhandError(f"{video}: no face found in any of the {len(track)} frames read")
        ang = track.angles
        jump = track.max_jump()
        quiet = json_out is not None and str(json_out) == "-"
        if not quiet:
            out.print(
                f"{video}: face in {track.n_found} of {len(track)} frames; calibration frame "
                f"{track.frame[track.calibration]}; max frame-to-frame jump "
                f"{jump['rotation']:.2f}° (at frame {jump['frame']})"
            )
            for k, name in enumerate(("yaw", "pitch", "roll")):
                out.print(
                    f"  {name:5s} {np.nanmin(ang[:, k]):+7.2f}° … {np.nanmax(ang[:, k]):+7.2f}°"
                )
        if overlay is not None:
            from thirdhand.perception.overlay import render_overlay

            render_overlay(track, overlay)
            if not quiet:
                out.print(f"overlay → {overlay}")
    except ThirdhandError as exc:
        _fail(str(exc))


def _save_events(task_path: Path, **events: Any) -> None:
    from thirdhand.perception.events import add_perception_events
    from thirdhand.taskfile import load_task, save_task

    task = load_task(task_path)
    save_task(add_perception_events(task, **events), task_path)


@app.command("gestures")
def gestures_command(
    recording: Annotated[Path, typer.Argument(help="Recording with tracked fingertips.")],
    json_out: JsonOpt = None,
    task: TaskOpt = None,
    force: ForceOpt = False,
    config: ConfigOption = None,
) -> None:
    """Pointing gestures pointed(hand, object, t0, t1) from thumb, index and middle fingertips.

    Settings (``[gestures]`` of ``--config``): ``ray``, ``dwell``, ``cone``.
    """
    from thirdhand.perception.pointing import detect_pointing

    try:
        cfg = load_settings(config, "gestures", GestureSettings)
        ray, dwell, cone = cfg.ray, cfg.dwell, cfg.cone
        _check_outputs([("--json", json_out)], force, [recording, task, config])
        demo = _load(recording)
        events = detect_pointing(demo, ray=ray, dwell=dwell, cone_deg=cone)
        data = {
            "source": str(recording),
            "parameters": {"ray": ray, "dwell": dwell, "cone_deg": cone},
            "pointing": [e.to_dict() for e in events],
        }
        _write_json(data, json_out, force)
        if task is not None:
            _save_events(
                task, pointing=events, source=str(recording), parameters=data["parameters"]
            )
    except ThirdhandError as exc:
        _fail(str(exc))
    if json_out is not None and str(json_out) == "-":
        return
    out.print(f"{recording}: {len(events)} pointing gestures")
    for e in events:
        target = e.object if e.object is not None else "(nothing in the cone)"
        angle = f", {e.angle_deg:.1f}° off" if e.object is not None else ""
        out.print(f"  pointed({e.hand}, {target}, {e.t0:.2f}, {e.t1:.2f})  [{e.ray} ray{angle}]")
    if task is not None:
        out.print(f"events → {task} (stages.perception)")


@app.command("attention")
def attention_command(
    recording: Annotated[Path, typer.Argument(help="Recording with a tracked head.")],
    json_out: JsonOpt = None,
    head: Annotated[str | None, typer.Option(help="Head body (default: the only one).")] = None,
    task: TaskOpt = None,
    force: ForceOpt = False,
    config: ConfigOption = None,
) -> None:
    """Which object a motion-captured head attends to over time, as intervals.

    Settings (``[attention]`` of ``--config``): ``forward``, ``cone``, ``hysteresis``,
    ``min_duration``.
    """
    from thirdhand.perception.attention import attended_objects

    try:
        cfg = load_settings(config, "attention", AttentionSettings)
        axis = list(cfg.forward)
        cone, hysteresis, min_duration = cfg.cone, cfg.hysteresis, cfg.min_duration
        _check_outputs([("--json", json_out)], force, [recording, task, config])
        demo = _load(recording)
        if head is not None and head in demo and demo.info(head).kind != "head":
            heads = ", ".join(demo.bodies_of_kind("head")) or "none"
            raise ThirdhandError(
                f"--head {head}: is a {demo.info(head).kind}, not a head (heads: {heads})"
            )
        intervals = attended_objects(
            demo, head, forward=axis, cone_deg=cone, hysteresis_deg=hysteresis,
            min_duration=min_duration,
        )  # fmt: skip
        params = {"forward": axis, "cone_deg": cone, "hysteresis_deg": hysteresis,
                  "min_duration": min_duration}  # fmt: skip
        data = {
            "source": str(recording),
            "parameters": params,
            "attention": [
                {"object": a.object, "t0": a.t0, "t1": a.t1, "angle_deg": a.angle_deg}
                for a in intervals
            ],
        }
        _write_json(data, json_out, force)
        if task is not None:
            _save_events(task, attention=intervals, source=str(recording), parameters=params)
    except ThirdhandError as exc:
        _fail(str(exc))
    if json_out is not None and str(json_out) == "-":
        return
    out.print(f"{recording}: {len(intervals)} attention intervals")
    for a in intervals:
        out.print(f"  attends({a.object}, {a.t0:.2f}, {a.t1:.2f})  [{a.angle_deg:.1f}° off]")
