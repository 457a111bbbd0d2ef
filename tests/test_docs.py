"""The documentation cannot rot: its commands and snippets run, its reference covers the code.

- The shell commands of the getting-started page and of the first-session tutorial
  are taken from the Markdown itself and run, on the demo's output, in a temporary
  folder (``make demo`` becomes ``thirdhand demo -o out/chair``; viewers, servers and
  ``make test`` are left out: they do not end by themselves).
- Every Python snippet under ``docs/`` runs, in the same kind of folder (the snippets
  read ``out/chair/task.json``); the README's runs in tests/test_api.py.
- The generated reference names every leaf command, every settings table and every
  stage block of the task file (the pages the site builds, from the same functions).
- The README is at most 150 lines, the hand-written Markdown under ``docs/`` at most
  5,000, and no tracked file names a numbered work session; README and docs name no
  issue number and no commit hash.
"""

from __future__ import annotations

import os
import re
import runpy
import shlex
import shutil
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
README = ROOT / "README.md"
DATA = ROOT.parent / "shared" / "data"
MESHES = DATA / "3rdhand" / "meshes"
#: Pages whose shell commands run in the tests (the user's first hour).
RUN_PAGES = ("getting-started.md", "tutorials/first-session.md")
#: Commands that open a viewer, serve a GUI or run the whole suite: shown, not run.
NOT_RUN = ("xdg-open", "rerun", "thirdhand review", "make test", "ros2", "pip install")
BIN = Path(sys.executable).parent


def _pages() -> list[Path]:
    return sorted(p for p in DOCS.rglob("*.md"))


def _blocks(text: str, language: str) -> list[str]:
    """The fenced code blocks of ``language`` in a Markdown text (indented fences too)."""
    pattern = re.compile(
        rf"^(?P<indent>[ \t]*)```{language}[ \t]*\n(?P<body>.*?)^(?P=indent)```[ \t]*$",
        re.M | re.S,
    )
    blocks = []
    for m in pattern.finditer(text):
        indent = len(m.group("indent"))
        blocks.append("\n".join(line[indent:] for line in m.group("body").splitlines()))
    return blocks


def shell_commands(text: str) -> list[str]:
    """Each command of the ``sh`` blocks: continuation lines joined, comments dropped."""
    commands: list[str] = []
    for block in _blocks(text, "sh"):
        pending = ""
        for raw in block.splitlines():
            line = raw.rstrip()
            if line.endswith("\\"):
                pending += line[:-1] + " "
                continue
            line = pending + line
            pending = ""
            words = shlex.split(line, comments=True)
            if words:
                commands.append(shlex.join(words))
    return commands


def _argv(command: str) -> list[str] | None:
    """The argv that runs ``command`` here, or None for a command that is not run."""
    if command.startswith(NOT_RUN):
        return None
    words = shlex.split(command)
    if words[:2] == ["make", "demo"]:
        return [sys.executable, "-m", "thirdhand", "demo", "-o", "out/chair"]
    if words[0] == "thirdhand":
        return [sys.executable, "-m", "thirdhand", *words[1:]]
    if words[0] == "python":
        return [sys.executable, *words[1:]]
    if (BIN / words[0]).is_file():
        return [str(BIN / words[0]), *words[1:]]
    raise AssertionError(f"the docs run {words[0]!r}, which the tests do not know how to run")


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "src"), str(ROOT)])
    env.setdefault("OPENBLAS_NUM_THREADS", "1")
    env.setdefault("OMP_NUM_THREADS", "1")
    if MESHES.is_dir():
        env.setdefault("THIRDHAND_MESH_PATH", str(MESHES))
    return env


def _run(argv: list[str], cwd: Path) -> None:
    done = subprocess.run(argv, cwd=cwd, env=_env(), capture_output=True, text=True)
    assert done.returncode == 0, f"{shlex.join(argv)} failed:\n{done.stderr[-3000:]}"


def _data_link(folder: Path) -> None:
    """``../shared/data`` as the pages name it, seen from ``folder``."""
    if DATA.is_dir():
        (folder.parent / "shared").mkdir(exist_ok=True)
        link = folder.parent / "shared" / "data"
        if not link.exists():
            link.symlink_to(DATA)


@pytest.fixture(scope="module")
def demo_dir(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """A folder with the demo's output in ``out/chair``, made once (``thirdhand demo``)."""
    base = tmp_path_factory.mktemp("docs") / "work"
    base.mkdir()
    _data_link(base)
    _run([sys.executable, "-m", "thirdhand", "demo", "-o", "out/chair"], base)
    yield base


def _fresh_copy(demo_dir: Path, name: str) -> Path:
    """A folder of its own holding a copy of the demo's output at the same depth."""
    folder = demo_dir.parent.parent / name / "work"
    folder.mkdir(parents=True)
    shutil.copytree(demo_dir / "out", folder / "out", symlinks=True)
    _data_link(folder)
    return folder


# --- (a) the commands of the first hour -------------------------------------------------------


def test_the_command_extraction_reads_continuations_and_drops_comments() -> None:
    text = "```sh\nthirdhand learn a b \\\n    --scene s.json   # meshes\n# only a comment\n```\n"
    assert shell_commands(text) == ["thirdhand learn a b --scene s.json"]
    assert _argv("xdg-open out/chair/report/index.html") is None
    assert _argv("make demo")[-2:] == ["-o", "out/chair"]  # type: ignore[index]


@pytest.mark.slow
@pytest.mark.parametrize("page", RUN_PAGES)
def test_the_pages_shell_commands_run(page: str, demo_dir: Path) -> None:
    commands = shell_commands((DOCS / page).read_text(encoding="utf-8"))
    assert commands, f"{page} has no shell command"
    folder = _fresh_copy(demo_dir, page.replace("/", "_").removesuffix(".md"))
    ran = 0
    for command in commands:
        argv = _argv(command)
        if argv is None:
            continue
        if argv[3:4] == ["demo"]:
            continue  # the fixture ran it; its output is in the folder
        _run(argv, folder)
        ran += 1
    assert ran >= 2


# --- (b) every Python snippet -----------------------------------------------------------------


def _snippets() -> list[tuple[str, int, str]]:
    """Every ``python`` block under docs/ (the README's one runs in tests/test_api.py)."""
    found = []
    for path in _pages():
        for k, code in enumerate(_blocks(path.read_text(encoding="utf-8"), "python")):
            found.append((str(path.relative_to(ROOT)), k, code))
    return found


def test_there_are_snippets_to_run() -> None:
    assert len(_snippets()) >= 8


@pytest.mark.slow
@pytest.mark.parametrize(
    ("page", "index", "code"), _snippets(), ids=[f"{p}[{k}]" for p, k, _ in _snippets()]
)
def test_every_python_snippet_runs(page: str, index: int, code: str, demo_dir: Path) -> None:
    name = f"snippet_{page.replace('/', '_').removesuffix('.md')}_{index}"
    folder = _fresh_copy(demo_dir, name)
    script = folder / "snippet.py"
    script.write_text(code, encoding="utf-8")
    _run([sys.executable, str(script)], folder)


# --- (c) the reference covers the code ---------------------------------------------------------


@pytest.fixture(scope="module")
def reference() -> dict[str, Any]:
    return runpy.run_path(str(DOCS / "scripts" / "gen_reference.py"), run_name="reference")


def test_the_cli_reference_names_every_leaf_command(reference: dict[str, Any]) -> None:
    leaves = reference["leaf_commands"]()
    # The walk reaches the lazily imported stage commands and their subcommands.
    for known in ("learn", "execute", "segment calibrate", "primitives library", "convert"):
        assert known in leaves
    page = reference["cli_page"]()
    missing = [c for c in leaves if f"## `thirdhand {c}`" not in page]
    assert not missing, f"commands without a section: {missing}"


def test_the_hand_written_pages_show_every_leaf_command(reference: dict[str, Any]) -> None:
    text = "\n".join(p.read_text(encoding="utf-8") for p in _pages())
    missing = [c for c in reference["leaf_commands"]() if f"thirdhand {c}" not in text]
    assert not missing, f"commands no guide, tutorial or explanation shows: {missing}"


def test_the_cli_reference_names_every_option(reference: dict[str, Any]) -> None:
    page = reference["cli_page"]()
    for path, command in reference["command_tree"]():
        if not path:
            continue  # the root's --version
        for param in command.params:
            if getattr(param, "hidden", False) or param.param_type_name == "argument":
                continue
            assert f"`{param.opts[0]}`" in page, f"thirdhand {' '.join(path)}: {param.opts[0]}"


def test_the_settings_reference_names_every_table_and_key(reference: dict[str, Any]) -> None:
    from thirdhand.config import REGISTRY, settings_class

    page = reference["settings_page"]()
    assert reference["settings_tables"]() == list(REGISTRY)
    for table in REGISTRY:
        assert f"## `[{table}]`" in page
        for key in settings_class(table).model_fields:
            assert f"| `{key}` |" in page, f"[{table}] {key}"


def test_the_task_file_reference_names_every_stage_block(reference: dict[str, Any]) -> None:
    from thirdhand.task.stages import Stages

    page = reference["task_file_page"]()
    for block in Stages.model_fields:
        assert f"{{ #stages-{block} }}" in page, block
    assert "## The document: `TaskFile`" in page


def test_the_site_lists_every_hand_written_page() -> None:
    nav = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    for page in _pages():
        rel = page.relative_to(DOCS).as_posix()
        assert f": {rel}" in nav, f"{rel} is not in the site's nav"
    for generated in runpy.run_path(str(DOCS / "scripts" / "gen_reference.py"), run_name="x")[
        "PAGES"
    ]:
        assert f": {generated}" in nav


# --- (d) sizes and the words history leaves behind --------------------------------------------


def test_the_readme_is_a_front_page() -> None:
    text = README.read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 150
    assert "make demo" in text and "make test" in text


def test_the_hand_written_docs_stay_short() -> None:
    lines = sum(len(p.read_text(encoding="utf-8").splitlines()) for p in _pages())
    assert lines <= 5000, f"{lines} hand-written lines under docs/"


def _tracked_text_files() -> list[Path]:
    listed = subprocess.run(
        ["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, text=True, check=False
    )
    if listed.returncode != 0:
        pytest.skip("not a git checkout")
    files = []
    for name in listed.stdout.split("\0"):
        path = ROOT / name
        if name and path.is_file() and path.suffix not in (".png", ".parquet", ".stl", ".npz"):
            files.append(path)
    return files


SESSION = re.compile(r"\bsessions?[-_ ]?[0-9]+", re.I)
ISSUE = re.compile(r"\bissues?\s*#?[0-9]+|(?<![\w.#/-])#[0-9]+\b", re.I)
HASH = re.compile(r"\b(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}\b")


def test_no_tracked_file_names_a_numbered_work_session() -> None:
    bad = []
    for path in _tracked_text_files():
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            continue
        for n, line in enumerate(text.splitlines(), 1):
            if SESSION.search(line):
                bad.append(f"{path.relative_to(ROOT)}:{n}")
    assert not bad, "numbered work sessions: " + ", ".join(bad[:20])


def test_readme_and_docs_name_no_issue_and_no_commit_hash() -> None:
    bad = []
    for path in [README, *_pages()]:
        for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if ISSUE.search(line) or HASH.search(line):
                bad.append(f"{path.relative_to(ROOT)}:{n}: {line.strip()[:80]}")
    assert not bad, "\n".join(bad)


def test_the_history_patterns_catch_what_they_should() -> None:
    word = "session"  # spelt apart: this file is tracked too
    assert SESSION.search(f"measured in {word} 38") and SESSION.search(f"the {word}-41 code")
    assert not SESSION.search("a review session saved a hundred times")
    assert ISSUE.search("(issue 35)") and ISSUE.search("see #12")
    assert not ISSUE.search("first-session.md#2-review-it")
    assert HASH.search("before (156d70b)") and not HASH.search("deadbeef is all letters? no")
    assert not HASH.search("1234567")
