"""``thirdhand review TASK.json [--demo REC...] [--replay RUN...] [--port N] [--config FILE]``.

The review GUI.

Mounted as a top-level command by :mod:`thirdhand.cli` (``COMMANDS``).
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated, Any

import typer

from thirdhand.config import ConfigOption


def review_command(
    task: Annotated[Path, typer.Argument(help="Task file (thirdhand.task/2) to review.")],
    demo: Annotated[
        list[Path] | None,
        typer.Option("--demo", help="A recording to play back on the timeline (repeatable)."),
    ] = None,
    port: Annotated[int, typer.Option(help="Port (the next free one if busy).")] = 8080,
    host: Annotated[
        str,
        typer.Option(
            help="Address to bind; 0.0.0.0 serves the whole network. Beyond loopback an "
            "access token is asked, carried by the URL printed at start."
        ),
    ] = "127.0.0.1",
    replay: Annotated[
        list[Path] | None,
        typer.Option(
            "--replay",
            help="An execution record of this task (thirdhand execute --record OUT) to play "
            "on the same scene (repeatable).",
        ),
    ] = None,
    config: ConfigOption = None,
) -> None:
    """Open a task in the review GUI (a local web app): see, animate and correct it.

    Serves until Ctrl-C (or SIGTERM, whatever signal disposition the process
    inherited) or the GUI's Quit button (which asks first when there are unsaved
    changes). Settings (``[review]`` of ``--config``): extra mesh folders, light rendering.
    """
    from thirdhand import options
    from thirdhand.config import load_settings
    from thirdhand.review.settings import ReviewSettings

    cfg = load_settings(config, "review", ReviewSettings)

    options.port(port)
    options.host(host)
    from thirdhand.review.app import ReviewApp

    demos = _task_recordings(task, list(demo or []))
    app = ReviewApp(
        task,
        demos=demos,
        host=host,
        port=port,
        meshes=[Path(m) for m in cfg.meshes],
        light_rendering=cfg.light,
        replays=list(replay or []),
    )
    # Ctrl-C (SIGINT) anywhere from here is the normal way to stop: exit 0. SIGTERM
    # ends with status 143 (thirdhand.cli.main); both stop the server in ``finally``.
    try:
        url = app.start()
        sys.stdout.write(f"thirdhand review: {task} at {url} (Ctrl-C to stop)\n")
        sys.stdout.flush()
        while not app.quit_requested.wait(0.5):
            pass
    except KeyboardInterrupt:
        if app.session.dirty:
            sys.stderr.write("thirdhand review: stopped with unsaved changes\n")
    finally:
        app.stop()


def _task_recordings(task: Path, paths: list[Path]) -> list[Any]:
    """The ``--demo`` recordings, each refused in one line if it is another task's."""
    from thirdhand import io
    from thirdhand.errors import ThirdhandError
    from thirdhand.task.store import load_task

    if not paths:
        return []
    t = load_task(task)
    out = []
    for p in paths:
        d = io.load(p)
        problem = t.foreign_recording_problem(d.body_names)
        if problem is not None:
            raise ThirdhandError(f"--demo {p}: {problem}")
        out.append(d)
    return out
