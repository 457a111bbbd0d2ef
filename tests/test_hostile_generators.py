"""Structure-aware hostile inputs (hypothesis), beside the byte mutations of test_fuzz.py.

Four generators, one per class of input a user hands thirdhand:

- output paths (empty, ``.``, ``..``, ``-``, a file as a parent, a folder where a
  file is meant, a device, a FIFO, a socket, links), with and without ``--force``;
- recordings (time axes, quaternions of any norm, labels at any time), through the
  core type and through a Parquet file written behind the writer's back;
- task files and segmentation models (any JSON shape, nesting included);
- round trips over every pair of writable formats.

Each example must end in the package's error, one line, or in a result that
keeps the class's invariant. Examples are bounded and derandomized, so the suite
costs the same on every run.
"""

from __future__ import annotations

import json
import math
import os
import socket
import stat
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from thirdhand import BodyInfo, Demonstration, io, se3
from thirdhand.demonstration import (
    MAX_QUAT_NORM_ERROR,
    ConstraintEvent,
    InteractionInterval,
    Labels,
    PlanStep,
    label_tolerance,
)
from thirdhand.errors import DemonstrationError, FormatError, OutputError, ThirdhandError
from thirdhand.fileops import check_output, write_bytes

SETTINGS = settings(
    max_examples=40,
    derandomize=True,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)


def one_line(exc: BaseException) -> None:
    assert isinstance(exc, ThirdhandError), repr(exc)
    assert "\n" not in str(exc), str(exc)


# ----------------------------------------------------------------- output paths
#: Path pieces a careless or hostile user types.
PIECES = ["", ".", "..", "-", "out.csv", "out", "file", "dir", "fifo", "sock", "null", "link"]


def _scene(root: Path) -> dict[str, Path]:
    """A folder holding one of every kind of thing an output path can name."""
    (root / "file").write_text("user data")
    (root / "dir").mkdir()
    (root / "dir" / "keep.txt").write_text("user data")
    os.mkfifo(root / "fifo")
    s = socket.socket(socket.AF_UNIX)
    s.bind(str(root / "sock"))
    s.close()
    (root / "null").symlink_to("/dev/null")
    (root / "link").symlink_to(root / "fifo")
    return {"file": root / "file", "dir": root / "dir"}


def _kinds(root: Path) -> dict[str, int]:
    return {p.name: os.lstat(p).st_mode for p in root.rglob("*")}


@SETTINGS
@given(pieces=st.lists(st.sampled_from(PIECES), min_size=1, max_size=3), force=st.booleans())
def test_output_paths_are_refused_in_one_line_or_written_safely(
    pieces: list[str], force: bool
) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp)
        root = base / "l1" / "l2" / "l3"  # deep enough that '..' stays inside the sandbox
        root.mkdir(parents=True)
        _scene(root)
        before = _kinds(base)
        raw = str(root) + "/" + "/".join(pieces)
        try:
            p = check_output(raw, force=force)
            write_bytes(p, b"new")
        except OutputError as exc:
            one_line(exc)
            assert _kinds(base) == before  # nothing moved, nothing left
            return
        # Written: a regular file now, and nothing special was moved aside.
        assert stat.S_ISREG(os.lstat(p).st_mode) and Path(p).read_bytes() == b"new"
        assert Path(raw).name not in ("", ".", "..", "-") and not raw.endswith(("/.", "/.."))
        after = _kinds(base)
        for name, mode in before.items():
            if not stat.S_ISREG(mode) and not stat.S_ISDIR(mode) and not stat.S_ISLNK(mode):
                assert after.get(name) == mode, name  # a FIFO or socket stays where it was
        assert (root / "dir" / "keep.txt").is_file()


# ------------------------------------------------------------------- recordings
finite = st.floats(-1e3, 1e3, allow_nan=False)
any_float = st.one_of(
    finite, st.sampled_from([math.nan, math.inf, -math.inf, 1e9, 149112.0, 0.0, -1e-300])
)


@st.composite
def raw_recordings(draw: st.DrawFn) -> dict[str, Any]:
    """Arrays and labels as a reader might hand them over: mostly sane, sometimes not."""
    n = draw(st.integers(1, 8))
    t = np.arange(n) / 100.0
    if draw(st.booleans()):
        t = t.copy()
        t[draw(st.integers(0, n - 1))] = draw(any_float)
    rng = np.random.default_rng(draw(st.integers(0, 2**16)))
    pos = rng.uniform(-1, 1, (n, 3))
    quat = se3.random_quat(rng, n)
    if draw(st.booleans()):
        quat = quat * draw(st.sampled_from([1.0 + 1e-9, 1.005, 1.02, 0.5, 149112.0, 0.0]))
    if draw(st.booleans()):
        pos[draw(st.integers(0, n - 1))] = np.nan  # an untracked frame
    inter = tuple(
        InteractionInterval("f", "p", draw(any_float), draw(any_float))
        for _ in range(draw(st.integers(0, 2)))
    )
    cons = tuple(
        ConstraintEvent(draw(any_float), "p", "f", "fixed") for _ in range(draw(st.integers(0, 1)))
    )
    plan = tuple(
        PlanStep("p", "f", "c1", draw(st.one_of(st.none(), any_float)))
        for _ in range(draw(st.integers(0, 1)))
    )
    return {"t": t, "pos": pos, "quat": quat, "labels": Labels(inter, cons, plan)}


def _check_invariants(d: Demonstration) -> None:
    """What every loaded recording holds, whatever the format it came from."""
    assert np.all(np.isfinite(d.t)) and np.all(np.diff(d.t) > 0)
    tol = label_tolerance(d.t)
    for name in d.body_names:
        v = d.valid(name)
        norms = np.linalg.norm(d.quat(name)[v], axis=1)
        assert np.all(np.abs(norms - 1.0) < 1e-9)
    times = [x for i in d.labels.interactions for x in (i.start, i.end)]
    times += [c.time for c in d.labels.constraints]
    times += [s.time for s in d.labels.plan if s.time is not None]
    assert all(d.t[0] - tol <= x <= d.t[-1] + tol for x in times)
    assert all(i.start <= i.end for i in d.labels.interactions)


def _build(raw: dict[str, Any]) -> Demonstration:
    return Demonstration(
        raw["t"],
        [BodyInfo("f", "finger", "right"), BodyInfo("p")],
        {"f": raw["pos"], "p": raw["pos"][::-1].copy()},
        {"f": raw["quat"], "p": raw["quat"][::-1].copy()},
        labels=raw["labels"],
    )


@SETTINGS
@given(raw=raw_recordings())
def test_recordings_are_validated_by_the_core_type(raw: dict[str, Any]) -> None:
    try:
        d = _build(raw)
    except DemonstrationError as exc:
        one_line(exc)
        return
    _check_invariants(d)
    norms = np.linalg.norm(raw["quat"], axis=1)
    assert np.all(np.abs(norms[d.valid("f")] - 1.0) <= MAX_QUAT_NORM_ERROR)


@settings(SETTINGS, max_examples=25)
@given(raw=raw_recordings())
def test_parquet_is_no_back_door(raw: dict[str, Any]) -> None:
    """A Parquet file written behind the writer's back: the reader validates like the core."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from thirdhand.demonstration import labels_to_dict

    cols: dict[str, Any] = {"t": pa.array(raw["t"])}
    for name, order in (("f", slice(None)), ("p", slice(None, None, -1))):
        for j, c in enumerate(("x", "y", "z")):
            cols[f"{name}:{c}"] = pa.array(raw["pos"][order, j])
        for j, c in enumerate(("qx", "qy", "qz", "qw")):
            cols[f"{name}:{c}"] = pa.array(raw["quat"][order, j])
        cols[f"{name}:valid"] = pa.array(np.isfinite(raw["pos"][order]).all(axis=1))
    header = {
        "format": "thirdhand.demonstration/1",
        "bodies": [{"name": "f", "kind": "finger", "hand": "right"}, {"name": "p"}],
        "labels": labels_to_dict(raw["labels"]),
        "meta": {},
    }
    table = pa.table(cols).replace_schema_metadata({b"thirdhand": json.dumps(header).encode()})
    with tempfile.TemporaryDirectory() as tmp:
        p = Path(tmp) / "raw.parquet"
        pq.write_table(table, p)
        try:
            d = io.load(p)
        except FormatError as exc:
            one_line(exc)
            with pytest.raises(DemonstrationError):
                _build(raw)  # the core type refuses the same arrays
            return
    _check_invariants(d)


# ------------------------------------------------------------ task files, models
json_leaf = st.one_of(
    st.none(), st.booleans(), st.integers(-(2**40), 2**40), finite, st.text(max_size=6)
)
json_values = st.recursive(
    json_leaf,
    lambda inner: st.one_of(
        st.lists(inner, max_size=3), st.dictionaries(st.text(max_size=6), inner, max_size=3)
    ),
    max_leaves=12,
)


@st.composite
def task_documents(draw: st.DrawFn) -> str:
    """A task file: a valid one with a field replaced, or nested deeper than any parser likes."""
    from thirdhand.taskfile import SCHEMA

    doc: dict[str, Any] = {
        "schema": SCHEMA,
        "objects": [{"name": "base"}, {"name": "leg"}],
        "constraints": [{"id": "c1", "parent": "base", "child": "leg", "type": "fixed"}],
        "plan": [{"parent": "base", "child": "leg", "constraint": "c1"}],
    }
    where = draw(st.sampled_from(["objects", "constraints", "plan", "schema", "new", "nest"]))
    if where == "nest":
        depth = draw(st.integers(60, 3000))
        return json.dumps(doc)[:-1] + ', "x": ' + "[" * depth + "]" * depth + "}"
    value = draw(json_values)
    if where in ("objects", "constraints", "plan") and draw(st.booleans()):
        doc[where][0][draw(st.sampled_from(["name", "id", "parent", "type", "pos"]))] = value
    else:
        doc[where] = value
    return json.dumps(doc)


@SETTINGS
@given(text=task_documents())
def test_task_files_load_or_fail_in_one_line(text: str) -> None:
    from thirdhand.errors import TaskFileError
    from thirdhand.taskfile import parse_task

    try:
        task = parse_task(text, name="task.json")
    except TaskFileError as exc:
        one_line(exc)
        return
    assert task.objects


@settings(SETTINGS, max_examples=25)
@given(
    doc=st.one_of(
        json_values,
        st.integers(60, 3000).map(lambda k: "[" * k + "]" * k),
    )
)
def test_models_load_or_fail_in_one_line(doc: Any) -> None:
    from thirdhand.segment.model import load_model

    with tempfile.TemporaryDirectory() as tmp:
        p = Path(tmp) / "model.json"
        p.write_text(doc if isinstance(doc, str) else json.dumps(doc))
        try:
            load_model(p)
        except ThirdhandError as exc:
            one_line(exc)
            return
    pytest.fail(f"a random document loaded as a segmentation model: {doc!r}")


# ------------------------------------------------- round trips over format pairs
#: Every writable target: extension (empty: an MLR folder) and the tolerance it keeps.
WRITABLE = {".parquet": 0.0, ".csv": 0.0, ".c3d": 1e-6, ".mcap": 0.0, ".db3": 0.0,
            ".bag": 0.0, ".log": 0.0, "": 0.0}  # fmt: skip


def _same(a: Demonstration, b: Demonstration, atol: float) -> bool:
    """Faithful: bodies, labels, time (to the nanosecond) and poses (q = -q) alike."""
    if a.bodies != b.bodies or a.labels != b.labels or a.t.shape != b.t.shape:
        return False
    if not np.allclose(a.t, b.t, rtol=0, atol=1e-9):
        return False
    for n in a.body_names:
        if not np.array_equal(a.valid(n), b.valid(n)):
            return False
        v = a.valid(n)
        if not np.allclose(a.pos(n)[v], b.pos(n)[v], rtol=0, atol=atol):
            return False
        qa, qb = a.quat(n)[v], b.quat(n)[v]
        near = np.minimum(
            np.abs(qa - qb).max(axis=1, initial=0), np.abs(qa + qb).max(axis=1, initial=0)
        )
        if np.any(near > max(atol, 0.0) + 1e-15):
            return False
    return True


@st.composite
def writable_demos(draw: st.DrawFn) -> Demonstration:
    """Recordings that some formats carry and others cannot: kinds, labels, odd rates."""
    n = draw(st.integers(2, 12))
    rate = draw(st.sampled_from([10.0, 120.0, 100.0]))
    t = np.arange(n) / rate + draw(st.sampled_from([0.0, 0.0, 1.5]))
    rng = np.random.default_rng(draw(st.integers(0, 2**16)))
    single = draw(st.booleans())
    names = ["x"] if single else ["rh_index", "seat"]
    kinds = {"x": "part", "rh_index": "finger", "seat": draw(st.sampled_from(["part", "tool"]))}
    bodies = [
        BodyInfo(m, kinds[m], "right" if kinds[m] == "finger" else None)  # type: ignore[arg-type]
        for m in names
    ]
    pos = {m: rng.uniform(-1, 1, (n, 3)) for m in names}
    if draw(st.booleans()):
        pos[names[-1]][n // 2] = np.nan
    labels = Labels()
    if not single and draw(st.booleans()):
        labels = Labels(interactions=(InteractionInterval("rh_index", "seat", t[0], t[-1]),))
    return Demonstration(t, bodies, pos, {m: se3.random_quat(rng, n) for m in names}, labels=labels)


def _round_trips(demo: Demonstration) -> None:
    """A -> B: each write refuses in one line (FormatError) or the recording comes back whole."""
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        for i, (ext_a, tol_a) in enumerate(WRITABLE.items()):
            first = root / f"a{i}" / f"x{ext_a}"
            try:
                io.save(demo, first)
            except FormatError as exc:
                one_line(exc)
                continue
            once = io.load(first)
            assert _same(demo, once, tol_a), f"{ext_a or 'MLR'} dropped something silently"
            for j, (ext_b, tol_b) in enumerate(WRITABLE.items()):
                second = root / f"b{i}_{j}" / f"x{ext_b}"
                try:
                    io.save(once, second)
                except FormatError as exc:
                    one_line(exc)
                    continue
                twice = io.load(second)
                assert _same(demo, twice, tol_a + tol_b), (
                    f"{ext_a or 'MLR'} -> {ext_b or 'MLR'} dropped something silently"
                )


@settings(SETTINGS, max_examples=3)
@given(demo=writable_demos())
def test_round_trip_over_every_pair_of_writable_formats(demo: Demonstration) -> None:
    _round_trips(demo)


@pytest.mark.slow
@settings(SETTINGS, max_examples=12)
@given(demo=writable_demos())
def test_round_trip_over_every_pair_of_writable_formats_long(demo: Demonstration) -> None:
    _round_trips(demo)
