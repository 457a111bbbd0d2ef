"""Shared helper of the command-line tests: run ``thirdhand.cli.main`` in process."""

from __future__ import annotations

from pathlib import Path

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


def settings_file(folder: Path, command: str, **values: object) -> Path:
    """A ``--config`` file (TOML) whose ``[command]`` table holds ``values``."""
    import json

    path = folder / f"{command.replace('.', '_')}.settings.toml"
    lines = [f"[{command}]"] + [f"{k} = {json.dumps(v)}" for k, v in values.items()]
    path.write_text("\n".join(lines) + "\n")
    return path
