"""Progress display: rich bars on a terminal, nothing when output is piped."""

from __future__ import annotations

import sys
from collections.abc import Iterator
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
