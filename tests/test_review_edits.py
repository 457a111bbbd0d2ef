"""Corrections on the task model (thirdhand.review.edits, history, dofs), without a browser."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from thirdhand.review.dofs import (
    NOISE_ROTATION,
    classify_dof,
    dof_animation,
    quat_distance,
    relative,
    world_poses,
)
from thirdhand.review.edits import (
    Confirm,
    EditError,
    MoveStep,
    SetDofRange,
    SetParent,
    SetPose,
    SetPoseValue,
    apply_correction,
    apply_edit,
    parse_number,
    pose_values,
)
from thirdhand.review.history import History
from thirdhand.synth import make_scene
from thirdhand.synth.task import truth_task
from thirdhand.taskfile import TaskFile, dump_task


@pytest.fixture(scope="module")
def chair() -> TaskFile:
    return truth_task(make_scene("chair", seed=0, sensor=None))


def test_set_pose_value_position(chair: TaskFile) -> None:
    before = dump_task(chair)
    out = apply_edit(chair, SetPoseValue("c1", "x", 0.2), who="tester")
    c = out.constraint_by_id("c1")
    assert c.pos == (0.2, chair.constraint_by_id("c1").pos[1], chair.constraint_by_id("c1").pos[2])
    assert c.source == "corrected"
    last = out.provenance.corrections[-1]
    assert (last.who, last.field, last.old, last.new) == (
        "tester",
        "constraints[0].pos[0]",
        0.115,
        0.2,
    )
    assert out.provenance.modified == last.when
    assert dump_task(chair) == before  # pure
    assert chair.constraint_by_id("c1").source == "learned"
    # Other constraints untouched.
    assert out.constraint_by_id("c3") == chair.constraint_by_id("c3")


@pytest.mark.parametrize("name", ["roll", "pitch", "yaw"])
def test_set_pose_value_angle(chair: TaskFile, name: str) -> None:
    # The back is fixed at the identity orientation: far from the xyz gimbal lock.
    values = pose_values(chair.constraint_by_id("c5"))
    out = apply_edit(chair, SetPoseValue("c5", name, 0.3))
    got = pose_values(out.constraint_by_id("c5"))
    for k in ("roll", "pitch", "yaw"):
        assert got[k] == pytest.approx(0.3 if k == name else values[k], abs=1e-12)
    assert got["x"] == values["x"]
    corr = out.provenance.corrections[-1]
    assert corr.field == "constraints[4].quat"
    assert corr.model_extra is not None and corr.model_extra["parameter"] == name


@given(st.floats(-3.0, 3.0), st.floats(-1.4, 1.4), st.floats(-3.0, 3.0))
def test_pose_values_round_trip(roll: float, pitch: float, yaw: float) -> None:
    task = truth_task_cache()
    for name, v in (("roll", roll), ("pitch", pitch), ("yaw", yaw)):
        task = apply_edit(task, SetPoseValue("c5", name, v))
    got = pose_values(task.constraint_by_id("c5"))
    assert [got["roll"], got["pitch"], got["yaw"]] == pytest.approx([roll, pitch, yaw], abs=1e-9)


_CACHE: list[TaskFile] = []


def truth_task_cache() -> TaskFile:
    if not _CACHE:
        _CACHE.append(truth_task(make_scene("chair", seed=0, sensor=None)))
    return _CACHE[0]


def test_set_pose_normalises_quaternion(chair: TaskFile) -> None:
    out = apply_edit(chair, SetPose("c5", pos=(0.0, 0.01, 0.2), quat=(0.0, 0.0, 2.0, 2.0)))
    c = out.constraint_by_id("c5")
    assert c.pos == (0.0, 0.01, 0.2)
    assert np.allclose(c.quat, [0, 0, math.sqrt(0.5), math.sqrt(0.5)])
    fields = [x.field for x in out.provenance.corrections]
    assert fields[-3:] == ["constraints[4].pos[1]", "constraints[4].pos[2]", "constraints[4].quat"]


def test_unchanged_value_records_nothing(chair: TaskFile) -> None:
    c = chair.constraint_by_id("c1")
    out = apply_edit(chair, SetPoseValue("c1", "y", c.pos[1]))
    assert out.provenance.corrections == chair.provenance.corrections
    assert out.constraint_by_id("c1").source == "learned"


def test_dof_range_and_type(chair: TaskFile) -> None:
    out = apply_edit(chair, SetDofRange("c1", "rx", 0.0, 0.0))
    c = out.constraint_by_id("c1")
    assert c.free_dofs.rx == (0.0, 0.0)
    assert c.type == "fixed"
    assert c.source == "corrected"
    fields = [(x.field, x.old, x.new) for x in out.provenance.corrections]
    assert ("constraints[0].free_dofs.rx", [-math.pi, math.pi], [0.0, 0.0]) in fields
    assert ("constraints[0].type", "revolute", "fixed") in fields
    out2 = apply_edit(out, SetDofRange("c1", "tz", -0.01, 0.05))
    assert out2.constraint_by_id("c1").type == "prismatic"
    assert out2.constraint_by_id("c1").free_dofs.tz == (-0.01, 0.05)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (SetPoseValue("c1", "x", float("nan")), "finite"),
        (SetPoseValue("c1", "x", float("inf")), "finite"),
        (SetPoseValue("c1", "x", "12"), "expected a number"),  # type: ignore[arg-type]
        (SetPoseValue("nope", "x", 0.1), "unknown constraint 'nope'"),
        (SetPoseValue("c1", "w", 0.1), "unknown pose value"),
        (SetPose("c1", quat=(0.0, 0.0, 0.0, 0.0)), "zero norm"),
        (SetPose("c1", pos=(0.0, float("nan"), 0.0)), "finite"),
        (SetDofRange("c1", "rz", 0.2, -0.2), "min 11.5° > max -11.5°"),
        (SetDofRange("c1", "rz", float("nan"), 0.1), "finite"),
        (SetDofRange("c1", "Tx", 0.0, 0.1), "unknown DOF"),
        (SetDofRange("c1", "rz", -4.0, 4.0), "wider than a full turn"),
        (SetParent("leg1", "leg9"), "unknown parent object 'leg9'"),
        (SetParent("leg1", "leg1"), "its own parent"),
        (SetParent("seating", "leg1"), "no constraint has the child"),
        (MoveStep(0, 5), "out of range"),
        (MoveStep(-1, 2), "out of range"),
        (Confirm("c1", "ax"), "unknown DOF"),
    ],
)
def test_malformed_edit_refused_task_unchanged(chair: TaskFile, edit: object, message: str) -> None:
    before = dump_task(chair)
    with pytest.raises(EditError, match=message):
        apply_edit(chair, edit)  # type: ignore[arg-type]
    assert dump_task(chair) == before


def test_parent_change_keeps_world_pose(chair: TaskFile) -> None:
    step = next(k for k, s in enumerate(chair.plan) if s.child == "leg1")
    before = world_poses(chair, step)
    out = apply_edit(chair, SetParent("leg1", "leg2"))
    c = next(c for c in out.constraints if c.child == "leg1")
    assert c.parent == "leg2" and c.source == "corrected"
    assert out.plan[step].parent == "leg2"
    after = world_poses(out, step)
    assert np.allclose(after["leg1"].pos, before["leg1"].pos, atol=1e-12)
    assert quat_distance(after["leg1"].quat, before["leg1"].quat) < 1e-9
    expected = relative(before["leg2"], before["leg1"])
    assert np.allclose(c.pos, expected.pos, atol=1e-12)
    fields = {x.field for x in out.provenance.corrections}
    i = out.constraints.index(c)
    assert {f"constraints[{i}].parent", f"constraints[{i}].quat", f"plan[{step}].parent"} <= fields
    # Free DOFs (constraint frame, child relative) are kept.
    assert c.free_dofs == chair.constraint_by_id(c.id).free_dofs


def test_parent_cycle_refused(chair: TaskFile) -> None:
    out = apply_edit(chair, SetParent("leg1", "leg2"))
    before = dump_task(out)
    with pytest.raises(EditError, match=r"cycle \(leg2 -> leg1 -> leg2\)"):
        apply_edit(out, SetParent("leg2", "leg1"))
    # A longer loop: leg1 -> leg2 -> back, then back under leg1.
    out2 = apply_edit(out, SetParent("leg2", "back"))
    with pytest.raises(EditError, match="cycle"):
        apply_edit(out2, SetParent("back", "leg1"))
    assert dump_task(out) == before


def _order(task: TaskFile) -> list[str]:
    return [s.child for s in task.plan]


def test_move_step_total_order(chair: TaskFile) -> None:
    out = apply_edit(chair, MoveStep(4, 0))
    assert _order(out) == ["back", "leg2", "leg3", "leg4", "leg1"]
    assert all(s.after is None for s in out.plan)
    assert out.provenance.corrections[-1].field == "plan"
    back = apply_edit(out, MoveStep(0, 4))
    assert _order(back) == _order(chair)


def test_move_step_learned_chain_stays_a_chain(chair: TaskFile) -> None:
    chain = chair.model_copy(deep=True)
    for k, s in enumerate(chain.plan):
        s.after = [k - 1] if k else []
    out = apply_edit(chain, MoveStep(1, 3))
    assert _order(out) == ["leg2", "leg4", "leg1", "leg3", "back"]
    assert [s.after for s in out.plan] == [[], [0], [1], [2], [3]]


def test_move_step_partial_order_remaps_and_drops(chair: TaskFile) -> None:
    # leg2 first; leg3 and leg4 after leg2; leg1 after leg3; back after leg1 and leg4.
    po = chair.model_copy(deep=True)
    for s, after in zip(po.plan, [[], [0], [0], [1], [2, 3]], strict=True):
        s.after = after
    po = TaskFile.model_validate(po.model_dump(by_alias=True))
    # Moving leg4 (index 2) to the front contradicts "leg4 after leg2".
    out = apply_edit(po, MoveStep(2, 0))
    assert _order(out) == ["leg4", "leg2", "leg3", "leg1", "back"]
    assert [s.after for s in out.plan] == [[], [], [1], [2], [0, 3]]
    dropped = [c for c in out.provenance.corrections if c.field.endswith(".after")]
    assert len(dropped) == 1
    assert dropped[0].field == "plan[0].after" and dropped[0].old == "seating->leg2"
    assert (
        dropped[0].model_extra is not None
        and "dependency dropped" in dropped[0].model_extra["reason"]
    )
    # A move that contradicts nothing keeps every dependency (remapped).
    out2 = apply_edit(po, MoveStep(1, 2))
    assert _order(out2) == ["leg2", "leg4", "leg3", "leg1", "back"]
    assert [s.after for s in out2.plan] == [[], [0], [0], [2], [1, 3]]
    assert not [c for c in out2.provenance.corrections if c.field.endswith(".after")]


def test_confirm(chair: TaskFile) -> None:
    low = chair.model_copy(deep=True)
    low.constraints[0].confidence = 0.4
    out = apply_edit(low, Confirm("c1"))
    assert out.constraint_by_id("c1").confidence == 1.0
    assert out.constraint_by_id("c1").source == "learned"
    out = apply_edit(out, Confirm("c1", "rx"))
    assert out.stages.review is not None
    assert out.stages.review.confirmed == {"c1": ["constraint", "rx"]}


def test_apply_correction_is_apply_edit() -> None:
    assert apply_correction is apply_edit


def test_history_undo_redo(chair: TaskFile) -> None:
    h = History(chair)
    assert not h.dirty and not h.can_undo and not h.can_redo
    t1 = h.apply(SetPoseValue("c1", "x", 0.2))
    t2 = h.apply(SetDofRange("c1", "rx", 0.0, 0.0))
    assert h.dirty and h.current is t2
    assert h.undo() is t1
    assert h.undo() is chair and not h.dirty and not h.can_undo
    assert h.undo() is chair
    assert h.redo() is t1 and h.redo() is t2 and not h.can_redo
    h.mark_saved()
    assert not h.dirty
    h.undo()
    assert h.dirty
    t3 = h.apply(MoveStep(0, 1))  # drops the undone branch
    assert not h.can_redo and h.current is t3
    assert h.edits == [SetPoseValue("c1", "x", 0.2), MoveStep(0, 1)]
    with pytest.raises(EditError):
        h.apply(SetPoseValue("c1", "x", float("nan")))
    assert h.current is t3


@pytest.mark.parametrize(
    ("text", "unit", "value"),
    [
        ("0.12", "m", 0.12),
        ("12 cm", "m", 0.12),
        ("120mm", "m", 0.12),
        ("1e-3 m", "m", 1e-3),
        ("12", "cm", 0.12),
        ("-0,5", "m", -0.5),
        ("45 deg", "rad", math.pi / 4),
        ("45°", "rad", math.pi / 4),
        ("90", "deg", math.pi / 2),
        ("0.5", "rad", 0.5),
    ],
)
def test_parse_number(text: str, unit: str, value: float) -> None:
    assert parse_number(text, unit=unit) == pytest.approx(value, rel=1e-12)


@pytest.mark.parametrize(
    ("text", "unit"),
    [
        ("", "m"),
        ("abc", "m"),
        ("nan", "m"),
        ("inf", "m"),
        ("1e999", "m"),
        ("12 deg", "m"),
        ("3 cm", "rad"),
        ("1..2", "m"),
        ("12 furlongs", "m"),
    ],
)
def test_parse_number_refused(text: str, unit: str) -> None:
    with pytest.raises(EditError):
        parse_number(text, unit=unit)


def test_classify_dof() -> None:
    assert classify_dof(0.0, 0.0) == "locked"
    assert classify_dof(-0.01, 0.01) == "noise"
    assert classify_dof(-0.5, 0.5) == "limited"
    assert classify_dof(-math.pi, math.pi) == "full"
    assert classify_dof(-3.1416, 3.1416) == "full"
    assert classify_dof(0.0, 0.004, "tx") == "noise"
    assert classify_dof(0.0, 0.05, "tz") == "limited"
    assert classify_dof(-math.pi, math.pi, "tz") == "limited"
    assert classify_dof(0.0, NOISE_ROTATION) == "limited"


def test_dof_animation(chair: TaskFile) -> None:
    leg = chair.constraint_by_id("c1")  # revolute, rx full
    rest = dof_animation(leg, "rx", 0.0)
    assert np.allclose(rest.pos, leg.pos) and quat_distance(rest.quat, leg.quat) < 1e-12
    quarter = dof_animation(leg, "rx", 0.25)
    assert np.allclose(quarter.pos, leg.pos)
    assert quat_distance(quarter.quat, leg.quat) == pytest.approx(math.pi / 2)
    # The child rotated about its own x axis: that axis does not move in the parent frame.
    from thirdhand.se3 import quat_rotate

    assert np.allclose(quat_rotate(quarter.quat, [1, 0, 0]), quat_rotate(leg.quat, [1, 0, 0]))
    # A locked translation swings by the demo amplitude along the child's axis.
    swing = dof_animation(leg, "tz", 0.25)
    assert np.allclose(np.subtract(swing.pos, leg.pos), quat_rotate(leg.quat, [0, 0, 0.02]))
    assert np.allclose(
        dof_animation(leg, "tz", 0.75).pos,
        np.subtract(leg.pos, quat_rotate(leg.quat, [0, 0, 0.02])),
    )
    # A limited range reaches its ends.
    lim = leg.model_copy(update={"free_dofs": dataclasses.replace(leg.free_dofs, ty=(-0.01, 0.03))})
    assert np.allclose(
        np.subtract(dof_animation(lim, "ty", 0.25).pos, leg.pos),
        quat_rotate(leg.quat, [0, 0.03, 0]),
    )
    assert np.allclose(
        np.subtract(dof_animation(lim, "ty", 0.75).pos, leg.pos),
        quat_rotate(leg.quat, [0, -0.01, 0]),
    )


def test_world_poses_match_noise_free_keyframes(chair: TaskFile) -> None:
    # Noise-free truth: constrained children placed by their constraint land on the keyframe.
    for k, step in enumerate(chair.plan):
        w = world_poses(chair, k)
        kf = step.keyframe
        for c in chair.constraints:
            if c.child in kf:
                assert np.allclose(w[c.child].pos, kf[c.child].pos, atol=2e-4), (k, c.child)
    assert set(world_poses(chair)) == {o.name for o in chair.objects}
    with pytest.raises(IndexError):
        world_poses(chair, 99)


def test_implausible_offsets_are_refused_and_edits_described() -> None:
    import math

    from thirdhand.review.edits import (
        PLAUSIBLE_OFFSET_M,
        EditError,
        MoveStep,
        SetDofRange,
        SetPoseValue,
        apply_edit,
        describe_edit,
    )
    from thirdhand.synth import make_scene
    from thirdhand.synth.task import truth_task

    task = truth_task(make_scene("chair", seed=0, sensor=None))
    cid = task.constraints[1].id
    with pytest.raises(EditError, match="not plausible"):
        apply_edit(task, SetPoseValue(cid, "y", 1e9))
    apply_edit(task, SetPoseValue(cid, "y", PLAUSIBLE_OFFSET_M * 0.99))  # within: fine
    assert describe_edit(SetPoseValue(cid, "x", 0.12)) == f"{cid} x = 12.00 cm"
    assert describe_edit(SetDofRange(cid, "rx", -math.pi / 4, math.pi / 4)) == (
        f"{cid} rx range -45.0° to 45.0°"
    )
    assert describe_edit(MoveStep(3, 2)) == "step 4 moved to position 3"
