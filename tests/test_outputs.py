"""Nothing a user made is lost: the output policy of every command.

No command writes over one of its inputs, nor over an existing file without
``--force``; with ``--force`` the previous file is kept as a numbered backup and
no backup is ever replaced; writes go to a unique temporary file beside the
target and are renamed; a short write is an error that leaves the old file and
nothing else; concurrent task-file saves never show a reader an invalid file and
lose no version.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cli_helpers import call
from thirdhand import BodyInfo, Demonstration, io, se3
from thirdhand.errors import OutputError
from thirdhand.fileops import atomic_output, check_output, next_backup, write_bytes
from thirdhand.taskfile import SCHEMA, TaskFile, load_task, save_task


def one_error_line(err: str) -> str:
    """The single ``thirdhand: error:`` line of ``err`` (asserts there is exactly one line)."""
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("thirdhand: error: "), err
    return lines[0]


def small_demo(n: int = 30, seed: int = 1) -> Demonstration:
    rng = np.random.default_rng(seed)
    return Demonstration(
        np.arange(n) / 120.0,
        [BodyInfo("seat"), BodyInfo("leg")],
        {"seat": rng.normal(size=(n, 3)), "leg": rng.normal(size=(n, 3))},
        {"seat": se3.random_quat(rng, n), "leg": se3.random_quat(rng, n)},
    )


def task_doc(**changes: object) -> dict:
    doc: dict = {
        "schema": SCHEMA,
        "objects": [{"name": "seating"}, {"name": "leg1"}, {"name": "leg2"}],
        "constraints": [
            {"id": "c1", "parent": "seating", "child": "leg1", "type": "fixed"},
            {"id": "c2", "parent": "seating", "child": "leg2", "type": "fixed"},
        ],
        "plan": [
            {"parent": "seating", "child": "leg1", "constraint": "c1"},
            {"parent": "seating", "child": "leg2", "constraint": "c2"},
        ],
    }
    doc.update(changes)
    return doc


@pytest.fixture
def demo_path(tmp_path: Path) -> Path:
    path = tmp_path / "demo.parquet"
    io.save(small_demo(), path)
    return path


@pytest.fixture
def task_path(tmp_path: Path) -> Path:
    path = tmp_path / "chair.json"
    save_task(TaskFile.model_validate(task_doc()), path)
    return path


def same_data(a: Demonstration, b: Demonstration) -> bool:
    """Same bodies, frames and positions (formats differ in the metadata they keep)."""
    return a.body_names == b.body_names and all(
        np.allclose(a.pos(n), b.pos(n), atol=1e-9, equal_nan=True) for n in a.body_names
    )


def listing(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


# --- fileops ---------------------------------------------------------------------------------


def test_numbered_backups_never_replace_a_file(tmp_path: Path) -> None:
    target = tmp_path / "out.csv"
    own = tmp_path / "out.csv.bak"
    own.write_bytes(b"the user's own file")
    target.write_bytes(b"v0")
    for k in (1, 2, 3):
        write_bytes(target, f"v{k}".encode())
    assert own.read_bytes() == b"the user's own file"
    assert [(tmp_path / f"out.csv.bak.{i}").read_bytes() for i in (1, 2, 3)] == [
        b"v0",
        b"v1",
        b"v2",
    ]
    assert target.read_bytes() == b"v3"
    assert next_backup(target).name == "out.csv.bak.4"
    assert listing(tmp_path) == ["out.csv", "out.csv.bak", *(f"out.csv.bak.{i}" for i in (1, 2, 3))]


def test_backup_of_a_folder_is_a_complete_copy(tmp_path: Path) -> None:
    folder = tmp_path / "rec"
    io.save(small_demo(seed=1), folder)
    first = (folder / "poses.dat").read_bytes()
    io.save(small_demo(seed=2), folder)
    assert (tmp_path / "rec.bak" / "poses.dat").read_bytes() == first
    assert io.load(folder).equals(small_demo(seed=2))
    assert listing(tmp_path) == ["rec", "rec.bak"]


def test_check_output_refuses_inputs_by_path_link_and_folder(tmp_path: Path) -> None:
    src = tmp_path / "a.json"
    src.write_text("{}")
    (tmp_path / "sub").mkdir()
    link = tmp_path / "link.json"
    link.symlink_to(src)
    hard = tmp_path / "hard.json"
    os.link(src, hard)
    for out in (src, tmp_path / "sub" / ".." / "a.json", link, hard):
        with pytest.raises(OutputError, match="also an input"):
            check_output(out, force=True, inputs=[src])
    folder = tmp_path / "rec"
    folder.mkdir()
    with pytest.raises(OutputError, match="inside the input folder"):
        check_output(folder / "poses.dat", force=True, inputs=[folder])
    with pytest.raises(OutputError, match="pass --force"):
        check_output(src, force=False)
    assert check_output(tmp_path / "new.json", force=False, inputs=[src]) == tmp_path / "new.json"


def test_failed_writer_leaves_old_file_and_no_temporary(tmp_path: Path) -> None:
    target = tmp_path / "x.bin"
    target.write_bytes(b"old")
    with pytest.raises(RuntimeError, match="half-way"), atomic_output(target) as tmp:
        tmp.write_bytes(b"partial")
        raise RuntimeError("half-way")
    with pytest.raises(KeyboardInterrupt), atomic_output(target) as tmp:
        tmp.write_bytes(b"partial")
        raise KeyboardInterrupt
    assert target.read_bytes() == b"old"
    assert listing(tmp_path) == ["x.bin"]


def test_a_failed_write_removes_the_folders_made_for_it(tmp_path: Path) -> None:
    (tmp_path / "kept").mkdir()
    target = tmp_path / "kept" / "new" / "deeper" / "x.bin"
    with pytest.raises(RuntimeError, match="half-way"), atomic_output(target) as tmp:
        tmp.write_bytes(b"partial")
        raise RuntimeError("half-way")
    assert listing(tmp_path) == ["kept"] and listing(tmp_path / "kept") == []
    with atomic_output(target) as tmp:  # a write that succeeds keeps them
        tmp.write_bytes(b"whole")
    assert target.read_bytes() == b"whole"


def test_a_signal_while_the_temporary_is_removed_waits_until_it_is_gone(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """SIGTERM in the middle of the clean-up: the clean-up ends, then the command stops."""
    import shutil

    from thirdhand import cli, fileops
    from thirdhand.errors import Terminated

    real_rmtree = shutil.rmtree
    seen: list[bool] = []

    def rmtree_hit_by_a_signal(path, ignore_errors=False):  # type: ignore[no-untyped-def]
        os.kill(os.getpid(), signal.SIGTERM)  # the handler runs now: it must not raise
        seen.append(True)
        real_rmtree(path, ignore_errors=ignore_errors)

    previous = signal.signal(signal.SIGTERM, cli._on_signal)
    try:
        monkeypatch.setattr(fileops.shutil, "rmtree", rmtree_hit_by_a_signal)
        with pytest.raises(Terminated):
            with atomic_output(tmp_path / "out.txt") as tmp:
                tmp.write_text("complete")
    finally:
        signal.signal(signal.SIGTERM, previous)
    assert seen == [True]
    assert (tmp_path / "out.txt").read_text() == "complete"
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]  # no temporary left


def test_a_write_cut_short_before_its_clean_up_is_removed_on_exit(tmp_path: Path) -> None:
    from thirdhand.fileops import remove_leftovers

    writing = atomic_output(tmp_path / "new" / "out.txt")
    tmp = writing.__enter__()  # a signal then ends the process before the write's clean-up
    tmp.write_text("half")
    assert (tmp_path / "new").exists()
    remove_leftovers()
    assert list(tmp_path.iterdir()) == []  # its temporary folder and the folder made for it
    remove_leftovers()  # nothing left to do


def test_signals_deferred_raises_after_the_block_and_only_then() -> None:
    from thirdhand import cli
    from thirdhand.errors import Terminated
    from thirdhand.fileops import signals_deferred

    previous = signal.signal(signal.SIGINT, cli._on_signal)
    steps = []
    try:
        with pytest.raises(KeyboardInterrupt):
            with signals_deferred():
                with signals_deferred():  # nested: the outermost block decides
                    os.kill(os.getpid(), signal.SIGINT)
                    steps.append("inner done")
                steps.append("outer done")
        with pytest.raises(KeyboardInterrupt):  # outside a block: at once
            os.kill(os.getpid(), signal.SIGINT)
            steps.append("not reached")
    finally:
        signal.signal(signal.SIGINT, previous)
    assert steps == ["inner done", "outer done"]
    assert not issubclass(Terminated, Exception)  # ``except Exception`` does not swallow it


def test_temporary_names_are_unique_per_writer(tmp_path: Path) -> None:
    target = tmp_path / "task.json"
    with atomic_output(target) as a, atomic_output(target) as b:
        assert a != b and a.parent != b.parent
        assert a.name == b.name == "task.json"
        assert a.parent.parent == b.parent.parent == tmp_path
        a.write_text("a")
        b.write_text("b")
    assert target.read_text() == "a"
    assert (tmp_path / "task.json.bak").read_text() == "b"


# --- commands never write over their inputs ----------------------------------------------------


def test_commands_refuse_to_write_over_their_inputs(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, demo_path: Path, task_path: Path
) -> None:
    stem = task_path.with_suffix("")  # --record STEM writes STEM.parquet and STEM.json
    cases = [
        ["irl", "learn", str(task_path), "--json", str(task_path), "--force"],
        ["learn", str(demo_path), "-o", str(demo_path), "--force"],
        ["segment", str(demo_path), "--json", str(demo_path), "--force"],
        ["segment", "train", str(demo_path), "-o", str(demo_path), "--force"],
        ["primitives", "fit", str(demo_path), "-o", str(demo_path), "--force"],
        ["execute", str(task_path), "--record", str(stem), "--force"],
        ["transfer", str(task_path), "--to", "bench", "-o", str(task_path), "--force"],
        ["convert", str(demo_path), str(demo_path), "--force"],
        ["gestures", str(demo_path), "--json", str(demo_path), "--force"],
    ]
    before = {p: p.read_bytes() for p in (demo_path, task_path)}
    for args in cases:
        rc, _, err = call(capsys, *args)
        assert rc == 1, args
        assert "also an input" in one_error_line(err), args
    assert {p: p.read_bytes() for p in before} == before
    assert listing(tmp_path) == ["chair.json", "demo.parquet"]


def test_commands_refuse_an_existing_output_without_force(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, demo_path: Path, task_path: Path
) -> None:
    existing = tmp_path / "mine.json"
    existing.write_text("mine")
    png = tmp_path / "mine.png"
    png.write_bytes(b"my figure")
    report = tmp_path / "report"
    report.mkdir()
    (report / "index.html").write_text("my report")
    (tmp_path / "run.json").write_text("my run")
    cases = [
        ["irl", "learn", str(task_path), "--json", str(existing)],
        ["learn", str(demo_path), "-o", str(existing)],
        ["learn", str(demo_path), "-o", str(tmp_path / "new.json"), "--report", str(report)],
        ["segment", str(demo_path), "--json", str(existing)],
        ["primitives", "fit", str(demo_path), "-o", str(existing)],
        ["primitives", "library", str(demo_path), "--body", "seat", "--plot", str(png)],
        ["execute", str(task_path), "--record", str(tmp_path / "run")],
        ["synth", "chair", "-o", str(demo_path)],
        ["transfer", str(task_path), "--to", "bench", "-o", str(existing)],
    ]
    for args in cases:
        rc, _, err = call(capsys, *args)
        assert rc == 1, args
        assert "pass --force" in one_error_line(err), args
    assert existing.read_text() == "mine" and png.read_bytes() == b"my figure"
    assert (report / "index.html").read_text() == "my report"
    assert (tmp_path / "run.json").read_text() == "my run"
    assert not (tmp_path / "new.json").exists()


def test_convert_force_keeps_every_version(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, demo_path: Path
) -> None:
    target = tmp_path / "out.csv"
    own = tmp_path / "out.csv.bak"
    own.write_text("the user's own notes")
    assert call(capsys, "convert", str(demo_path), str(target))[0] == 0
    first = target.read_bytes()
    other = tmp_path / "other.parquet"
    io.save(small_demo(seed=5), other)
    assert call(capsys, "convert", str(other), str(target), "--force")[0] == 0
    second = target.read_bytes()
    assert call(capsys, "convert", str(demo_path), str(target), "--force")[0] == 0
    assert own.read_text() == "the user's own notes"
    assert (tmp_path / "out.csv.bak.1").read_bytes() == first
    assert (tmp_path / "out.csv.bak.2").read_bytes() == second
    assert target.read_bytes() == first


@pytest.mark.parametrize("name", ["out.bag", "out_mlr", "out_ros2"])
def test_force_works_for_bag_and_folder_targets(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, demo_path: Path, name: str
) -> None:
    target = tmp_path / name
    to = ["--to", "rosbag"] if name == "out_ros2" else []
    assert call(capsys, "convert", str(demo_path), str(target), *to)[0] == 0
    other = tmp_path / "other.parquet"
    io.save(small_demo(seed=5), other)
    rc, _, err = call(capsys, "convert", str(other), str(target), *to)
    assert rc == 1 and "pass --force" in one_error_line(err)
    rc, out, err = call(capsys, "convert", str(other), str(target), *to, "--force")
    assert rc == 0, err
    assert "overwrite=" not in out + err
    assert same_data(io.load(target), io.load(other))
    # Restoring a backup is renaming it back (rosbags tells ROS 1 from 2 by the extension).
    restored = tmp_path / "restored" / name
    restored.parent.mkdir()
    os.rename(tmp_path / f"{name}.bak", restored)
    assert same_data(io.load(restored), io.load(demo_path))
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_execute_record_json_of_task_is_refused(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    # The task is run.json: --record run would write the trajectory over it.
    task = tmp_path / "run.json"
    save_task(TaskFile.model_validate(task_doc()), task)
    before = task.read_bytes()
    rc, _, err = call(capsys, "execute", str(task), "--record", str(tmp_path / "run"))
    assert rc == 1 and "also an input" in one_error_line(err)
    assert task.read_bytes() == before


# --- short writes ------------------------------------------------------------------------------

LIMITED = """
import resource, signal, sys
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
limit = int(sys.argv[1])
resource.setrlimit(resource.RLIMIT_FSIZE, (limit, resource.RLIM_INFINITY))
from thirdhand.cli import main
raise SystemExit(main(sys.argv[2:]))
"""


def run_limited(limit: int, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-c", LIMITED, str(limit), *args],
        capture_output=True,
        text=True,
        check=False,
        timeout=300,
    )


@pytest.mark.parametrize("name", ["out.c3d", "out.csv", "out.parquet", "out.bag", "out_mlr"])
def test_short_write_is_an_error_and_leaves_the_old_file(tmp_path: Path, name: str) -> None:
    src = tmp_path / "in.parquet"
    io.save(small_demo(n=400), src)
    target = tmp_path / "out" / name
    target.parent.mkdir()
    old = tmp_path / "old.parquet"
    io.save(small_demo(n=3, seed=9), old)
    io.save(io.load(old), target)
    before = io.load(target)
    proc = run_limited(4096, "convert", str(src), str(target), "--force")
    assert proc.returncode == 1, proc.stdout + proc.stderr
    line = one_error_line(proc.stderr)
    assert "file-size limit" in line and "nothing was replaced" in line
    assert "wrote" not in proc.stdout
    assert same_data(io.load(target), before)
    assert listing(target.parent) == [name]


def test_short_write_of_a_task_file_keeps_the_old_one(tmp_path: Path) -> None:
    path = tmp_path / "task.json"
    save_task(TaskFile.model_validate(task_doc()), path)
    before = path.read_bytes()
    big = task_doc(stages={"notes": {"text": "x" * 20000}})
    code = textwrap.dedent(
        f"""
        import resource, signal, sys
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (4096, resource.RLIM_INFINITY))
        from thirdhand.taskfile import TaskFile, save_task
        from thirdhand.errors import TaskFileError
        try:
            save_task(TaskFile.model_validate({big!r}), {str(path)!r})
        except TaskFileError as exc:
            print(exc)
            raise SystemExit(1)
        """
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert proc.returncode == 1, proc.stderr
    assert "cannot write task file: the file-size limit was reached" in proc.stdout
    assert path.read_bytes() == before
    assert listing(tmp_path) == ["task.json"]


# --- concurrent saves --------------------------------------------------------------------------

WRITER = """
import sys
from thirdhand.taskfile import load_task, save_task
path, who, n = sys.argv[1], sys.argv[2], int(sys.argv[3])
task = load_task(path)
failures = 0
for i in range(n):
    task.stages.set_other("writer", {"who": who, "i": i})
    try:
        save_task(task, path)
    except Exception as exc:
        failures += 1
        print(type(exc).__name__, exc, file=sys.stderr)
print(failures)
"""

READER = """
import sys, time
from pathlib import Path
from thirdhand.taskfile import parse_task
path, stop = Path(sys.argv[1]), Path(sys.argv[2])
reads = bad = 0
while not stop.exists():
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        bad += 1
        continue
    reads += 1
    try:
        parse_task(text)
    except Exception:
        bad += 1
print(reads, bad)
"""


@pytest.mark.slow
def test_concurrent_saves_from_two_processes_lose_nothing(tmp_path: Path) -> None:
    path = tmp_path / "task.json"
    save_task(TaskFile.model_validate(task_doc()), path)
    stop = tmp_path / "stop"
    n = 150
    reader = subprocess.Popen(
        [sys.executable, "-c", READER, str(path), str(stop)], stdout=subprocess.PIPE, text=True
    )
    writers = [
        subprocess.Popen(
            [sys.executable, "-c", WRITER, str(path), who, str(n)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for who in ("a", "b")
    ]
    try:
        results = [w.communicate(timeout=600) for w in writers]
    finally:
        stop.touch()
        for w in writers:
            w.kill()
        reads_bad = reader.communicate(timeout=60)[0].split()
        reader.kill()
    assert [r[0].strip() for r in results] == ["0", "0"], [r[1] for r in results]
    reads, bad = (int(v) for v in reads_bad)
    assert reads > 0 and bad == 0
    # Every version survives: the final file plus one backup per save.
    versions = [path, *sorted(tmp_path.glob("task.json.bak*"))]
    assert len(versions) == 2 * n + 1
    seen = set()
    for p in versions:
        w = load_task(p).stages.other("writer")
        seen.add(None if not isinstance(w, dict) else (w["who"], w["i"]))
    assert seen == {None} | {(who, i) for who in ("a", "b") for i in range(n)}
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


# --- signals -----------------------------------------------------------------------------------


START_UP_CTRL_C = """
import os, signal, sys


class CtrlCWhileImportingTyper:  # deterministic: the signal arrives inside thirdhand.cli's imports
    def find_spec(self, name, path=None, target=None):
        if name == "typer":
            os.kill(os.getpid(), signal.SIGINT)
        return None


sys.meta_path.insert(0, CtrlCWhileImportingTyper())
from thirdhand.cli import main
raise SystemExit(main(["--version"]))
"""


def _default_sigint() -> None:
    """A child starts as from a shell, whatever the test process's own SIGINT disposition.

    (A full suite run once left the xdist worker with SIGINT ignored — some library
    in the process does it — and an ignored disposition is inherited.)
    """
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_ctrl_c_during_start_up_is_one_line() -> None:
    code = START_UP_CTRL_C
    proc = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=120,
        preexec_fn=_default_sigint,
    )
    assert proc.returncode == 130, proc.stderr
    assert one_error_line(proc.stderr) == "thirdhand: error: interrupted; no output was written"


def test_importing_the_cli_leaves_ctrl_c_alone() -> None:
    code = "import signal, thirdhand.cli\n"
    code += "print(signal.getsignal(signal.SIGINT) is signal.default_int_handler)"
    proc = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=120,
        preexec_fn=_default_sigint,
    )
    assert proc.stdout.strip() == "True", proc.stderr


@pytest.mark.slow
@pytest.mark.parametrize(
    ("sig", "code", "word"),
    [
        (signal.SIGINT, 0, None),
        (signal.SIGTERM, 143, "thirdhand: error: terminated; no output was written"),
    ],
)
def test_review_stops_on_signals_even_when_sigint_was_ignored(
    task_path: Path, sig: int, code: int, word: str | None
) -> None:
    def ignore_sigint() -> None:  # what a shell does to a background job
        signal.signal(signal.SIGINT, signal.SIG_IGN)

    proc = subprocess.Popen(
        [sys.executable, "-m", "thirdhand", "review", str(task_path), "--port", "0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=ignore_sigint,
    )
    try:
        assert proc.stdout is not None
        for line in proc.stdout:  # viser prints a banner first
            if line.startswith("thirdhand review:"):
                break
        assert "http://" in line
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=120)
        # Ctrl-C is review's normal stop (exit 0); SIGTERM is one error line.
        assert proc.returncode == code
        assert err.strip().splitlines()[-1:] == ([word] if word else [])
        assert "Traceback" not in err
    finally:
        proc.kill()
        proc.wait()


@pytest.mark.parametrize("target", ["rec", "rec.csv", "rec.parquet", "rec.bag"])
@pytest.mark.parametrize("bad", ["seat\nrow", "seat\r", " seat", "se\x00at"])
def test_writers_refuse_names_they_cannot_read_back(tmp_path: Path, target: str, bad: str) -> None:
    from thirdhand.errors import FormatError

    demo = small_demo()
    demo = Demonstration(
        demo.t,
        [BodyInfo(bad), BodyInfo("leg")],
        {bad: demo.pos("seat"), "leg": demo.pos("leg")},
        {bad: demo.quat("seat"), "leg": demo.quat("leg")},
    )
    with pytest.raises(FormatError, match="no recording format reads it back"):
        io.save(demo, tmp_path / target)
    assert listing(tmp_path) == []


#: Commands that write one output: (input kind, arguments with {IN} and {OUT}).
WRITERS: list[tuple[str, str]] = [
    ("demo", "convert {IN} {OUT}"),
    ("demo", "segment {IN} --json {OUT}"),
    ("demo", "segment {IN} --plot {OUT}"),
    ("demo", "segment train {IN} -o {OUT}"),
    ("demo", "learn {IN} -o {OUT}"),
    ("demo", "primitives fit {IN} -o {OUT}"),
    ("demo", "primitives library {IN} --body seat --plot {OUT}"),
    ("demo", "gestures {IN} --json {OUT}"),
    ("demo", "attention {IN} --json {OUT}"),
    ("task", "irl learn {IN} --json {OUT}"),
    ("task", "transfer {IN} --to bench -o {OUT}"),
    ("task", "execute {IN} --record {OUT}"),
    ("task", "simulate {IN} --json {OUT}"),
    ("task", "simulate {IN} --video {OUT}"),
]


def alias_of(path: Path, how: str) -> Path:
    """Another name of ``path``: itself, ``./``, ``sub/..``, a symlink or a hard link."""
    folder = path.parent
    if how == "same":
        return path
    if how == "dot":
        return folder / "." / path.name
    if how == "updown":
        (folder / "sub").mkdir(exist_ok=True)
        return folder / "sub" / ".." / path.name
    link = folder / f"{how}-{path.name}"
    if not os.path.lexists(link):
        if how == "symlink":
            link.symlink_to(path)
        else:
            os.link(path, link)
    return link


@settings(
    max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    case=st.sampled_from(WRITERS),
    how=st.sampled_from(["same", "dot", "updown", "symlink", "hardlink"]),
    force=st.booleans(),
)
def test_property_no_command_writes_over_its_input(
    capsys: pytest.CaptureFixture[str],
    demo_path: Path,
    task_path: Path,
    case: tuple[str, str],
    how: str,
    force: bool,
) -> None:
    kind, template = case
    inp = demo_path if kind == "demo" else task_path
    out = alias_of(inp, how)
    if "--record" in template:
        out = out.with_suffix("")  # --record STEM writes STEM.json: the task
    args = template.format(IN=inp, OUT=out).split() + (["--force"] if force else [])
    before = inp.read_bytes()
    rc, _, err = call(capsys, *args)
    assert rc == 1, args
    assert "also an input" in one_error_line(err), args
    assert inp.read_bytes() == before
