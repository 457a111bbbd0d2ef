"""Every case of the second hostile pass, closed by class (docs/reference/reliability.md).

Each test names the issue's case number. The classes: one output-path policy
(``fileops.check_output``), bounded reads (``readlimits``), validation of the core
type whatever the reader (``Demonstration``), writers that carry or refuse, the
tracker repair only for its tracker, and sanity checks that say what is wrong.
The structure-aware generators live in ``test_hostile_generators.py``.
"""

from __future__ import annotations

import json
import os
import shlex
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from cli_helpers import call
from thirdhand import BodyInfo, Demonstration, io, se3
from thirdhand.demonstration import InteractionInterval, Labels
from thirdhand.errors import (
    DemonstrationError,
    FormatError,
    OutputError,
    TaskFileError,
    ThirdhandError,
)
from thirdhand.fileops import check_output, write_bytes
from thirdhand.taskfile import SCHEMA, TaskFile, load_task, save_task

SRC = str(Path(__file__).resolve().parents[1] / "src")


def demo_of(
    parts: list[str],
    *,
    n: int = 60,
    seed: int = 0,
    finger: bool = True,
    labels: Labels | None = None,
) -> Demonstration:
    rng = np.random.default_rng(seed)
    bodies = [BodyInfo("rh_index", "finger", "right")] if finger else []
    bodies += [BodyInfo(p) for p in parts]
    return Demonstration(
        np.arange(n) / 120.0,
        bodies,
        {b.name: rng.uniform(-1.0, 1.0, (n, 3)) for b in bodies},
        {b.name: se3.random_quat(rng, n) for b in bodies},
        labels=labels,
    )


def chain_task(n_steps: int) -> dict[str, Any]:
    children = [f"p{i}" for i in range(n_steps)]
    return {
        "schema": SCHEMA,
        "objects": [{"name": "base"}, *({"name": c} for c in children)],
        "constraints": [
            {"id": f"c{i}", "parent": "base", "child": c, "type": "fixed"}
            for i, c in enumerate(children)
        ],
        "plan": [
            {"parent": "base", "child": c, "constraint": f"c{i}"} for i, c in enumerate(children)
        ],
    }


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("hostile33")
    out: dict[str, Path] = {"dir": d}
    out["chair"] = d / "chair.parquet"
    io.save(demo_of(["seating", "leg1"]), out["chair"])
    out["chair_csv"] = d / "chair.csv"
    io.save(demo_of(["seating", "leg1"]), out["chair_csv"])
    out["bench"] = d / "bench.parquet"
    io.save(demo_of(["seating", "leg2"], seed=1), out["bench"])
    out["toolbox"] = d / "toolbox.parquet"
    io.save(demo_of(["side_left", "handle"], seed=2), out["toolbox"])
    out["task"] = d / "task.json"
    save_task(TaskFile.model_validate(chain_task(2)), out["task"])
    out["task35"] = d / "task35.json"
    save_task(TaskFile.model_validate(chain_task(35)), out["task35"])
    out["deep_task"] = d / "deep_task.json"
    text = json.dumps(chain_task(1))
    out["deep_task"].write_text(text[:-1] + ', "x": ' + "[" * 5000 + "]" * 5000 + "}")
    out["deep_model"] = d / "deep_model.json"
    out["deep_model"].write_text("[" * 100_000 + "]" * 100_000)
    out["fifo"] = d / "fifo.json"
    os.mkfifo(out["fifo"])
    out["dwell_config"] = d / "dwell.toml"  # gestures --dwell 1e9, now a setting
    out["dwell_config"].write_text("[gestures]\ndwell = 1e9\n")
    out["meshes_config"] = d / "meshes.toml"  # execute --meshes /etc/passwd, now a setting
    out["meshes_config"].write_text("[execute]\nmeshes = ['/etc/passwd']\n")
    out["userdir"] = d / "mine"
    out["userdir"].mkdir()
    (out["userdir"] / "notes.txt").write_text("mine")
    return out


#: (issue case, arguments with {placeholders}, a fragment the one error line holds)
CLI_CASES: list[tuple[str, str, str]] = [
    ("8", "convert {chair} ''", "names a folder"),
    ("8", "convert {chair} .", "names a folder"),
    ("8", "convert {chair} ..", "names a folder"),
    ("8", "synth chair -o ''", "names a folder"),
    ("8", "learn {chair} -o .", "names a folder"),
    ("8", "segment {chair} --json ''", "names a folder"),
    ("8", "execute {task} --record ''", "names a folder"),
    ("8", "convert {chair} {chair}/x.csv", "is a file, not a folder"),
    ("8", "convert {chair} {userdir}", "holds no recording"),
    ("9", "irl learn {deep_task}", "nested 5001 levels"),
    ("9", "segment {chair} -m {deep_model}", "nested 100000 levels"),
    ("10", "irl learn /dev/zero", "is a device"),
    ("10", "segment {chair} -m /dev/zero", "is a device"),
    ("10", "irl learn {fifo}", "FIFO"),
    ("10", "info /dev/zero", "is a device"),
    ("11", "irl learn {task35}", "at most 18 steps"),
    ("13", "convert {chair} /dev/null --force", "is a device"),
    ("13", "convert {chair} {fifo} --force", "FIFO"),
    ("13", "convert {chair} {userdir} --force", "holds no recording"),
    ("14", "learn {chair} {bench} {toolbox} -o {dir}/t.json", "different tasks"),
    ("14", "learn {chair} {dir}/../{dir.name}/chair.parquet -o {dir}/t.json", "same file"),
    ("14", "merge {chair} {dir}/./chair.parquet -o {dir}/m.parquet", "same file"),
    ("14", "execute {task} --config {meshes_config}", "not a folder"),
    ("14", "execute {task} --demo {toolbox}", "none of the task's objects"),
    ("14", "convert {chair} -", "standard output"),
    ("14", "gestures {chair} --config {dwell_config}", "dwell"),
    ("14", "attention {chair} --head leg1", "not a head"),
]


@pytest.mark.parametrize(
    ("case", "template", "fragment"), CLI_CASES, ids=[f"{c[0]}:{c[1][:50]}" for c in CLI_CASES]
)
def test_issue33_command_is_one_error_line(
    capsys: pytest.CaptureFixture[str],
    files: dict[str, Path],
    case: str,
    template: str,
    fragment: str,
) -> None:
    args = shlex.split(template.format(**files))
    rc, out, err = call(capsys, *args)
    assert rc == 1, (case, args, out, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("thirdhand: error: "), err
    assert fragment in lines[0], lines[0]
    assert "wrote" not in out
    assert files["fifo"].is_fifo() and (files["userdir"] / "notes.txt").is_file()


def test_case1_mlr_of_another_tracker_keeps_every_sample(tmp_path: Path) -> None:
    # A body crossing the world origin (the middle of a Motive floor), 1,200 samples.
    n = 1200
    pos = np.zeros((n, 3))
    pos[:, 0] = np.linspace(-1.0, 1.0, n)
    demo = Demonstration(
        np.arange(n) / 120.0,
        [BodyInfo("a")],
        {"a": pos},
        {"a": se3.random_quat(np.random.default_rng(0), n)},
    )
    io.save(demo, tmp_path / "rec")
    assert (tmp_path / "rec" / "meta.kvg").read_text().startswith("writer = thirdhand")
    back = io.load(tmp_path / "rec")
    assert back.equals(demo) and int(back.valid("a").sum()) == n
    assert back.meta["mlr"]["polhemus_repair"] is False


def test_case2_articulation_log_refuses_what_it_cannot_carry(tmp_path: Path) -> None:
    demo = demo_of(["seating"], finger=False)  # 120 Hz, body 'seating'
    with pytest.raises(FormatError, match="stores no body name"):
        io.save(demo, tmp_path / "x.log")
    with pytest.raises(FormatError, match="stores no time"):
        io.save(demo, tmp_path / "seating.log")
    # What it can carry round-trips exactly.
    ok = Demonstration(
        np.arange(20) / 10.0, [BodyInfo("x")], {"x": demo.pos("seating")[:20]},
        {"x": demo.quat("seating")[:20]},
    )  # fmt: skip
    io.save(ok, tmp_path / "x.log")
    assert io.load(tmp_path / "x.log").equals(ok)
    assert not (tmp_path / "seating.log").exists()


def test_case3_motive_csv_carries_kinds_and_labels(tmp_path: Path) -> None:
    lab = Labels(interactions=(InteractionInterval("rh_index", "seating", 0.1, 0.2),))
    demo = demo_of(["seating", "leg1"], labels=lab)
    io.save(demo, tmp_path / "rec.csv")
    back = io.load(tmp_path / "rec.csv")
    assert back.bodies == demo.bodies and back.labels == demo.labels
    assert back.info("rh_index").kind == "finger"
    # An explicit kinds option still wins over the header.
    from thirdhand.io import motive

    assert motive.read(tmp_path / "rec.csv", kinds={"rh_index": "hand"}).info("rh_index").kind == (
        "hand"
    )


def test_case3_a_real_motive_export_takes_kinds_from_a_sidecar(tmp_path: Path) -> None:
    from thirdhand.io import motive

    demo = demo_of(["seating"])
    bare = demo.replace(bodies=[BodyInfo(b.name, oriented=True) for b in demo.bodies])
    io.save(bare, tmp_path / "rec.csv")  # no kinds stated: like a real Motive export
    assert io.load(tmp_path / "rec.csv").info("rh_index").kind == "part"
    side = motive.sidecar_path(tmp_path / "rec.csv")
    assert side.name == "rec.thirdhand.json"
    side.write_text(
        json.dumps(
            {
                "format": "thirdhand.motive-extra/1",
                "bodies": [{"name": "rh_index", "kind": "finger", "hand": "right"}],
            }
        )
    )
    assert io.load(tmp_path / "rec.csv").bodies == demo.bodies
    side.write_text('{"format": "thirdhand.motive-extra/1", "bodies": [{"name": "lid"}]}')
    with pytest.raises(FormatError, match=r"rec\.thirdhand\.json: names body 'lid'"):
        io.load(tmp_path / "rec.csv")


def _rewrite_parquet(path: Path, *, column: str | None = None, value: float = 0.0,
                     meta: Any = None) -> None:  # fmt: skip
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pq.read_table(path)
    if column is not None:
        arr = table.column(column).to_numpy().copy()
        arr[3] = value
        table = table.set_column(table.column_names.index(column), column, pa.array(arr))
    if meta is not None:
        table = table.replace_schema_metadata({b"thirdhand": meta})
    pq.write_table(table, path)


def test_case4_parquet_is_no_back_door_for_a_huge_quaternion(tmp_path: Path) -> None:
    p = tmp_path / "q.parquet"
    io.save(demo_of(["seating"]), p)
    _rewrite_parquet(p, column="seating:qw", value=149112.0)
    with pytest.raises(FormatError, match="frame 3: quaternion has norm 149112"):
        io.load(p)


@pytest.mark.parametrize(
    ("start", "end", "says"),
    [
        (float("nan"), 0.2, "not finite"),
        (0.3, 0.1, "starts after it ends"),
        (1e9, 1e9 + 1, "outside the recording"),
    ],
)
def test_case7_bad_label_intervals_do_not_load_from_parquet(
    tmp_path: Path, start: float, end: float, says: str
) -> None:
    import pyarrow.parquet as pq

    p = tmp_path / "l.parquet"
    io.save(demo_of(["seating"]), p)
    header = json.loads(pq.read_schema(p).metadata[b"thirdhand"])
    header["labels"]["interactions"] = [
        {"a": "rh_index", "b": "seating", "start": start, "end": end}
    ]
    _rewrite_parquet(p, meta=json.dumps(header).encode())
    with pytest.raises(FormatError, match=says):
        io.load(p)
    with pytest.raises(DemonstrationError, match=says):
        demo_of(["seating"], labels=Labels(interactions=(InteractionInterval(
            "rh_index", "seating", start, end),)))  # fmt: skip


def test_case5_segment_invents_no_interaction() -> None:
    from thirdhand.segment import segment_demonstration

    n = 240
    rng = np.random.default_rng(0)
    bodies = [BodyInfo("rh_index", "finger", "right"), BodyInfo("seat"), BodyInfo("leg")]
    pos = {"rh_index": np.full((n, 3), np.nan), "seat": np.full((n, 3), np.nan),
           "leg": rng.uniform(-1, 1, (n, 3))}  # fmt: skip
    quat = {k: np.where(np.isfinite(v[:, :1]), se3.random_quat(rng, n), np.nan)
            for k, v in pos.items()}  # fmt: skip
    never = segment_demonstration(Demonstration(np.arange(n) / 120.0, bodies, pos, quat))
    assert all(not p.intervals and not p.label.any() for p in never.pairs)
    two = demo_of(["seat", "leg"], n=2)
    two = two.replace(t=np.array([0.0, 0.008]))
    result = segment_demonstration(two)
    for p in result.pairs:
        assert all(0.0 <= s <= e <= 0.008 for s, e in p.intervals), p.intervals
    for h in result.hands:
        assert all(0.0 <= s <= e <= 0.008 for s, e in h.intervals), h.intervals


def test_case6_info_json_is_strict_json(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    p = tmp_path / "one.parquet"
    io.save(demo_of(["seating"], n=1), p)
    rc, out, err = call(capsys, "info", "--json", str(p))
    assert rc == 0, err

    def refuse(name: str) -> None:
        raise ValueError(name)

    doc = json.loads(out, parse_constant=refuse)
    assert doc["rate_hz"] is None and doc["n_frames"] == 1


def test_case9_deep_kvg_and_parquet_metadata_are_refused(tmp_path: Path) -> None:
    io.save(demo_of(["seating"]), tmp_path / "rec")
    (tmp_path / "rec" / "meta.kvg").write_text("a = " + "{ b = " * 5000 + "1" + " }" * 5000)
    with pytest.raises(FormatError, match="nested more than 64"):
        io.load(tmp_path / "rec")
    p = tmp_path / "deep.parquet"
    io.save(demo_of(["seating"]), p)
    _rewrite_parquet(p, meta=b"[" * 50_000 + b"]" * 50_000)
    with pytest.raises(FormatError, match="nested 50000 levels"):
        io.load(p)
    from thirdhand.io import elan

    eaf = tmp_path / "deep.eaf"
    eaf.write_text("<a>" * 5000 + "</a>" * 5000)
    with pytest.raises(FormatError, match="XML nested more than 64"):
        elan.parse_eaf(eaf)


def test_case10_reads_of_devices_and_fifos_stop_at_once(files: dict[str, Path]) -> None:
    for path in ("/dev/zero", files["fifo"], files["dir"]):
        with pytest.raises(TaskFileError, match="not a task file"):
            load_task(path)
    # In a separate process, with a timeout: no read without end, no wait on a FIFO.
    proc = subprocess.run(
        [sys.executable, "-m", "thirdhand", "segment", str(files["chair"]), "-m",
         str(files["fifo"])],
        capture_output=True, text=True, timeout=120, check=False,
        env={**os.environ, "PYTHONPATH": SRC},
    )  # fmt: skip
    assert proc.returncode == 1 and "FIFO" in proc.stderr


def test_case12_merge_of_two_sessions_names_the_residuals() -> None:
    from thirdhand.merge import merge
    from thirdhand.merge.align import MergeError

    rng = np.random.default_rng(5)
    n = 1200
    t = np.arange(n) / 120.0

    def walk() -> np.ndarray:
        return np.cumsum(rng.normal(scale=0.01, size=(n, 3)), axis=0)

    def rec(p: np.ndarray) -> Demonstration:
        return Demonstration(t, [BodyInfo("a")], {"a": p}, {"a": np.tile([0, 0, 0, 1.0], (n, 1))})

    with pytest.raises(MergeError, match=r"not one session: .* mm median"):
        merge([rec(walk()), rec(walk())])


def test_case14_concurrent_writers_to_a_new_output(tmp_path: Path) -> None:
    target = tmp_path / "out.csv"
    check_output(target)  # this command found it missing, no --force
    target.write_bytes(b"the other process's output")  # another command got there first
    with pytest.raises(OutputError, match="created by another process"):
        write_bytes(target, b"mine")
    assert target.read_bytes() == b"the other process's output"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.csv"]  # no .bak, no temporary


def test_case14_two_processes_convert_to_one_new_output(files: dict[str, Path]) -> None:
    target = files["dir"] / "race.csv"
    cmd = [sys.executable, "-m", "thirdhand", "convert", str(files["chair"]), str(target)]
    env = {**os.environ, "PYTHONPATH": SRC}
    procs = [
        subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        for _ in range(2)
    ]
    results = [(*p.communicate(timeout=120), p.returncode) for p in procs]
    codes = sorted(r[2] for r in results)
    assert codes == [0, 1], results  # one wins; the other says so
    # Never a silent move aside: no backup, one complete file.
    assert not list(files["dir"].glob("race.csv.bak*"))
    assert io.load(target).n_frames == 60
    err = next(r[1] for r in results if r[2] == 1)
    assert "exists" in err or "another process" in err


def test_case14_execute_with_failed_steps_is_an_error_line(
    capsys: pytest.CaptureFixture[str], files: dict[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    from thirdhand.execute import executor
    from thirdhand.execute.step_plan import SearchCounts

    step = SimpleNamespace(
        index=1, child="p0", parent="base", constraint="c0", grasp="top", grasp_source="",
        place_motion="direct", regrasp=None, planning_time_s=0.1, joint_length_rad=0.0,
        tool_length_m=0.0, n_collisions=0, success=False, status="no grasp", tried=SearchCounts(),
        collision_pairs=[],
    )  # fmt: skip
    result = SimpleNamespace(steps=[step], events=[], success=False, n_collisions=0)
    fake = SimpleNamespace(robot=None, run_offline=lambda seed: result)
    monkeypatch.setattr(executor.Executor, "for_task", classmethod(lambda cls, *a, **k: fake))
    rc, _, err = call(capsys, "execute", str(files["task"]))
    assert rc == 1
    assert err.strip().splitlines() == [
        f"thirdhand: error: {files['task']}: 1 of 1 steps failed (c0: no grasp)"
    ]


def test_duplicate_inputs_by_any_spelling(tmp_path: Path) -> None:
    from thirdhand.fileops import check_distinct_inputs

    (tmp_path / "rec.parquet").write_bytes(b"x")
    (tmp_path / "link.parquet").symlink_to(tmp_path / "rec.parquet")
    os.link(tmp_path / "rec.parquet", tmp_path / "hard.parquet")
    for other in ("./rec.parquet", "sub/../rec.parquet", "link.parquet", "hard.parquet"):
        (tmp_path / "sub").mkdir(exist_ok=True)
        with pytest.raises(OutputError, match="same file"):
            check_distinct_inputs([tmp_path / "rec.parquet", tmp_path / other])
    check_distinct_inputs([tmp_path / "rec.parquet", tmp_path / "sub"])


def test_force_replaces_only_files_and_recording_folders(tmp_path: Path) -> None:
    io.save(demo_of(["seating"]), tmp_path / "rec")
    check_output(tmp_path / "rec", force=True)  # a recording folder thirdhand wrote
    io.save(demo_of(["seating"], seed=3), tmp_path / "rec")
    assert (tmp_path / "rec.bak" / "poses.dat").is_file()
    (tmp_path / "x.csv").mkdir()
    with pytest.raises(OutputError, match=r"is a folder; a \.csv output is a file"):
        check_output(tmp_path / "x.csv", force=True)
    os.mkfifo(tmp_path / "pipe")
    with pytest.raises(OutputError, match="FIFO"):
        check_output(tmp_path / "pipe", force=True)
    # Even a writer that skipped the check never moves a FIFO aside.
    with pytest.raises(OutputError, match="never moved aside"):
        write_bytes(tmp_path / "pipe", b"x")
    assert (tmp_path / "pipe").is_fifo() and not (tmp_path / "pipe.bak").exists()


def test_every_error_of_this_file_is_a_package_error() -> None:
    for exc in (OutputError, FormatError, TaskFileError, DemonstrationError):
        assert issubclass(exc, ThirdhandError)
