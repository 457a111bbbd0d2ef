"""Progress display: rich bars on a terminal, nothing when output is piped."""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn


def interactive() -> bool:
    """True when standard error is a terminal (progress is shown only then)."""
    return sys.stderr.isatty()


@contextmanager
def progress() -> Iterator[Progress]:
    """A rich ``Progress`` on stderr, disabled when stderr is not a terminal."""
    bar = Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        TimeElapsedColumn(),
        console=Console(stderr=True),
        disable=not interactive(),
        transient=True,
    )
    with bar:
        yield bar


@contextmanager
def stage_status(prefix: str = "learn") -> Iterator[Callable[[str], None]]:
    """A callable naming the stage that runs, shown as a spinner on a terminal.

    Yields
    ------
    callable
        ``say("primitives")`` shows ``learn: primitives…`` on stderr (when stderr
        is a terminal; otherwise it does nothing).
    """
    if not interactive():
        yield lambda _stage: None
        return
    console = Console(stderr=True)
    with console.status(f"{prefix}…") as status:
        yield lambda stage: status.update(f"{prefix}: {stage}…")
