"""Names from a task file through every export, and runs checked against their robot.

The exports (PDDL, BehaviorTree.CPP XML, tf frames in the ROS 2 bag) either hold
a name exactly, map it to an identifier of their own that no other name gets, or
refuse it in one line. A run file (``execute --record``) is checked against the
robot it names before anything is written for a real arm.
"""

from __future__ import annotations

import itertools
import json
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cli_helpers import call
from test_export_robot import PANDA, _bt_run, _run
from thirdhand.errors import FormatError, TaskFileError
from thirdhand.execute.run_check import MAX_RUN_S, robot_description, run_problem
from thirdhand.export.behavior_tree import check_port_value, tree_xml
from thirdhand.export.pddl_task import DOMAIN, RESERVED, comment_text, pddl_names, problem_pddl
from thirdhand.export.ros2 import WORLD_FRAME, frame_ids, read_execution
from thirdhand.taskfile import TaskFile

#: Names a hostile task file holds: PDDL words, separators, braces, control characters.
HOSTILE = [
    "not",
    "define",
    "and",
    "part",
    "leg 3",
    "leg_3",
    "Leg_3",
    "x\n(define (problem pwned))",
    "a;b",
    "{child}",
    " {parent} ",
    "bell\x07",
    "tab\tname",
    "<&\"'>",
    "é",
    "3leg",
    "/box/side",
    "box/side",
    "panda_link0",
    "world",
]


def chain_task(names: list[str]) -> TaskFile:
    """A plan that mounts every name on the one before it (constraint ids ``c<i>``)."""
    return TaskFile.new(
        objects=[{"name": n} for n in names],
        constraints=[
            {"id": f"c{i}", "parent": a, "child": b, "type": "fixed"}
            for i, (a, b) in enumerate(itertools.pairwise(names))
        ],
        plan=[
            {"parent": a, "child": b, "constraint": f"c{i}"}
            for i, (a, b) in enumerate(itertools.pairwise(names))
        ],
    )


# --- PDDL ---------------------------------------------------------------------------


def _parse_pddl(tmp_path: Path, problem: str) -> Any:
    import pddl

    (tmp_path / "d.pddl").write_text(DOMAIN)
    (tmp_path / "p.pddl").write_text(problem)
    pddl.parse_domain(tmp_path / "d.pddl")
    return pddl.parse_problem(tmp_path / "p.pddl")


def test_a_newline_in_a_name_does_not_inject_pddl(tmp_path) -> None:
    names = ["seat", "x\n(define (problem pwned))", "not", "define", "and"]
    text = problem_pddl(chain_task(names))
    code = [line for line in text.splitlines() if not line.startswith(";")]
    assert [line for line in code if "(define" in line or "(problem" in line] == [
        "(define (problem task)"
    ]
    prob = _parse_pddl(tmp_path, text)
    assert prob.name == "task"
    objects = {o.name for o in prob.objects}
    assert {"seat", "not_", "define_", "and_"} <= objects
    assert len(objects) == len(names) + len(names) - 1  # parts and slots, all distinct
    # every original is in the header, escaped to one line
    assert ";   part x__define__problem_pwned = x\\n(define (problem pwned))\n" in text


@pytest.mark.slow
@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    st.lists(
        st.sampled_from(HOSTILE) | st.text(min_size=1, max_size=8),
        min_size=2,
        max_size=6,
        unique=True,
    )
)
def test_any_names_make_a_problem_pddl_parses_and_a_planner_solves(tmp_path, names) -> None:
    from pyperplan.planner import HEURISTICS, SEARCHES, search_plan

    text = problem_pddl(chain_task(names))
    prob = _parse_pddl(tmp_path, text)
    ids = [o.name for o in prob.objects]
    assert len(ids) == len(set(ids)) == 2 * len(names) - 1
    assert not set(ids) & RESERVED
    comments = [line for line in text.splitlines() if line.startswith(";")]
    assert len(comments) == 1 + 2 * len(names) - 1  # nothing in a name broke a line
    plan = search_plan(
        tmp_path / "d.pddl", tmp_path / "p.pddl", SEARCHES["astar"], HEURISTICS["hff"]
    )
    assert plan is not None and len(plan) == len(names) - 1


@given(st.lists(st.text(min_size=1, max_size=6), min_size=1, max_size=8, unique=True))
def test_pddl_names_are_identifiers_and_injective(names) -> None:
    ids = pddl_names(names)
    assert len(set(ids)) == len(ids)
    assert all(i[0].isalpha() and i not in RESERVED and i == i.lower() for i in ids)
    assert all(comment_text(n).isascii() and comment_text(n).isprintable() for n in names)


# --- BehaviorTree.CPP XML -----------------------------------------------------------


def test_a_control_character_or_a_blackboard_reference_is_one_line() -> None:
    for bad, why in [("bell\x07", r"U\+0007"), ("{child}", "blackboard"), (" {x} ", "blackboard")]:
        with pytest.raises(TaskFileError, match=why) as err:
            tree_xml(chain_task(["seat", bad]))
        assert "\n" not in str(err.value) and "plan[0].child" in str(err.value)
    for fine in ["a{b}", "{", "<&\"'>", "é", "x}"]:
        assert check_port_value(fine, where="x") == fine


@settings(max_examples=30, deadline=None)
@given(
    st.lists(
        st.sampled_from(HOSTILE) | st.text(min_size=1, max_size=8),
        min_size=2,
        max_size=5,
        unique=True,
    )
)
def test_any_names_make_well_formed_xml_with_the_names_or_one_line(names) -> None:
    task = chain_task(names)
    try:
        xml = tree_xml(task)
    except TaskFileError as exc:
        assert "\n" not in str(exc)
        assert any(
            any(ord(ch) < 32 or 0x7F <= ord(ch) < 0xA0 or 0xD800 <= ord(ch) < 0xE000 for ch in n)
            or (n.strip(" ")[:1] == "{" and n.strip(" ")[-1:] == "}")
            for n in names
        )
        return
    root = ET.fromstring(xml)
    steps = root.findall(".//BehaviorTree[@ID='Assembly']//SubTree")
    assert [(s.get("parent"), s.get("child")) for s in steps] == [
        (p.parent, p.child) for p in task.plan
    ]
    assert len(_bt_run(xml)) == 3 * len(task.plan)


# --- tf frames ----------------------------------------------------------------------

LINKS = robot_description("panda").links


@given(
    st.lists(
        st.sampled_from(HOSTILE) | st.text(min_size=1, max_size=8),
        min_size=1,
        max_size=8,
        unique=True,
    ),
    st.randoms(),
)
def test_tf_frames_are_valid_unique_and_do_not_depend_on_order(names, rnd) -> None:
    frames = frame_ids(names, reserved=LINKS)
    assert len(set(frames)) == len(frames)
    assert not set(frames) & {WORLD_FRAME, *LINKS}
    assert all(f and f[0] != "/" and f.isascii() and " " not in f for f in frames)
    shuffled = list(names)
    rnd.shuffle(shuffled)
    again = dict(zip(shuffled, frame_ids(shuffled, reserved=LINKS), strict=True))
    assert again == dict(zip(names, frames, strict=True))


def test_leg_3_keeps_its_frame_beside_leg_space_3() -> None:
    a = frame_ids(["leg 3", "leg_3"])
    b = frame_ids(["leg_3", "leg 3"])
    assert a[1] == b[0] == "leg_3" and a[0] == b[1] != "leg_3" and a[0].startswith("leg_3_")
    assert frame_ids(["panda_link0", "box/side"], reserved=LINKS)[1] == "box/side"
    assert frame_ids(["panda_link0"], reserved=LINKS)[0].startswith("panda_link0_")


# --- a run against its robot --------------------------------------------------------


def _edit(doc: dict[str, Any], **arrays: Any) -> dict[str, Any]:
    return {**doc, **arrays}


RUN_CASES = [
    ("three joints", lambda d: _edit(d, joint_names=PANDA[:3], q=[r[:3] for r in d["q"]]),
     "'joint_names' has 3 joints; panda has 7"),
    ("names not the robot's", lambda d: _edit(d, joint_names=["j1", *PANDA[1:]]),
     "'joint_names'[0] is 'j1'; panda's joint 0 is 'panda_joint1'"),
    ("a joint at 100 rad", lambda d: _edit(d, q=[[100.0, *r[1:]] for r in d["q"]]),
     "'q'[0] at 0 s: panda_joint1 = 100 is outside its limits [-2.8973, 2.8973]"),
    ("a step listed twice", lambda d: _edit(d, steps=[*d["steps"], d["steps"][0]]),
     "steps[3]: step 0 is also steps[0]; each step is listed once"),
    ("times scaled by 1e-6", lambda d: _edit(d, t=[v * 1e-6 for v in d["t"]], segments=[]),
     "rad/s since the sample before; its limit is"),
    ("a time below 0", lambda d: _edit(d, t=[v - 1.0 for v in d["t"]]),
     "'t'[0] is -1.0 s; a run starts at 0 s or later"),
    ("a time of 2**31 s", lambda d: _edit(d, t=[*d["t"][:-1], 2.0**31]),
     f"'t'[99] is 2.14748e+09 s; a run lasts at most {MAX_RUN_S:.0f} s"),
    ("a segment outside the run", lambda d: _edit(d, segments=[{**d["segments"][0], "t_end": 9.0}]),
     "segments[0]: [0.0, 9.0] s is not a time span within the run's"),
    ("a segment of a step not listed",
     lambda d: _edit(d, segments=[{**d["segments"][0], "step": 7}]),
     "segments[0]: step 7 is not in 'steps'"),
]  # fmt: skip


@pytest.mark.parametrize(("label", "change", "message"), RUN_CASES, ids=[c[0] for c in RUN_CASES])
def test_a_hand_edited_run_is_refused_in_one_line(tmp_path, capsys, label, change, message) -> None:
    path, doc, _ = _run(tmp_path)
    read_execution(path)  # the run as recorded is accepted
    path.write_text(json.dumps(change(doc)))
    with pytest.raises(FormatError) as err:
        read_execution(path)
    assert message in str(err.value) and "\n" not in str(err.value), label
    rc, _, out = call(capsys, "convert", str(path), str(tmp_path / "run.mcap"))
    assert rc == 1 and out.count("\n") == 1 and message in out
    assert not (tmp_path / "run.mcap").exists()


@settings(max_examples=80, deadline=None)
@given(
    st.integers(2, 30),
    st.floats(1e-3, 1e3),
    st.floats(-5.0, 5.0),
    st.integers(0, 6),
)
def test_run_check_accepts_exactly_runs_within_the_limits(n, dt, offset, joint) -> None:
    panda = robot_description("panda")
    mid = (panda.lower + panda.upper) / 2
    t = np.arange(n) * dt
    q = np.tile(mid, (n, 1))
    q[:, joint] += np.linspace(0.0, offset, n)
    problem = run_problem(panda, PANDA, t, q)
    inside = panda.lower[joint] - 1e-3 <= mid[joint] + offset <= panda.upper[joint] + 1e-3
    speed = abs(offset) / (dt * (n - 1))
    slow = speed * dt <= 1.05 * panda.velocity[joint] * dt + 4e-6
    assert (problem is None) == (inside and slow and t[-1] <= MAX_RUN_S), problem


def test_rrd_checks_a_run_against_its_robot_too(tmp_path, capsys) -> None:
    from test_export_rrd import _run_with_robot

    path, _, _ = _run_with_robot(tmp_path, stored_base=True)
    doc = json.loads(path.read_text())
    doc["q"] = [[100.0, *row[1:]] for row in doc["q"]]
    path.write_text(json.dumps(doc))
    target = tmp_path / "x.rrd"
    rc, _, err = call(capsys, "convert", str(path.with_suffix(".parquet")), str(target),
                      "--with", str(path))  # fmt: skip
    assert rc == 1 and err.count("\n") == 1
    assert "panda_joint1 = 100 is outside its limits" in err and not target.exists()
