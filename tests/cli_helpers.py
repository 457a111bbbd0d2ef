"""Shared helper of the command-line tests: run ``thirdhand.cli.main`` in process."""

from __future__ import annotations

import pytest

from thirdhand.cli import main


def call(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    """Exit code, stdout and stderr of ``thirdhand ARGS…`` run in this process."""
    try:
        rc = main(list(args))
    except SystemExit as exc:
        rc = int(exc.code or 0)
    cap = capsys.readouterr()
    return rc, cap.out, cap.err
