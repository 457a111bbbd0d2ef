"""Robot hand-off: a run as a ROS 2 MCAP, a plan as a BehaviorTree.CPP v4 tree and as PDDL.

Each export is read back by a reader that is not ours: the MCAP by
``mcap-ros2-support``'s decoder, by ``rosbags`` and by our own reader; the tree
by BehaviorTree.CPP itself (``behaviortreepy``) with stub nodes; the PDDL by the
``pddl`` parser, and solved by ``pyperplan``.
"""

from __future__ import annotations

import functools
import json
import os
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from cli_helpers import call, settings_file
from thirdhand import io
from thirdhand.demonstration import BodyInfo, Demonstration
from thirdhand.export.behavior_tree import ACTIONS, layers
from thirdhand.export.pddl_task import domain_path
from thirdhand.export.ros2 import ORIGIN_NS, WORLD_FRAME
from thirdhand.taskfile import TaskFile, save_task

PANDA = [f"panda_joint{k}" for k in range(1, 8)]
PANDA_HOME = (0.0, -0.785398, 0.0, -2.35619, 0.0, 1.5707, 0.785398)
BAXTER_HOME = (0.0, -0.55, 0.0, 0.75, 0.0, 1.26, 0.0)
NS = 1_000_000_000


# --- a hand-made run: exact values to compare against --------------------------------


def _run(
    folder: Path, *, success: bool = True, joints: list[str] = PANDA
) -> tuple[Path, dict[str, Any], Demonstration]:
    """A Panda run of 3 steps (the 2nd by a person) at 50 Hz, with its replay.

    The joints swing by 0.1 rad around the robot's home, inside its limits.
    """
    home = PANDA_HOME if joints == PANDA else BAXTER_HOME
    t = np.round(np.arange(100) * 0.02, 6)
    q = np.round(np.asarray(home) + 0.1 * np.sin(np.outer(t, np.arange(1, 8)) + np.arange(7)), 6)
    segments = [
        {"step": 0, "segment": "approach", "t_start": 0.0, "t_end": 0.48, "attached": None},
        {"step": 0, "segment": "insert", "t_start": 0.5, "t_end": 0.98, "attached": "leg 1"},
        {"step": 2, "segment": "approach", "t_start": 1.0, "t_end": 1.78, "attached": None},
        {"step": -1, "segment": "home", "t_start": 1.8, "t_end": 1.98, "attached": None},
    ]
    steps = [
        {"index": 0, "parent": "seat", "child": "leg 1", "constraint": "c1", "status": "done"},
        {"index": 1, "parent": "seat", "child": "leg2", "constraint": "c2"},
        {"index": 2, "parent": "seat", "child": "back", "constraint": "c3", "status": "done"},
    ]
    steps[1]["status"] = "done by person" if success else "no reachable goal (place IK failed)"
    doc = {
        "schema": "thirdhand.trajectory/1",
        "robot": "panda" if joints == PANDA else "baxter",
        "base_pose": {"pos": [0.1, -0.2, 0.75], "quat": [0.0, 0.0, 0.6, 0.8]},
        "joint_names": joints,
        "rate_hz": 50.0,
        "t": t.tolist(),
        "q": q.tolist(),
        "success": success,
        "n_collisions": 0,
        "segments": segments,
        "steps": steps,
        "events": [],
    }
    path = folder / "run.json"
    path.write_text(json.dumps(doc))
    n = t.size
    leg = np.column_stack([np.linspace(0.3, 0.5, n), np.full(n, 0.1), np.full(n, 0.8)])
    leg[:10] = np.nan  # not yet on the table: no transform
    pos = {"seat": np.tile([0.5, 0.0, 0.8], (n, 1)), "leg 1": leg, "robot_tool": leg + 0.01}
    half = np.sqrt(0.5)
    quat = {k: np.tile([0.0, 0.0, half, half], (n, 1)) for k in pos}
    quat["leg 1"][:10] = np.nan
    bodies = [BodyInfo("seat"), BodyInfo("leg 1"), BodyInfo("robot_tool", kind="tool")]
    replay = Demonstration(t, bodies, pos, quat, meta={"units": "m"})
    io.save(replay, folder / "run.parquet")
    return path, doc, replay


@pytest.fixture(scope="module")
def run_mcap(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    folder = tmp_path_factory.mktemp("run")
    path, doc, replay = _run(folder)
    from thirdhand.export.ros2 import write_mcap

    counts = write_mcap(path, folder / "run.mcap")
    return {"mcap": folder / "run.mcap", "doc": doc, "replay": replay, "counts": counts}


def _decoded(path: Path) -> dict[str, list[tuple[int, Any, Any]]]:
    """``topic -> [(log time ns, message, channel)]`` decoded by mcap-ros2-support."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    out: dict[str, list[tuple[int, Any, Any]]] = {}
    with open(path, "rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        for schema, channel, message, decoded in reader.iter_decoded_messages():
            assert schema.encoding == "ros2msg"
            out.setdefault(channel.topic, []).append((message.log_time, decoded, channel))
    return out


def _ns(stamp: Any) -> int:
    return int(stamp.sec) * NS + int(stamp.nanosec)


def test_mcap_decodes_with_mcap_ros2(run_mcap: dict[str, Any]) -> None:
    doc, replay = run_mcap["doc"], run_mcap["replay"]
    t, q = np.asarray(doc["t"]), np.asarray(doc["q"])
    topics = _decoded(run_mcap["mcap"])
    assert {k: len(v) for k, v in topics.items()} == run_mcap["counts"]
    # one trajectory per step the arm did (the person's step has none), in time order
    trajs = topics["/joint_trajectory"]
    assert len(trajs) == 2
    # the return home (step -1) ends the last step's trajectory
    spans = [(0, 50, [0, 24, 25, 49]), (50, 100, [0, 39, 40, 49])]
    for (log, msg, _), (lo, hi, ends) in zip(trajs, spans, strict=True):
        assert msg.joint_names == PANDA
        assert log == _ns(msg.header.stamp) == ORIGIN_NS + round(t[lo] * NS)
        assert len(msg.points) == hi - lo
        since = [_ns(p.time_from_start) for p in msg.points]
        assert since == [round((t[k] - t[lo]) * NS) for k in range(lo, hi)]
        np.testing.assert_array_equal([p.positions for p in msg.points], q[lo:hi])
        vel = np.array([p.velocities for p in msg.points])
        # each motion segment starts and ends at rest; inside, central differences
        np.testing.assert_array_equal(vel[ends], 0.0)
        assert np.all(vel[1:24] != 0.0)
        np.testing.assert_allclose(vel[1], (q[lo + 2] - q[lo]) / 0.04, rtol=1e-9)
    states = topics["/joint_states"]
    assert len(states) == t.size
    last = states[-1][1]
    assert last.name == [*PANDA, "panda_finger_joint1", "panda_finger_joint2"]
    np.testing.assert_array_equal(last.position, [*q[-1], 0.04, 0.04])
    assert [_ns(m.header.stamp) for _, m, _ in states] == [log for log, _, _ in states]
    # tf: the parts (named after the task's objects), not the tool; a part without a
    # pose has no transform
    tf = topics["/tf"]
    assert [m.transforms[0].header.frame_id for _, m, _ in tf[:1]] == [WORLD_FRAME]
    assert [len(m.transforms) for _, m, _ in tf[9:11]] == [1, 2]
    frames = {tr.child_frame_id: tr.transform for tr in tf[-1][1].transforms}
    assert set(frames) == {"seat", "leg_1"}
    tr = frames["leg_1"]
    got = [tr.translation.x, tr.translation.y, tr.translation.z]
    np.testing.assert_array_equal(got, replay.pos("leg 1")[-1])
    (static,) = topics["/tf_static"]
    base = static[1].transforms[0]
    assert (base.header.frame_id, base.child_frame_id) == (WORLD_FRAME, "panda_link0")
    r = base.transform.rotation
    assert [r.x, r.y, r.z, r.w] == [0.0, 0.0, 0.6, 0.8]
    assert "transient_local" in static[2].metadata["offered_qos_profiles"]
    # the gripper: open at the start, closed on leg 1 while it is held, open again
    grip = topics["/gripper_command"]
    assert [log for log, _, _ in grip] == [ORIGIN_NS + k * NS // 2 for k in range(3)]
    assert [m.position for _, m, _ in grip] == [0.04, 0.0, 0.04]


def test_baxter_run_names_its_urdf_joints_and_base(tmp_path) -> None:
    from thirdhand.export.ros2 import write_mcap

    arm = [f"right_{j}" for j in ("s0", "s1", "e0", "e1", "w0", "w1", "w2")]
    path, _, _ = _run(tmp_path, joints=arm)
    write_mcap(path, tmp_path / "run.mcap")
    topics = _decoded(tmp_path / "run.mcap")
    assert all(m.joint_names == arm for _, m, _ in topics["/joint_trajectory"])
    assert topics["/tf_static"][0][1].transforms[0].child_frame_id == "base"
    names = topics["/joint_states"][0][1].name
    assert names[:7] == arm and {"left_s0", "r_gripper_l_finger_joint"} <= set(names)
    # the right gripper's finger: open as simulated, closed at its other URDF limit
    assert [m.position for _, m, _ in topics["/gripper_command"]] == [0.020833, 0.0, 0.020833]


def test_a_record_without_held_parts_has_no_gripper_commands(tmp_path) -> None:
    from thirdhand.export.ros2 import write_mcap

    path, doc, _ = _run(tmp_path)
    for seg in doc["segments"]:
        del seg["attached"]
    path.write_text(json.dumps(doc))
    counts = write_mcap(path, tmp_path / "run.mcap")
    assert "/gripper_command" not in counts
    assert set(_decoded(tmp_path / "run.mcap")) == set(counts)


def test_mcap_reads_back_with_rosbags_and_ours(run_mcap: dict[str, Any]) -> None:
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    doc, replay = run_mcap["doc"], run_mcap["replay"]
    store = get_typestore(Stores.LATEST)
    with AnyReader([run_mcap["mcap"]], default_typestore=store) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        conns = [c for c in reader.connections if c.topic == "/joint_trajectory"]
        msgs = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(conns)]
    assert types == {
        "/tf_static": "tf2_msgs/msg/TFMessage",
        "/joint_trajectory": "trajectory_msgs/msg/JointTrajectory",
        "/joint_states": "sensor_msgs/msg/JointState",
        "/tf": "tf2_msgs/msg/TFMessage",
        "/gripper_command": "control_msgs/msg/GripperCommand",
    }
    assert [len(m.points) for m in msgs] == [50, 50]
    np.testing.assert_array_equal(msgs[1].points[-1].positions, doc["q"][-1])
    # our own reader: the parts' poses over time (and the static robot base)
    back = io.load(run_mcap["mcap"])
    assert set(back.body_names) == {"seat", "leg_1", "panda_link0"}
    np.testing.assert_allclose(back.pos("leg_1")[10:], replay.pos("leg 1")[10:], atol=1e-12)
    assert np.isnan(back.pos("leg_1")[:10]).all()
    np.testing.assert_allclose(back.t, replay.t, atol=1e-9)


# --- plans: the behaviour tree and PDDL ----------------------------------------------


@functools.cache
def _chair() -> TaskFile:
    """The synthetic chair's true task (shared: callers copy before they change it)."""
    from thirdhand.synth import make_scene
    from thirdhand.synth.task import truth_task

    return truth_task(make_scene("chair", seed=0))


def _partial(task: TaskFile) -> TaskFile:
    """The chair with the legs in any order after the first, the back after all legs."""
    plan = [s.model_copy(update={"after": None}) for s in task.plan]
    legs = [i for i, s in enumerate(plan) if s.child.startswith("leg")]
    back = next(i for i, s in enumerate(plan) if not s.child.startswith("leg"))
    order = [legs[0], *legs[1:], back]
    steps = []
    for k, i in enumerate(order):
        after = [] if k == 0 else [0] if i != back else list(range(1, len(order) - 1))
        steps.append(plan[i].model_copy(update={"after": after}))
    return task.model_copy(update={"plan": steps})


def _custom(tag: str) -> bool:
    return tag in {a[0] for a in ACTIONS}


def _check_model(root: ET.Element) -> None:
    """Every node used is declared in the TreeNodesModel with exactly the ports it is given."""
    model = root.find("TreeNodesModel")
    assert model is not None
    declared = {
        (el.tag, el.get("ID")): {p.get("name") for p in el if p.tag.endswith("_port")}
        for el in model
    }
    trees = {bt.get("ID") for bt in root.findall("BehaviorTree")}
    assert root.get("main_tree_to_execute") in trees
    builtin = {"Sequence", "Parallel", "BehaviorTree"}
    for bt in root.findall("BehaviorTree"):
        for el in bt.iter():
            if el.tag in builtin:
                continue
            given = set(el.attrib) - {"name", "ID"}
            if el.tag == "SubTree":
                assert el.get("ID") in trees
                assert given == declared[("SubTree", el.get("ID"))]
            else:
                assert _custom(el.tag)
                assert given == declared[("Action", el.tag)]


def _bt_run(xml: str) -> list[str]:
    """Instantiate and tick the tree in BehaviorTree.CPP with stub actions; their paths.

    behaviortreepy registers simple actions without ports (``register_simple_action``
    takes a name and a callback only), and BehaviorTree.CPP refuses attributes that
    are not declared ports of the registered node: the stubs' port attributes are
    dropped here (they are checked by :func:`_check_model`). The subtrees' ports,
    their references and the control nodes are BehaviorTree.CPP's to check.
    """
    import behaviortreepy as bt

    root = ET.fromstring(xml)
    for tree in root.findall("BehaviorTree"):
        for el in tree.iter():
            if _custom(el.tag):
                el.attrib = {"name": el.get("name", el.tag)}
    factory = bt.BehaviorTreeFactory()
    ticked: list[str] = []

    def tick(node: Any) -> Any:
        ticked.append(node.full_path())
        return bt.NodeStatus.SUCCESS

    for name, _, _ in ACTIONS:
        factory.register_simple_action(name, tick)
    tree = factory.create_tree_from_text(ET.tostring(root, encoding="unicode"))
    assert tree.tick_while_running() == bt.NodeStatus.SUCCESS
    return ticked


def _write_task(task: TaskFile, path: Path) -> Path:
    save_task(task, path)
    return path


@pytest.mark.parametrize("partial", [False, True])
def test_behavior_tree_runs_in_btcpp(tmp_path, capsys, partial) -> None:
    task = _chair()
    if partial:
        task = _partial(task)
    src = _write_task(task, tmp_path / "chair.task.json")
    rc, _, err = call(capsys, "convert", str(src), str(tmp_path / "chair.xml"))
    assert rc == 0, err
    xml = (tmp_path / "chair.xml").read_text()
    root = ET.fromstring(xml)
    assert root.tag == "root" and root.get("BTCPP_format") == "4"
    steps = root.findall(".//BehaviorTree[@ID='Assembly']//SubTree")
    assert len(steps) == len(task.plan) == 5
    assert [int(s.get("step")) for s in steps] == list(range(5))
    for s, p in zip(steps, task.plan, strict=True):
        c = task.constraint_by_id(p.constraint or "")
        assert (s.get("parent"), s.get("child"), s.get("constraint")) == (p.parent, p.child, c.id)
        pose = [float(v) for v in s.get("goal_pose", "").split(";")]
        np.testing.assert_allclose(pose, [*c.pos, *c.quat], rtol=1e-8, atol=1e-12)
        dofs = [float(v) for v in s.get("free_dofs", "").split(";")]
        np.testing.assert_allclose(dofs, c.free_dof_array().ravel(), rtol=1e-8, atol=1e-12)
    parallels = root.findall(".//Parallel")
    assert len(parallels) == int(partial)
    if partial:
        assert parallels[0].get("success_count") == "-1"
        assert len(parallels[0].findall("SubTree")) == 3
    _check_model(root)
    ticked = _bt_run(xml)
    assert len(ticked) == 3 * len(task.plan)
    assert [p.split("/")[-1].split("::")[0] for p in ticked[:3]] == [a[0] for a in ACTIONS]
    # the tick order is a linear extension of the plan's partial order
    done = [int(p.split(":")[0].split()[-1]) - 1 for p in ticked[::3]]
    preds = task.predecessors()
    assert sorted(done) == list(range(5))
    assert all(done.index(j) < done.index(i) for i in done for j in preds[i])


def test_btcpp_refuses_an_undeclared_subtree_port(tmp_path, capsys) -> None:
    # the check above can fail: BehaviorTree.CPP reads the TreeNodesModel of the subtree
    src = _write_task(_chair(), tmp_path / "chair.task.json")
    call(capsys, "convert", str(src), str(tmp_path / "chair.xml"))
    xml = (tmp_path / "chair.xml").read_text().replace(' free_dofs="', ' free_dof="', 1)
    with pytest.raises(RuntimeError, match="free_dofs"):
        _bt_run(xml)


def test_layers_respect_the_partial_order() -> None:
    assert layers([[], [0], [0], [1, 2], []]) == [[0, 4], [1, 2], [3]]
    assert layers([[], [0], [1]]) == [[0], [1], [2]]


def _goal_atoms(problem: Any) -> list[Any]:
    """The goal's atoms (the parser turns a conjunction of one into the atom)."""
    goal = problem.goal
    return list(goal.operands) if hasattr(goal, "operands") else [goal]


def _solve(domain: Path, problem: Path) -> list[tuple[str, ...]]:
    from pyperplan.planner import HEURISTICS, SEARCHES, search_plan

    plan = search_plan(domain, problem, SEARCHES["astar"], HEURISTICS["hff"])
    assert plan is not None
    return [tuple(op.name.strip("()").split()) for op in plan]


def test_pddl_parses_and_a_planner_solves_it(tmp_path, capsys) -> None:
    import pddl

    # a chain: the second board goes onto the first, so the parent order is forced
    task = TaskFile.new(
        objects=[{"name": n} for n in ("/box/base", "/box/side", "/box/lid", "Screw 1")],
        constraints=[
            {"id": "c1", "parent": "/box/base", "child": "/box/side", "type": "fixed"},
            {"id": "c2", "parent": "/box/side", "child": "/box/lid", "type": "revolute"},
            {"id": "c3", "parent": "/box/base", "child": "Screw 1", "type": "screw"},
        ],
        plan=[
            {"parent": "/box/base", "child": "/box/side", "constraint": "c1"},
            {"parent": "/box/base", "child": "Screw 1", "constraint": "c3", "after": [0]},
            {"parent": "/box/side", "child": "/box/lid", "constraint": "c2", "after": [0]},
        ],
    )
    src = _write_task(task, tmp_path / "box.task.json")
    target = tmp_path / "box.pddl"
    rc, _, err = call(capsys, "convert", str(src), str(target))
    assert rc == 0, err
    domain = tmp_path / "box.domain.pddl"
    assert domain_path(target) == domain and domain.is_file()
    dom = pddl.parse_domain(domain)
    prob = pddl.parse_problem(target)
    assert dom.name == prob.domain_name == "thirdhand-assembly"
    assert {o.name for o in prob.objects} == {
        "box_base",
        "box_side",
        "box_lid",
        "screw_1",
        "c1",
        "c2",
        "c3",
    }
    plan = _solve(domain, target)
    assert sorted(plan) == sorted(
        [
            ("assemble", "box_base", "box_side", "c1"),
            ("assemble", "box_base", "screw_1", "c3"),
            ("assemble", "box_side", "box_lid", "c2"),
        ]
    )
    placed = {"box_base"}
    for _, parent, child, _ in plan:  # every parent in the assembly before its child
        assert parent in placed
        placed.add(child)


def test_pddl_of_the_chair_has_one_action_per_step(tmp_path, capsys) -> None:
    import pddl

    task = _chair()
    src = _write_task(task, tmp_path / "chair.task.json")
    rc, _, err = call(capsys, "convert", str(src), str(tmp_path / "chair.pddl"))
    assert rc == 0, err
    pddl.parse_domain(tmp_path / "chair.domain.pddl")
    prob = pddl.parse_problem(tmp_path / "chair.pddl")
    assert len(_goal_atoms(prob)) == len(task.plan)
    plan = _solve(tmp_path / "chair.domain.pddl", tmp_path / "chair.pddl")
    assert sorted(step[2:] for step in plan) == sorted((s.child, s.constraint) for s in task.plan)


# --- bad input: one line, nothing written ----------------------------------------------


def _listing(folder: Path) -> list[str]:
    return sorted(os.listdir(folder))


def test_failed_run_is_refused(tmp_path, capsys) -> None:
    path, _, _ = _run(tmp_path, success=False)
    before = _listing(tmp_path)
    rc, _, err = call(capsys, "convert", str(path), str(tmp_path / "run.mcap"))
    assert rc == 1 and err.count("\n") == 1
    assert "the run failed" in err and "step 1 (leg2 -> seat): no reachable goal" in err
    assert _listing(tmp_path) == before


def test_run_without_its_replay_or_not_a_run(tmp_path, capsys) -> None:
    path, _, _ = _run(tmp_path)
    (tmp_path / "run.parquet").unlink()
    rc, _, err = call(capsys, "convert", str(path), str(tmp_path / "run.mcap"))
    assert rc == 1 and "no replay run.parquet beside it" in err and err.count("\n") == 1
    task = _write_task(_chair(), tmp_path / "chair.task.json")
    rc, _, err = call(capsys, "convert", str(task), str(tmp_path / "task.mcap"))
    assert rc == 1 and "expected an execute --record file" in err
    assert not (tmp_path / "run.mcap").exists() and not (tmp_path / "task.mcap").exists()


@pytest.mark.parametrize("suffix", [".xml", ".pddl"])
def test_task_without_plan_is_one_error(tmp_path, capsys, suffix) -> None:
    task = _chair()
    src = _write_task(task.model_copy(update={"plan": []}), tmp_path / "empty.task.json")
    before = _listing(tmp_path)
    rc, _, err = call(capsys, "convert", str(src), str(tmp_path / f"out{suffix}"))
    assert rc == 1 and err.count("\n") == 1 and "the task has no plan" in err
    assert _listing(tmp_path) == before


@pytest.mark.parametrize("suffix", [".mcap", ".xml", ".pddl"])
def test_missing_output_folder_is_one_error(tmp_path, capsys, suffix) -> None:
    src = _run(tmp_path)[0] if suffix == ".mcap" else _write_task(_chair(), tmp_path / "t.json")
    before = _listing(tmp_path)
    target = tmp_path / "nowhere" / f"out{suffix}"
    rc, _, err = call(capsys, "convert", str(src), str(target))
    assert rc == 1 and err.count("\n") == 1 and "does not exist" in err
    assert _listing(tmp_path) == before


def test_existing_outputs_need_force(tmp_path, capsys) -> None:
    src = _write_task(_chair(), tmp_path / "chair.task.json")
    target = tmp_path / "chair.pddl"
    assert call(capsys, "convert", str(src), str(target))[0] == 0
    domain_path(target).write_text("mine")
    target.unlink()
    rc, _, err = call(capsys, "convert", str(src), str(target))
    assert rc == 1 and "chair.domain.pddl: the file exists; pass --force" in err
    assert not target.exists()
    assert call(capsys, "convert", str(src), str(target), "--force")[0] == 0
    assert (tmp_path / "chair.domain.pddl.bak").read_text() == "mine"
    rc, _, err = call(capsys, "convert", str(src), str(tmp_path / "x.xml"), "--to", "native")
    assert rc == 1 and "--to: not for a .xml target" in err


# --- end to end: a learned task, executed with --record, to all three ------------------


def _export_all(capsys, task: Path, run: Path, folder: Path) -> dict[str, Any]:
    """Convert a run and its task to the three formats and read each back."""
    import pddl

    for src, name in ((run, "run.mcap"), (task, "plan.xml"), (task, "plan.pddl")):
        rc, _, err = call(capsys, "convert", str(src), str(folder / name))
        assert rc == 0, err
    doc = json.loads(run.read_text())
    plan = json.loads(task.read_text())["plan"]
    topics = _decoded(folder / "run.mcap")
    trajs = [m for _, m, _ in topics["/joint_trajectory"]]
    done = [s for s in doc["steps"] if s["status"] == "done"]
    assert len(trajs) == len(done) > 0
    assert all(m.joint_names == doc["joint_names"] for m in trajs)
    assert sum(len(m.points) for m in trajs) == len(doc["t"])
    closes = [m for _, m, _ in topics["/gripper_command"] if m.position < 0.01]
    assert len(closes) >= len(done)
    root = ET.fromstring((folder / "plan.xml").read_text())
    assert root.get("BTCPP_format") == "4"
    assert len(root.findall(".//BehaviorTree[@ID='Assembly']//SubTree")) == len(plan)
    _check_model(root)
    assert len(_bt_run((folder / "plan.xml").read_text())) == 3 * len(plan)
    pddl.parse_domain(folder / "plan.domain.pddl")
    assert len(_goal_atoms(pddl.parse_problem(folder / "plan.pddl"))) == len(plan)
    assert len(_solve(folder / "plan.domain.pddl", folder / "plan.pddl")) == len(plan)
    return {"trajectories": trajs, "doc": doc}


@pytest.mark.slow
def test_learned_chair_executed_and_exported(tmp_path, capsys) -> None:
    rec, task, run = tmp_path / "chair.parquet", tmp_path / "chair.task.json", tmp_path / "run"
    assert call(capsys, "synth", "chair", "-o", str(rec), "--noise-free")[0] == 0
    cfg = settings_file(tmp_path, "learn", segment=False, primitives=False, reward=False)
    fast = ("--config", str(cfg))
    assert call(capsys, "learn", str(rec), "-o", str(task), *fast)[0] == 0
    rc, _, err = call(capsys, "execute", str(task), "--record", str(run))
    assert rc == 0, err
    got = _export_all(capsys, task, tmp_path / "run.json", tmp_path)
    assert got["doc"]["success"] and len(got["trajectories"]) == 5
    assert all(m.joint_names == PANDA for m in got["trajectories"])


@pytest.mark.slow
def test_real_toolbox_learned_with_its_scene_exports(tmp_path, capsys, shared_data) -> None:
    folder = shared_data / "3rdhand"
    task, run = tmp_path / "toolbox.task.json", tmp_path / "run"
    cfg = settings_file(tmp_path, "learn", segment=False, primitives=False, reward=False)
    fast = ("--config", str(cfg))
    scene = str(folder / "meshes" / "scene_toolbox_coop.json")
    rc, _, err = call(
        capsys, "learn", str(folder / "toolbox_coop_4"), "-o", str(task), "--scene", scene, *fast
    )
    assert rc == 0, err
    rc, _, err = call(capsys, "execute", str(task), "--record", str(run))
    assert rc == 0, err
    got = _export_all(capsys, task, tmp_path / "run.json", tmp_path)
    assert len(got["trajectories"]) >= 1
    frames = {
        tr.child_frame_id
        for _, m, _ in _decoded(tmp_path / "run.mcap")["/tf"][-1:]
        for tr in m.transforms
    }
    assert {"toolbox/side_front", "toolbox/side_left"} <= frames


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda d: d.update(q=d["q"][:-1]), "'q' has shape (99, 7), expected (100, 7)"),
        (lambda d: d.update(steps=["done"]), "steps[0]: expected a step report"),
        (lambda d: d.update(segments=[3]), "segments[0]: expected step, t_start and t_end"),
        (lambda d: d["base_pose"].update(quat=[0, 0, 0, 2]), "not a unit quaternion"),
        (lambda d: d.update(success=False), "the run failed, only a successful run"),
        (lambda d: d.update(t=d["t"][::-1]), "'t'[1] = 1.96 s is not after 't'[0] = 1.98 s"),
        (lambda d: d.update(robot="ur5"), "'robot' 'ur5' is not a robot thirdhand simulates"),
    ],
)
def test_malformed_record_is_one_error(tmp_path, capsys, change, message) -> None:
    path, doc, _ = _run(tmp_path)
    change(doc)
    path.write_text(json.dumps(doc))
    rc, _, err = call(capsys, "convert", str(path), str(tmp_path / "run.mcap"))
    assert rc == 1 and err.count("\n") == 1 and message in err, err
    assert not (tmp_path / "run.mcap").exists()


def test_step_without_constraint_id_uses_the_pair_or_is_one_error(tmp_path, capsys) -> None:
    task = _chair()
    plan = [s.model_copy(update={"constraint": None}) for s in task.plan]
    src = _write_task(task.model_copy(update={"plan": plan}), tmp_path / "t.json")
    assert call(capsys, "convert", str(src), str(tmp_path / "t.xml"))[0] == 0
    ids = [s.get("constraint") for s in ET.parse(tmp_path / "t.xml").iter("SubTree")]
    assert ids[: len(plan)] == [s.constraint for s in task.plan]
    bare = task.model_copy(update={"plan": plan, "constraints": task.constraints[1:]})
    src = _write_task(bare, tmp_path / "bare.json")
    rc, _, err = call(capsys, "convert", str(src), str(tmp_path / "bare.xml"))
    assert rc == 1 and err.count("\n") == 1 and "the tree needs its goal pose" in err
    assert not (tmp_path / "bare.xml").exists()
