"""The command line: one-line errors, no tracebacks, no silent overwrite."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from cli_helpers import call
from thirdhand import BodyInfo, Demonstration, io, se3


def run(*args: str) -> tuple[int, str, str]:
    proc = subprocess.run(
        [sys.executable, "-m", "thirdhand", *args], capture_output=True, text=True, check=False
    )
    return proc.returncode, proc.stdout, proc.stderr


@pytest.fixture
def small_demo(tmp_path: Path) -> Path:
    rng = np.random.default_rng(1)
    n = 30
    p = rng.normal(size=(n, 3))
    p[3:6] = np.nan
    demo = Demonstration(
        np.arange(n) / 120.0,
        [BodyInfo("seat"), BodyInfo("rh_thumb", "finger", hand="right", hand_body="rh")],
        {"seat": p, "rh_thumb": rng.normal(size=(n, 3))},
        {"seat": se3.random_quat(rng, n), "rh_thumb": se3.random_quat(rng, n)},
    )
    path = tmp_path / "demo.parquet"
    io.save(demo, path)
    return path


def test_help_lists_commands() -> None:
    rc, out, _ = run("--help")
    assert rc == 0
    for cmd in ("synth", "info", "convert", "demo"):
        assert cmd in out


def test_info_json(capsys: pytest.CaptureFixture[str], small_demo: Path) -> None:
    rc, out, _ = call(capsys, "info", str(small_demo), "--json")
    assert rc == 0
    info = json.loads(out)
    assert info["n_bodies"] == 2 and info["format"] == "native"
    assert info["rate_hz"] == pytest.approx(120.0)
    assert info["bodies"][0]["missing"] == pytest.approx(0.1)


@pytest.mark.parametrize(
    ("content", "match"),
    [
        (None, "no such file"),
        (b"", "unrecognised recording format"),
        (b"\x00\x01garbage", "unrecognised"),
    ],
)
def test_bad_input_is_one_line_without_traceback(
    tmp_path: Path, content: bytes | None, match: str
) -> None:
    path = tmp_path / "bad.xyz"
    if content is not None:
        path.write_bytes(content)
    rc, _, err = run("info", str(path))
    assert rc != 0
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("thirdhand: error: ") and match in lines[0]
    assert str(path) in lines[0]


@pytest.mark.parametrize(
    ("name", "content", "match"),
    [
        ("wiping.mat", b"MATLAB 5.0 MAT-file", "read by `thirdhand primitives library`"),
        ("track.npy", b"\x93NUMPY", "read by `thirdhand primitives library`"),
        ("track.csv", b"0,0.1,0.2,0.3\n0.01,0.1,0.2,0.3\n", "not a Motive CSV export"),
    ],
)
def test_tracks_given_as_recordings_name_the_command_that_reads_them(
    tmp_path: Path, name: str, content: bytes, match: str
) -> None:
    path = tmp_path / name
    path.write_bytes(content)
    rc, _, err = run("info", str(path))
    lines = err.strip().splitlines()
    assert rc != 0 and len(lines) == 1 and match in lines[0]


def test_convert_refuses_overwrite_and_keeps_backup(
    capsys: pytest.CaptureFixture[str], small_demo: Path, tmp_path: Path
) -> None:
    target = tmp_path / "copy.parquet"
    assert call(capsys, "convert", str(small_demo), str(target))[0] == 0
    assert io.load(target).equals(io.load(small_demo))
    before = target.read_bytes()
    rc, _, err = call(capsys, "convert", str(small_demo), str(target))
    assert rc != 0 and "--force" in err
    assert call(capsys, "convert", str(small_demo), str(target), "--force")[0] == 0
    assert (tmp_path / "copy.parquet.bak").read_bytes() == before


def test_info_on_real_3rdhand_excerpt(
    capsys: pytest.CaptureFixture[str], shared_data: Path
) -> None:
    rc, out, _ = call(
        capsys, "info", str(shared_data / "3rdhand" / "toolbox_coop_4_excerpt"), "--json"
    )
    assert rc == 0
    info = json.loads(out)
    assert info["format"] == "mlr"
    assert info["n_bodies"] == 11  # sensor row 8 is unused
    assert info["rate_hz"] == pytest.approx(100.0, rel=0.01)
    missing = [b["missing"] for b in info["bodies"]]
    assert all(0.0 < m < 1.0 for m in missing)


# -- start-up: stage commands are imported only when they run -------------

#: Heavy modules no stage-free command needs (``thirdhand --help`` must not import them).
HEAVY = ("scipy", "numba", "pinocchio", "coal", "ompl", "cma", "matplotlib", "viser", "pyarrow")


def test_help_imports_no_stage_dependency() -> None:
    import subprocess
    import sys

    code = (
        "import sys, contextlib, io\n"
        "from thirdhand.cli import main\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    status = main(['--help'])\n"
        f"heavy = [m for m in {HEAVY!r} if m in sys.modules]\n"
        "stages = [m for m in sys.modules\n"
        "          if m.startswith('thirdhand.') and m.endswith('cli') and m != 'thirdhand.cli']\n"
        "print(status, heavy, stages)\n"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert run.stdout.strip() == "0 [] []", run.stdout + run.stderr


def test_every_lazy_command_loads_with_its_listed_help() -> None:
    from thirdhand.cli import LAZY, load_command

    for name, entry in LAZY.items():
        command = load_command(name)
        assert command.name == name
        # The one line shown by ``thirdhand --help`` is the start of the command's own help.
        assert " ".join((command.help or "").split()).startswith(entry.help), name


def test_help_lists_every_stage_command(capsys: pytest.CaptureFixture[str]) -> None:
    from thirdhand.cli import LAZY

    status, text, _ = call(capsys, "--help")
    assert status == 0
    for name in LAZY:
        assert name in text


def test_a_missing_dependency_is_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from thirdhand import cli

    (tmp_path / "stage_needing_extra.py").write_text("import not_installed_pkg_xyz\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setitem(
        cli.LAZY, "needy", cli.LazyCommand("stage_needing_extra", "app", "Needs an extra.")
    )
    status, out, err = call(capsys, "needy", "--help")
    assert status == 1 and out == ""
    assert err == (
        "thirdhand: error: 'thirdhand needy' needs the Python package 'not_installed_pkg_xyz', "
        "which is not installed; install thirdhand with its extras: pip install 'thirdhand[dev]'\n"
    )
