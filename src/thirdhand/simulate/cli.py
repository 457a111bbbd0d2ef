"""``thirdhand simulate TASK.json``: run the plan in MuJoCo and say per step whether it works.

Plans the task as ``thirdhand execute`` does (or reads a run recorded with
``execute --record OUT`` through ``--run OUT.json``), then simulates it with
contacts: the part held by friction, fastened to its parent when it reaches its
goal, the assembly resting at the end. Prints a table per step; ``--json`` writes
the measures, ``--video`` an MP4 rendered offscreen. Exits 1 when a step is not
done. Needs the ``sim`` extra (``pip install 'thirdhand[sim]'``).
"""

from __future__ import annotations

import importlib.util
import time
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.table import Table

from thirdhand import jsontext
from thirdhand.config import ConfigOption, load_settings
from thirdhand.errors import ThirdhandError
from thirdhand.simulate.settings import SimulateSettings

#: Packages of the ``sim`` extra.
SIM_PACKAGES = ("mujoco", "coacd")


def check_extra() -> None:
    """Raise one line when the ``sim`` extra is not installed."""
    missing = [p for p in SIM_PACKAGES if importlib.util.find_spec(p) is None]
    if missing:
        raise ThirdhandError(
            f"'thirdhand simulate' needs {' and '.join(missing)}, which "
            f"{'is' if len(missing) == 1 else 'are'} not installed: pip install 'thirdhand[sim]'"
        )


def simulate_command(
    task: Annotated[Path, typer.Argument(help="Task file (thirdhand.task/2 JSON).")],
    run: Annotated[
        Path | None,
        typer.Option(help="A run recorded by 'thirdhand execute --record OUT' (OUT.json)."),
    ] = None,
    json_out: Annotated[
        Path | None, typer.Option("--json", help="Write the per-step measures (JSON).")
    ] = None,
    video: Annotated[Path | None, typer.Option(help="Write a video of the run (MP4).")] = None,
    force: Annotated[
        bool, typer.Option(help="Replace existing outputs (kept as numbered .bak).")
    ] = False,
    config: ConfigOption = None,
) -> None:
    """Run a task's plan in a physics simulator (MuJoCo) and say per step whether it works.

    Settings (``[simulate]`` of ``--config``; ``thirdhand config simulate``): grasp
    mode, collision geometry, density, friction, gripper force, timing, tolerances,
    servo gains, video size.
    """
    check_extra()
    from thirdhand.simulate.video import choose_backend

    choose_backend()  # before anything imports MuJoCo (the planner's robot check does)
    from thirdhand import options
    from thirdhand.fileops import atomic_output, atomic_write_bytes, check_output
    from thirdhand.task.store import load_task

    cfg = load_settings(config, "simulate", SimulateSettings)
    robot, seed = cfg.robot, cfg.seed
    options.seed(seed)
    for folder in cfg.meshes:
        if not Path(folder).is_dir():
            raise ThirdhandError(f"[simulate] meshes {folder}: not a folder of part meshes")
    inputs = [task, *([run] if run else []), *([config] if config else [])]
    if json_out is not None:
        check_output(json_out, force=force, inputs=inputs)
    if video is not None:
        check_output(video, force=force, inputs=inputs)
        if video.suffix.lower() != ".mp4":
            raise ThirdhandError(f"--video {video}: expected a .mp4 file")
    console = Console()
    t = load_task(task)
    search = list(cfg.meshes)
    if run is not None:
        from thirdhand.simulate.plan import from_record

        if robot is not None:
            raise ThirdhandError("[simulate] robot: a recorded run (--run) names its robot")
        plan = from_record(run, t)
        source = f"recorded: {run}"
    else:
        plan = _plan(t, task, robot, seed, search, console, cfg.rate)
        source = "planned"
    from thirdhand.simulate.run import simulate_run

    writer: Any = None
    note: str | None = None
    frames = 0
    wrote_video: str | None = None
    with _video_target(video, atomic_output) as tmp:

        def make_sink(model: Any) -> Any:
            nonlocal writer, note
            if tmp is None:
                return None
            from thirdhand.simulate.video import cell_lookat, open_video

            lookat = cell_lookat(plan.robot_base, plan.start.get(_base(t), None))
            writer, note = open_video(
                model, tmp, fps=cfg.fps, width=cfg.width, height=cfg.height,
                lookat=lookat, distance=2.0,
            )  # fmt: skip
            return writer

        t0 = time.perf_counter()
        try:
            sim = simulate_run(t, plan, cfg, task_path=task, search=search, make_sink=make_sink)
        finally:
            if writer is not None:
                writer.close()
        if writer is not None and tmp is not None:
            from thirdhand.simulate.video import count_frames

            frames = count_frames(tmp)
            if frames == 0:
                raise ThirdhandError(f"--video {video}: the encoder wrote no frame")
            wrote_video = str(video)
        elif tmp is not None:
            # nothing to rename: leave the target as it was
            raise _NoVideo(note or "no renderer")
    wall = time.perf_counter() - t0
    _print(console, sim, t0=wall)
    for n in sim.built.notes:
        console.print(f"note: {n}")
    if note is not None:
        console.print(f"video refused: {note}")
    elif wrote_video is not None:
        console.print(f"wrote {wrote_video} ({frames} frames)")
    if json_out is not None:
        from thirdhand.simulate.report import simulation_document

        doc = simulation_document(
            sim, cfg, task=str(task), robot=plan.robot, source=source, video=wrote_video,
            video_note=note, frames=frames,
        )  # fmt: skip
        text = jsontext.dumps(doc, what=str(json_out), indent=1)
        atomic_write_bytes(json_out, (text + "\n").encode())
        console.print(f"wrote {json_out}")
    bad = [o for o in sorted(sim.result.steps, key=lambda o: o.index) if o.status != "done"]
    if bad:
        what = ", ".join(f"{o.constraint}: {o.status}" for o in bad[:5])
        raise ThirdhandError(
            f"{task}: {len(bad)} of {len(sim.result.steps)} steps not done in simulation ({what})"
        )


class _NoVideo(Exception):
    """No renderer: the temporary video is dropped (the run is still reported)."""


class _video_target:
    """``atomic_output(video)`` when a video is asked for; a refused video leaves no file."""

    def __init__(self, video: Path | None, atomic_output: Any) -> None:
        self.cm = atomic_output(video) if video is not None else None

    def __enter__(self) -> Path | None:
        return self.cm.__enter__() if self.cm is not None else None

    def __exit__(self, kind: Any, exc: Any, tb: Any) -> bool:
        if self.cm is None:
            return False
        if isinstance(exc, _NoVideo):
            self.cm.__exit__(kind, exc, tb)
            return True
        return bool(self.cm.__exit__(kind, exc, tb))


def _base(t: Any) -> str:
    from thirdhand.execute.layout import base_part

    return base_part(t)


def _plan(
    t: Any, task: Path, robot: str | None, seed: int, search: list[str], console: Console,
    rate: float,
) -> Any:  # fmt: skip
    """Plan the task offline as ``thirdhand execute`` does (:func:`~.plan.plan_offline`)."""
    from thirdhand.simulate.plan import plan_offline

    with console.status("planning the run (thirdhand execute)"):
        return plan_offline(t, task_path=task, robot=robot, seed=seed, search=search, rate=rate)


def _fmt(v: float | None, digits: int = 1) -> str:
    return "–" if v is None else f"{v:.{digits}f}"


def _print(console: Console, sim: Any, *, t0: float) -> None:
    r = sim.result
    table = Table(title=f"simulated run ({r.grasp} grasp)")
    for col in ("step", "action", "grasp", "pos mm", "angle °", "slip mm", "force N",
                "tracking °", "status"):  # fmt: skip
        table.add_column(col)
    for o in sorted(r.steps, key=lambda o: o.index):
        colour = "[green]" if o.status == "done" else "[red]"
        table.add_row(
            str(o.index), f"{o.child} → {o.parent} ({o.constraint})", o.grasp or "",
            _fmt(o.position_error_mm), _fmt(o.angle_error_deg), _fmt(o.slip_mm),
            _fmt(o.peak_force_n, 0), _fmt(o.tracking_error_deg, 2), colour + o.status,
        )  # fmt: skip
    console.print(table)
    tm = sim.timings
    console.print(
        f"after the last step: largest part displacement {r.rest_displacement_mm:.2f} mm"
        f"{f' ({r.rest_part})' if r.rest_part else ''}"
    )
    console.print(
        f"simulated {r.sim_time_s:.1f} s in {tm['stepping']:.1f} s of stepping "
        f"({r.sim_time_s / max(tm['stepping'], 1e-9):.1f}× real time); decomposition "
        f"{tm['decomposition']:.1f} s, model {tm['build']:.1f} s, rendering {tm['rendering']:.1f} s"
    )
