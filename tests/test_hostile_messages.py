"""Messages are one clear line: interrupted commands say what they left, meshes are checked
before any C++ solver sees them, a path that is not a regular file is named as such.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from cli_helpers import call
from thirdhand import io
from thirdhand.synth import make_scene

SRC = str(Path(__file__).resolve().parents[1] / "src")


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("rec") / "chair.parquet"
    io.save(make_scene("chair", seed=0), path)
    return path


def test_interrupted_after_the_output_is_complete_says_so(
    recording: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Ctrl-C after the rename (while printing): the complete output is named, exit 130."""
    import thirdhand.cli as cli

    def interrupt(*_args: object, **_kwargs: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(cli.out, "print", interrupt)
    target = tmp_path / "o.csv"
    rc, _out, err = call(capsys, "convert", str(recording), str(target))
    assert rc == 130
    assert err == (
        f"thirdhand: error: interrupted after {target} was written complete; "
        "nothing else was written\n"
    )
    assert io.load(target).n_frames == io.load(recording).n_frames


def test_interrupted_before_the_output_leaves_nothing_and_says_so(
    recording: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """SIGTERM while the file is written: no output, no temporary, one line, exit 143."""
    import thirdhand.cli as cli
    from thirdhand.io import motive

    def terminated(*_args: object, **_kwargs: object) -> None:
        raise cli.Terminated

    monkeypatch.setattr(motive, "write", terminated)
    rc, _out, err = call(capsys, "convert", str(recording), str(tmp_path / "o.csv"))
    assert rc == 143
    assert err == "thirdhand: error: terminated; no output was written\n"
    assert list(tmp_path.iterdir()) == []


def test_sigterm_on_a_real_convert_is_one_line(recording: Path, tmp_path: Path) -> None:
    """A real signal while the output is written: one line; the output complete or absent."""
    env = {**os.environ, "PYTHONPATH": SRC}
    target = tmp_path / "o.mcap"
    proc = subprocess.Popen(
        [sys.executable, "-m", "thirdhand", "convert", str(recording), str(target)],
        stderr=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
        env=env,
    )
    while proc.poll() is None and not list(tmp_path.glob(".o.mcap.*")):
        time.sleep(0.01)  # until the writing starts (its temporary folder appears)
    proc.send_signal(signal.SIGTERM)
    _out, err = proc.communicate(timeout=120)
    lines = err.strip().splitlines()
    if proc.returncode == 0:
        assert lines == []
        return
    assert proc.returncode == 143, err
    assert len(lines) == 1 and "Traceback" not in err, err
    if target.exists():
        assert lines[0].endswith("was written complete; nothing else was written")
        assert io.load(target).n_frames > 0
    else:
        assert lines[0] == "thirdhand: error: terminated; no output was written"
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".o.mcap")]


def test_a_task_mesh_with_nan_vertices_is_one_line_before_any_solver(
    tmp_path: Path,
) -> None:
    """NaN vertices stop at the reader: no C++ "eigen: too many iterations" on stderr."""
    mesh = tmp_path / "part.stl"
    mesh.write_text(
        "solid p\nfacet normal 0 0 1\nouter loop\nvertex nan 0 0\nvertex 1 0 0\n"
        "vertex 0 1 0\nendloop\nendfacet\nendsolid p\n"
    )
    code = (
        "import sys\n"
        "from thirdhand.io.stl import stl_bounds\n"
        "from thirdhand.errors import ThirdhandError\n"
        "try:\n"
        f"    stl_bounds({str(mesh)!r})\n"
        "except ThirdhandError as exc:\n"
        "    print(exc, file=sys.stderr)\n"
    )
    proc = subprocess.run(
        [sys.executable, "-W", "error", "-c", code],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "PYTHONPATH": SRC},
    )
    assert proc.stderr.count("\n") == 1, proc.stderr
    assert "not a finite number" in proc.stderr and "eigen" not in proc.stderr


@pytest.mark.parametrize("kind", ["fifo", "folder", "device"])
def test_info_names_what_the_path_is(
    kind: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "x.parquet"
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "folder":
        path.mkdir()
    else:
        path = Path("/dev/zero")
    rc, _out, err = call(capsys, "info", str(path))
    assert rc == 1 and err.count("\n") == 1, err
    assert "no such file" not in err
    word = {"fifo": "FIFO", "folder": "folder", "device": "device"}[kind]
    assert word in err or "unrecognised" in err, err
