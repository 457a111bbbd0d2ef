"""Shared helper of the research command-line tests: run ``research.cli.main`` in process."""

from __future__ import annotations

import pytest

from research.cli import main


def call(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    """Exit code, stdout and stderr of ``python -m research ARGS…`` run in this process."""
    rc = main(list(args))
    cap = capsys.readouterr()
    return rc, cap.out, cap.err
