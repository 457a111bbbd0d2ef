"""The IROS 2015 user-study reader and the 19-number constraint rows, on the real file."""

from __future__ import annotations

import functools
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml

from thirdhand.errors import FormatError, ThirdhandError
from thirdhand.io.iros15 import WAIT, StudyStep, UserStudy, read_user_study, session_task
from thirdhand.taskfile import Constraint, dump_task, load_task, parse_task, save_task

Row = list[float]


@functools.cache
def _load_raw(path: Path) -> dict[str, Any]:
    with open(path) as fh:
        data: dict[str, Any] = yaml.load(fh, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
    return data


_read_study = functools.cache(read_user_study)


@pytest.fixture
def study_path(shared_data: Path) -> Path:
    path = shared_data / "3rdhand" / "iros15_user_study.yaml"
    if not path.is_file():
        pytest.skip(f"user study not found at {path}")
    return path


@pytest.fixture
def raw(study_path: Path) -> dict[str, Any]:
    """The YAML as parsed by PyYAML alone (cached: tests must not modify it)."""
    return _load_raw(study_path)


@pytest.fixture
def study(study_path: Path) -> UserStudy:
    return _read_study(study_path)


def raw_sessions(raw: dict[str, Any]) -> Iterator[tuple[str, str, str, dict[str, Any]]]:
    for subject, scenes in raw.items():
        for scene, sessions in scenes.items():
            for name, session in sessions.items():
                yield subject, scene, name, session


def raw_tables(raw: dict[str, Any]) -> Iterator[tuple[str, dict[str, Row]]]:
    """Every constraint table of the raw YAML, with a label of where it is."""
    for subject, scene, name, session in raw_sessions(raw):
        for key in ("symbols", "raw_symbols"):
            if key in session:
                yield f"{subject}/{scene}/{name}/{key}", session[key]
        for k, attempt in session.items():
            if k.isdigit() and "corrected_st" in attempt:
                yield f"{subject}/{scene}/{name}/{k}/corrected_st", attempt["corrected_st"]


def test_subjects_counted_from_the_raw_text(study_path: Path, study: UserStudy) -> None:
    top_level = re.findall(r"^([A-Za-z_]\w*):\s*$", study_path.read_text(), flags=re.MULTILINE)
    assert len(top_level) == 15
    assert list(study.subjects) == top_level


def test_sessions_and_attempts_match_the_raw_yaml(raw: dict[str, Any], study: UserStudy) -> None:
    raw_list = list(raw_sessions(raw))
    read_list = list(study.sessions())
    assert [(s, sc, n) for s, sc, n, _ in raw_list] == [(s, sc, se.name) for s, sc, se in read_list]
    assert len(read_list) == 67
    for (_, _, _, session), (_, _, read) in zip(raw_list, read_list, strict=True):
        keys = sorted(int(k) for k in session if k.isdigit())
        assert [a.index for a in read.attempts] == keys
        assert read.num_attempts == session["num_attempts"]
    assert sum(1 for _ in study.attempts()) == 93
    scenes = {sc for _, sc, _ in read_list}
    assert scenes == {"blue_chair", "green_bench", "test"}


def test_every_real_row_converts_and_back_bit_exactly(raw: dict[str, Any]) -> None:
    lengths = {7: 0, 19: 0}
    for where, table in raw_tables(raw):
        for symbol, row in table.items():
            c = Constraint.from_row(row, parent="seating", child="leg1", symbol=symbol)
            back = c.to_row()
            assert len(back) == 19, where
            lengths[len(row)] += 1
            if len(row) == 7:
                assert back == row + [0.0] * 12, f"{where}/{symbol}"
                assert c.type == "fixed" and c.free_dofs.free() == []
            else:
                assert back == row, f"{where}/{symbol}"
    assert lengths == {7: 124, 19: 668}


def test_reader_tables_hold_every_row_exactly(raw: dict[str, Any], study: UserStudy) -> None:
    read_tables = []
    for _, _, session in study.sessions():
        if session.plan is not None:
            read_tables.append(session.symbols)
        if session.raw_plan is not None:
            read_tables.append(session.raw_symbols)
        read_tables.extend(a.corrected_st for a in session.attempts if a.corrected_plan is not None)
    raw_list = list(raw_tables(raw))
    assert len(read_tables) == len(raw_list)
    n_used = n_unused = 0
    for (where, rows), table in zip(raw_list, read_tables, strict=True):
        assert len(table) == len(rows), where
        for symbol, row in rows.items():
            if symbol in table.constraints:
                n_used += 1
                assert table.constraints[symbol].to_row()[: len(row)] == row, f"{where}/{symbol}"
            else:
                n_unused += 1
                assert list(table.unused[symbol]) == row, f"{where}/{symbol}"
    assert (n_used, n_unused) == (679, 113)


def test_reference_values_of_one_attempt(study: UserStudy) -> None:
    session = study.subjects["adele"]["blue_chair"]["A"]
    assert session.plan is not None and session.plan[0] == StudyStep("mc2", "seating", "leg1")
    assert session.plan[-1] == WAIT
    attempt = session.attempts[0]
    assert attempt.state == "success"
    assert attempt.corrected_plan == session.plan
    assert attempt.effort["leg1"]["movex"] == 11
    assert attempt.effort_totals()["click"] == 26
    prec = attempt.corrected_precision
    assert prec is not None
    assert prec.reference_id == ("c3", "c1", "c2", "c4", "c0")
    assert prec.position[0] == 0.007897460392127359
    c = attempt.corrected_st.constraints["mc2"]
    assert (c.parent, c.child, c.type, c.source) == ("seating", "leg1", "revolute", "corrected")
    assert c.free_dofs.ry == (-3.1416, 3.1416)
    assert c.pos == (0.11500000208616257, 0.004999999888241291, 0.11699999868869781)
    assert session.symbols.constraints["mc1"].type == "fixed"
    assert session.symbols.constraints["mc1"].source == "learned"
    assert attempt.loadings == (1424278244.2105181,)


def test_raw_learner_output(study: UserStudy) -> None:
    session = study.subjects["adele"]["blue_chair"]["B"]
    assert session.raw_plan is not None
    assert session.raw_plan[0] == StudyStep("c0", "seating", "leg1", action="action1")
    c0 = session.raw_symbols.constraints["c0"]
    assert c0.type == "fixed" and c0.child == "leg1"
    assert len(c0.to_row()) == 19
    assert set(session.raw_symbols.unused) == {"c3", "c4"}
    assert session.raw_error is not None and session.raw_error.object == ("leg3", "back", "leg1")


BASE = """\
s1:
  blue_chair:
    A:
      '0':
        corrected_plan:
        - [mc1, seating, leg1]
        - wait
        corrected_st:
          mc1: [0.1, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0]
        effort:
          leg1: {click: 2}
        state: success
      num_attempts: 1
      plan:
      - [mc1, seating, leg1]
      - wait
      symbols:
        mc1: [0.1, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0]
"""


def test_minimal_study(tmp_path: Path) -> None:
    path = tmp_path / "study.yaml"
    path.write_text(BASE)
    study = read_user_study(path)
    (_, _, session, attempt), *rest = list(study.attempts())
    assert rest == []
    assert attempt.corrected_st.constraints["mc1"].to_row()[:7] == [
        0.1,
        0.0,
        0.1,
        0.0,
        0.0,
        0.0,
        1.0,
    ]
    assert attempt.corrected_st.constraints["mc1"].to_row()[7:] == [0.0] * 12
    assert session.symbols.constraints["mc1"].child == "leg1"


@pytest.mark.parametrize(
    ("old", "new", "expected"),
    [
        (
            "- [mc1, seating, leg1]\n      - wait",
            "- [mc1, seating]\n      - wait",
            "s1/blue_chair/A/plan/0",
        ),
        ("- wait\n      symbols", "- stop\n      symbols", "s1/blue_chair/A/plan/1"),
        ("0.0, 0.0, 1.0]\n", "0.0, 0.0]\n", "s1/blue_chair/A/0/corrected_st/mc1"),
        ("0.0, 0.0, 1.0]\n", "0.0, 0.0, 0.0]\n", "quaternion has zero norm"),
        ("{click: 2}", "{click: -2}", "s1/blue_chair/A/0/effort/leg1/click"),
        ("num_attempts: 1", "num_attempts: one", "s1/blue_chair/A/num_attempts"),
        ("state: success", "state: [1]", "s1/blue_chair/A/0/state"),
    ],
)
def test_malformed_study_names_where(tmp_path: Path, old: str, new: str, expected: str) -> None:
    assert old in BASE
    path = tmp_path / "study.yaml"
    path.write_text(BASE.replace(old, new, 1))
    with pytest.raises(FormatError, match=re.escape(expected)) as info:
        read_user_study(path)
    assert str(info.value).startswith(str(path))


def test_not_yaml_gives_the_line(tmp_path: Path) -> None:
    path = tmp_path / "study.yaml"
    path.write_text("s1:\n  blue_chair: [1, 2\n  other: 3\n")
    with pytest.raises(FormatError, match=r"study\.yaml line \d+: not valid YAML"):
        read_user_study(path)


def test_every_plan_becomes_a_valid_task_file(study: UserStudy, tmp_path: Path) -> None:
    n = 0
    for subject, scene, session in study.sessions():
        variants: list[tuple[int | None, Any, Any]] = [(None, session.plan, session.symbols)]
        variants += [(a.index, a.corrected_plan, a.corrected_st) for a in session.attempts]
        for attempt, plan, table in variants:
            if plan is None:
                continue
            task = session_task(
                study, subject=subject, scene=scene, session=session.name, attempt=attempt
            )
            n += 1
            steps = [s for s in plan if s != WAIT]
            assert [(s.parent, s.child, s.symbol) for s in task.plan] == [
                (s.parent, s.child, s.symbol) for s in steps
            ]
            assert {c.id: c.to_row() for c in task.constraints} == {
                k: c.to_row() for k, c in table.constraints.items()
            }
            block = task.stages.other("iros15")
            assert isinstance(block, dict)
            assert block["waits"] == [i for i, s in enumerate(plan) if s == WAIT]
            assert parse_task(dump_task(task)) == task
    assert n == 141
    task = session_task(study, subject="adele", scene="blue_chair", session="B", attempt=0)
    save_task(task, tmp_path / "adele.json")
    back = load_task(tmp_path / "adele.json")
    assert back == task
    assert all(c.source == "corrected" for c in back.constraints)
    assert [o.name for o in back.objects] == ["seating", "leg1", "leg2", "leg3", "leg4", "back"]
    block = back.stages.other("iros15")
    assert isinstance(block, dict)
    assert block["state"] == "success"
    assert set(block["unused_symbols"]) == {"c3", "c4"}  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("where", "expected"),
    [
        ({"subject": "nobody", "scene": "blue_chair", "session": "A"}, "no session nobody/"),
        ({"subject": "adele", "scene": "blue_chair", "session": "A", "attempt": 7}, "no attempt 7"),
        ({"subject": "elias", "scene": "test", "session": "test"}, "elias/test/test has no plan"),
    ],
)
def test_session_task_errors(study: UserStudy, where: dict[str, Any], expected: str) -> None:
    with pytest.raises(ThirdhandError, match=re.escape(expected)):
        session_task(study, **where)
