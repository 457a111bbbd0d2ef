"""Fuzz suite: random mutations of every text format never crash a reader.

A mutated file must either load faithfully or raise the package's error type
(:class:`~thirdhand.errors.ThirdhandError`, whose message the CLI prints as one
line); any other exception is a crash and fails the test. "Faithfully" for a
recording means no silent partial load: the same number of bodies and frames
as the file states, finite positions and unit quaternions where tracked.

Two kinds of cases: seeded byte-level mutations (the same cases on every run,
counted per format in :data:`COUNTS`), and hypothesis-driven ones, which shrink a
failure to a minimal example. The long runs are marked ``slow`` (they still run
in CI).
"""

from __future__ import annotations

import json
import re
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from thirdhand import BodyInfo, Demonstration, io, se3
from thirdhand.errors import ThirdhandError
from thirdhand.io import articulation, elan, kvg
from thirdhand.taskfile import SCHEMA, TaskFile, parse_task

# A reader must not leak numpy warnings on hostile numbers (inf, 1e308) either.
pytestmark = pytest.mark.filterwarnings("error::RuntimeWarning")

#: Cases per format in the seeded runs: (quick, slow).
COUNTS = {"motive": (300, 3000), "mlr": (300, 3000), "other": (150, 1500)}

TOKENS = [
    b",", b"\n", b"\r", b"\r\n", b'"', b" ", b"\t", b"-", b".", b"e", b"0", b"7", b"[", b"]",
    b"{", b"}", b"=", b"#", b"\x00", b"\xff", b"inf", b"-inf", b"nan", b"1e308", b"149112",
    b",,", b"Frame,Time", b"<", b">", b"\xc3(",
]  # fmt: skip


def mutate(data: bytes, rng: np.random.Generator, n_ops: int) -> bytes:
    """``data`` with ``n_ops`` random edits: bytes, tokens, numbers, lines, truncation."""
    for _ in range(n_ops):
        op = int(rng.integers(9))
        pos = int(rng.integers(len(data) + 1))
        tok = TOKENS[int(rng.integers(len(TOKENS)))]
        lines = data.split(b"\n")
        if op == 0:  # replace a byte
            data = data[:pos] + tok[:1] + data[pos + 1 :]
        elif op == 1:  # insert a token
            data = data[:pos] + tok + data[pos:]
        elif op == 2:  # delete a span
            data = data[:pos] + data[pos + int(rng.integers(1, 20)) :]
        elif op == 3:  # replace a number by a token or another number
            nums = list(re.finditer(rb"-?\d+(\.\d+)?(e-?\d+)?", data))
            if nums:
                m = nums[int(rng.integers(len(nums)))]
                new = tok if rng.random() < 0.5 else str(rng.normal() * 10.0 ** rng.integers(-3, 9))
                new_b = new if isinstance(new, bytes) else new.encode()
                data = data[: m.start()] + new_b + data[m.end() :]
        elif op == 4 and len(lines) > 1:  # delete a line
            del lines[int(rng.integers(len(lines)))]
            data = b"\n".join(lines)
        elif op == 5 and len(lines) > 1:  # duplicate a line
            i = int(rng.integers(len(lines)))
            lines.insert(i, lines[i])
            data = b"\n".join(lines)
        elif op == 6 and len(lines) > 2:  # move a line
            line = lines.pop(int(rng.integers(len(lines))))
            lines.insert(int(rng.integers(len(lines) + 1)), line)
            data = b"\n".join(lines)
        elif op == 7:  # truncate
            data = data[:pos]
        else:  # swap two lines
            if len(lines) > 1:
                i, j = (int(v) for v in rng.integers(len(lines), size=2))
                lines[i], lines[j] = lines[j], lines[i]
                data = b"\n".join(lines)
    return data


def small_demo(n: int = 25) -> Demonstration:
    rng = np.random.default_rng(3)
    pos = {"seat": rng.normal(size=(n, 3)), "leg": rng.normal(size=(n, 3))}
    valid = {"seat": np.ones(n, bool), "leg": rng.random(n) > 0.2}
    return Demonstration(
        np.arange(n) / 100.0,
        [BodyInfo("seat"), BodyInfo("leg")],
        pos,
        {"seat": se3.random_quat(rng, n), "leg": se3.random_quat(rng, n)},
        valid,
    )


def assert_faithful(demo: Demonstration, base: Demonstration, *, bodies: bool = True) -> None:
    """No silent partial load: every body and frame the file states, sane values.

    ``bodies=False`` when the mutation may legitimately change which bodies the
    file states (an edit of ``meta.kvg``, which names the used sensor rows).
    """
    if bodies:
        assert len(demo) == len(base), f"{len(demo)} of {len(base)} bodies loaded"
    assert demo.n_frames == base.n_frames, f"{demo.n_frames} of {base.n_frames} frames loaded"
    for name in demo.body_names:
        tr = demo.track(name)
        assert np.all(np.isfinite(tr.pos[tr.valid]))
        if tr.info.oriented:
            norm = np.linalg.norm(tr.quat[tr.valid], axis=1)
            assert np.all(np.abs(norm - 1.0) < 1e-9)


def check_recording(path: Path, fmt: str, base: Demonstration, *, bodies: bool = True) -> str:
    """Load ``path``; return ``"error"`` or ``"loaded"``; fail on a crash or partial load."""
    try:
        demo = io.load(path, format=fmt)
    except ThirdhandError as exc:
        assert str(path) in str(exc), f"the error does not name the file: {exc}"
        return "error"
    assert_faithful(demo, base, bodies=bodies)
    return "loaded"


@pytest.fixture(scope="module")
def bases(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    d = tmp_path_factory.mktemp("fuzz_bases")
    demo = small_demo()
    io.save(demo, d / "demo.csv")
    io.save(demo, d / "rec")
    return {"demo": demo, "csv": (d / "demo.csv").read_bytes(), "rec": d / "rec"}


def run_motive(bases: dict[str, Any], folder: Path, seeds: range) -> dict[str, int]:
    counts = {"error": 0, "loaded": 0}
    for seed in seeds:
        rng = np.random.default_rng(seed)
        path = folder / "m.csv"
        path.write_bytes(mutate(bases["csv"], rng, int(rng.integers(1, 4))))
        try:
            counts[check_recording(path, "motive", bases["demo"])] += 1
        except AssertionError as exc:
            raise AssertionError(f"seed {seed}: {exc}") from None
    return counts


def run_mlr(bases: dict[str, Any], folder: Path, seeds: range) -> dict[str, int]:
    counts = {"error": 0, "loaded": 0}
    files = sorted(p.name for p in bases["rec"].iterdir())
    for seed in seeds:
        rng = np.random.default_rng(seed)
        rec = folder / "rec"
        shutil.rmtree(rec, ignore_errors=True)
        shutil.copytree(bases["rec"], rec)
        # Mostly poses.dat; sometimes the times file or the meta file.
        name = "poses.dat" if rng.random() < 0.7 else files[int(rng.integers(len(files)))]
        (rec / name).write_bytes(mutate((rec / name).read_bytes(), rng, int(rng.integers(1, 4))))
        try:
            counts[check_recording(rec, "mlr", bases["demo"], bodies=name != "meta.kvg")] += 1
        except AssertionError as exc:
            raise AssertionError(f"seed {seed} ({name}): {exc}") from None
    return counts


def test_fuzz_motive_csv(bases: dict[str, Any], tmp_path: Path) -> None:
    counts = run_motive(bases, tmp_path, range(COUNTS["motive"][0]))
    assert counts["error"] > 0 and sum(counts.values()) == COUNTS["motive"][0]


def test_fuzz_poses_dat(bases: dict[str, Any], tmp_path: Path) -> None:
    counts = run_mlr(bases, tmp_path, range(COUNTS["mlr"][0]))
    assert counts["error"] > 0 and sum(counts.values()) == COUNTS["mlr"][0]


@pytest.mark.slow
def test_fuzz_motive_csv_long(bases: dict[str, Any], tmp_path: Path) -> None:
    quick, slow = COUNTS["motive"]
    counts = run_motive(bases, tmp_path, range(quick, slow))
    assert sum(counts.values()) == slow - quick


@pytest.mark.slow
def test_fuzz_poses_dat_long(bases: dict[str, Any], tmp_path: Path) -> None:
    quick, slow = COUNTS["mlr"]
    counts = run_mlr(bases, tmp_path, range(quick, slow))
    assert sum(counts.values()) == slow - quick


# --- the other text formats: label files, articulation logs, task files -----------------------


def labels_dir() -> Path:
    return Path(__file__).resolve().parents[2] / "shared" / "data" / "3rdhand" / "toolbox_3_labels"


def task_text() -> bytes:
    doc = {
        "schema": SCHEMA,
        "objects": [{"name": "seating"}, {"name": "leg1"}, {"name": "leg2"}],
        "constraints": [
            {
                "id": "c1",
                "parent": "seating",
                "child": "leg1",
                "type": "revolute",
                "pos": [0.1, 0.0, 0.02],
                "quat": [0.0, 0.0, 0.0, 1.0],
                "free_dofs": {"rz": [-3.14, 3.14]},
            },
            {"id": "c2", "parent": "seating", "child": "leg2", "type": "fixed"},
        ],
        "plan": [
            {"parent": "seating", "child": "leg1", "constraint": "c1"},
            {"parent": "seating", "child": "leg2", "constraint": "c2", "after": [0]},
        ],
    }
    return json.dumps(doc, indent=1).encode()


def articulation_text() -> bytes:
    rng = np.random.default_rng(4)
    q = se3.random_quat(rng, 20)
    rows = np.column_stack([rng.normal(size=(20, 3)), q])
    return "".join(" ".join(f"{v:.17g}" for v in r) + "\n" for r in rows).encode()


def _task(path: Path) -> Any:
    return parse_task(path.read_text(encoding="utf-8", errors="strict"), name=str(path))


def _articulation(path: Path) -> Any:
    # The format states no frame count: a duplicated or deleted row is a faithful load.
    demo = articulation.read(path)
    assert len(demo) == 1
    tr = demo.track(demo.body_names[0])
    assert np.all(np.isfinite(tr.pos[tr.valid]))
    return demo


#: name -> (base bytes or None when the shared data is absent, reader, file name)
def other_formats() -> dict[str, tuple[bytes | None, Callable[[Path], Any], str]]:
    lab = labels_dir()

    def base(name: str) -> bytes | None:
        p = lab / name
        return p.read_bytes() if p.is_file() else None

    return {
        "task": (task_text(), _task, "task.json"),
        "articulation": (articulation_text(), _articulation, "track.txt"),
        "kvg_annotations": (base("ann_kvg.kvg"), kvg.parse_annotations, "ann_kvg.kvg"),
        "kvg_meta": (base("meta.kvg"), kvg.read, "meta.kvg"),
        "elan_tab": (base("ann.txt"), elan.parse_tab, "ann.txt"),
        "elan_eaf": (base("elan.eaf"), elan.parse_eaf, "elan.eaf"),
    }


def fuzz_other(kind: str, folder: Path, seeds: range) -> dict[str, int]:
    data, reader, name = other_formats()[kind]
    if data is None:
        pytest.skip(f"the shared data holds no base file for {kind}")
    counts = {"error": 0, "loaded": 0}
    path = folder / name
    for seed in seeds:
        rng = np.random.default_rng(seed)
        path.write_bytes(mutate(data, rng, int(rng.integers(1, 4))))
        try:
            reader(path)
        except ThirdhandError:
            counts["error"] += 1
            continue
        except UnicodeDecodeError:
            if kind != "task":
                raise
            counts["error"] += 1  # parse_task takes text; load_task reports this one
            continue
        counts["loaded"] += 1
    return counts


@pytest.mark.parametrize(
    "kind", ["task", "articulation", "kvg_annotations", "kvg_meta", "elan_tab", "elan_eaf"]
)
def test_fuzz_other_text_formats(kind: str, tmp_path: Path) -> None:
    counts = fuzz_other(kind, tmp_path, range(COUNTS["other"][0]))
    assert counts["error"] > 0 and sum(counts.values()) == COUNTS["other"][0]


@pytest.mark.slow
@pytest.mark.parametrize(
    "kind", ["task", "articulation", "kvg_annotations", "kvg_meta", "elan_tab", "elan_eaf"]
)
def test_fuzz_other_text_formats_long(kind: str, tmp_path: Path) -> None:
    quick, slow = COUNTS["other"]
    counts = fuzz_other(kind, tmp_path, range(quick, slow))
    assert sum(counts.values()) == slow - quick


def test_task_file_load_reports_bad_bytes(tmp_path: Path) -> None:
    from thirdhand.taskfile import load_task

    path = tmp_path / "t.json"
    path.write_bytes(task_text()[:40] + b"\xff\xfe" + task_text()[40:])
    with pytest.raises(ThirdhandError, match="cannot read task file"):
        load_task(path)


# --- hypothesis: shrinking mutations ------------------------------------------------------------

edits = st.lists(
    st.tuples(st.integers(0, 10**6), st.integers(0, 20), st.sampled_from(TOKENS)),
    min_size=1,
    max_size=4,
)


def apply_edits(data: bytes, ops: list[tuple[int, int, bytes]]) -> bytes:
    """Each edit deletes ``n`` bytes at ``pos`` (modulo the length) and inserts ``token``."""
    for pos, n, tok in ops:
        p = pos % (len(data) + 1)
        data = data[:p] + tok + data[p + n :]
    return data


@settings(
    max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(ops=edits)
def test_hypothesis_motive_csv(bases: dict[str, Any], tmp_path: Path, ops: Any) -> None:
    path = tmp_path / "h.csv"
    path.write_bytes(apply_edits(bases["csv"], ops))
    check_recording(path, "motive", bases["demo"])


@settings(
    max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(ops=edits)
def test_hypothesis_poses_dat(bases: dict[str, Any], tmp_path: Path, ops: Any) -> None:
    rec = tmp_path / "rec"
    shutil.rmtree(rec, ignore_errors=True)
    shutil.copytree(bases["rec"], rec)
    poses = rec / "poses.dat"
    poses.write_bytes(apply_edits(poses.read_bytes(), ops))
    check_recording(rec, "mlr", bases["demo"])


@settings(max_examples=150, deadline=None)
@given(ops=edits)
def test_hypothesis_task_file(ops: Any) -> None:
    text = apply_edits(task_text(), ops).decode("utf-8", errors="replace")
    try:
        task = parse_task(text, name="task.json")
    except ThirdhandError:
        return
    assert isinstance(task, TaskFile)
