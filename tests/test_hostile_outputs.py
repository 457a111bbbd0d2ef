"""Two outputs of one command never name the same file (``fileops.check_outputs``).

Every command that writes several files checks each output against every other
output and every input before it reads anything: the same spelling, ``./x``, a
link to it. One line, exit status 1, nothing written and the inputs untouched.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from cli_helpers import call
from thirdhand import io
from thirdhand.errors import OutputError
from thirdhand.fileops import check_outputs
from thirdhand.synth import make_scene


@pytest.fixture(scope="module")
def recordings(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    folder = tmp_path_factory.mktemp("recs")
    a, b = folder / "a.parquet", folder / "b.parquet"
    io.save(make_scene("chair", seed=0), a)
    io.save(make_scene("chair", seed=1), b)
    return a, b


def _spellings(folder: Path, name: str) -> list[tuple[str, str]]:
    """Pairs of spellings of one file: the same, ``./`` and a symbolic link."""
    link = folder / f"link-{name}"
    os.symlink(folder / name, link)
    return [
        (str(folder / name), str(folder / name)),
        (str(folder / name), str(folder / "." / name)),
        (str(folder / name), str(link)),
    ]


# Each command with several outputs: argv with OUT1 and OUT2 the two outputs.
COMMANDS: dict[str, tuple[str, list[str]]] = {
    "merge -o --report": ("m.parquet", ["merge", "{a}", "{b}", "-o", "{o1}", "--report", "{o2}"]),
    "primitives library -o --plot": (
        "x.png",
        ["primitives", "library", "{a}", "--body", "rh_index", "-o", "{o1}", "--plot", "{o2}"],
    ),
    "segment run --json --plot": (
        "p.png",
        ["segment", "run", "{a}", "--json", "{o1}", "--plot", "{o2}"],
    ),
    "headpose --json --overlay": (
        "h.png",
        ["headpose", "{a}", "--json", "{o1}", "--overlay", "{o2}"],
    ),
    "live --json --record": (
        "r.json",
        ["live", "{a}", "--task", "{b}", "--json", "{o1}", "--record", "{o2}"],
    ),
    "learn -o --report": ("rep/index.html", ["learn", "{a}", "-o", "{o1}", "--report", "{o2}"]),
}


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_two_outputs_naming_one_file_are_refused(
    command: str,
    recordings: tuple[Path, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    name, argv = COMMANDS[command]
    a, b = recordings
    before = (a.read_bytes(), b.read_bytes())
    (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
    pairs = _spellings(tmp_path, name) if "/" not in name else [(str(tmp_path / name),) * 2]
    for first, second in pairs:
        if command == "learn -o --report":
            second = str(Path(second).parent)
        elif command == "live --json --record":
            second = second.removesuffix(".json")
        args = [x.format(a=a, b=b, o1=first, o2=second) if "{" in x else x for x in argv]
        rc, _out, err = call(capsys, *args)
        assert rc == 1, (command, err)
        assert err.count("\n") == 1 and "name the same file" in err, err
    assert not (tmp_path / name).exists()
    assert (a.read_bytes(), b.read_bytes()) == before


def test_convert_pddl_and_its_domain_as_one_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The domain beside a PDDL problem may not be the problem itself (a link)."""
    task = tmp_path / "t.json"
    task.write_text("{}")
    target = tmp_path / "p.pddl"
    os.symlink(target, tmp_path / "p.domain.pddl")
    rc, _out, err = call(capsys, "convert", str(task), str(target))
    assert rc == 1
    assert err.count("\n") == 1 and "name the same file" in err, err


def test_an_output_may_be_no_input(tmp_path: Path) -> None:
    inp = tmp_path / "in.parquet"
    inp.write_bytes(b"x")
    with pytest.raises(OutputError, match="input"):
        check_outputs([("-o", tmp_path / "x.json"), ("--report", inp)], inputs=[inp])
    assert inp.read_bytes() == b"x"


def test_same_inode_under_two_names(tmp_path: Path) -> None:
    """A hard link is the same file: refused even with --force."""
    f = tmp_path / "a.json"
    f.write_text("{}")
    os.link(f, tmp_path / "b.json")
    with pytest.raises(OutputError, match="name the same file"):
        check_outputs([("-o", f), ("--report", tmp_path / "b.json")], force=True)


def test_outputs_not_asked_for_are_skipped(tmp_path: Path) -> None:
    out = check_outputs([("-o", tmp_path / "a.json"), ("--report", None)])
    assert out == [tmp_path / "a.json"]
