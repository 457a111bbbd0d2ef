"""The scripted user: minimal corrections to a reference task (research.scripted_user)."""

from __future__ import annotations

import math

import pytest

from research.scripted_user import TOL_POS, TOL_ROT, residuals, scripted_corrections
from thirdhand.review.edits import SetDofRange, SetParent, SetPoseValue, apply_edit
from thirdhand.review.transfer import (
    transfer,
)
from thirdhand.synth import make_scene
from thirdhand.synth.task import truth_task
from thirdhand.taskfile import TaskFile


@pytest.fixture(scope="module")
def chair() -> TaskFile:
    return truth_task(make_scene("chair", seed=0, sensor=None))


@pytest.fixture(scope="module")
def bench() -> TaskFile:
    return truth_task(make_scene("bench", seed=0, sensor=None))


def _within(task: TaskFile, truth: TaskFile) -> None:
    res = residuals(task, truth)
    assert set(res) == {c.child for c in truth.constraints}
    for child, r in res.items():
        assert r["parent"] and r["classes"], child
        assert r["position"] <= TOL_POS, child
        assert r["angle"] <= math.sqrt(3) * TOL_ROT, child


def test_scripted_user_finds_planted_errors(chair: TaskFile) -> None:
    wrong = chair
    wrong = apply_edit(wrong, SetParent("back", "leg1"))  # pose re-expressed: world pose kept
    wrong = apply_edit(wrong, SetPoseValue("c1", "x", 0.16))  # 4.5 cm off
    wrong = apply_edit(wrong, SetPoseValue("c1", "z", 0.121))  # 4 mm: within tolerance
    wrong = apply_edit(wrong, SetPoseValue("c3", "yaw", 0.5))  # leg3 tilted
    wrong = apply_edit(wrong, SetPoseValue("c2", "roll", 1.0))  # about leg4's free axis: fine
    wrong = apply_edit(wrong, SetDofRange("c4", "rx", 0.0, 0.0))  # leg1 locked
    result = scripted_corrections(wrong, chair)
    assert result.corrected == ["leg2.x", "leg3.yaw", "back.parent"]
    assert result.ranges == ["leg1.range.rx"]
    assert (result.n_corrected, result.n_parameters) == (3, 35)
    assert not result.missing and not result.extra
    _within(result.task, chair)
    assert result.task.provenance.corrections[-1].who == "scripted user"
    # Nothing to do on the truth itself.
    assert scripted_corrections(chair, chair).edits == []


def test_scripted_user_bench_after_transfer(chair: TaskFile, bench: TaskFile) -> None:
    result = scripted_corrections(transfer(chair, "bench").task, bench)
    # Bench legs sit 7 cm from the centre, the chair's 11.5 cm; the seat is thicker:
    # x, y, z of each leg; orientations are the chair's up to the leg's free turn.
    assert result.n_corrected == 12 and result.n_parameters == 28
    assert sorted({p.split(".")[1] for p in result.corrected}) == ["x", "y", "z"]
    assert result.ranges == []
    _within(result.task, bench)


@pytest.mark.slow
def test_scripted_user_learned_chair() -> None:
    from thirdhand.learn.run import learn_task

    demo = make_scene("chair", seed=1)
    truth = truth_task(demo)
    learned = learn_task([demo], primitives=False, reward=False, grasps=False).task
    result = scripted_corrections(learned, truth)
    assert result.n_parameters == 35
    assert not result.missing
    _within(result.task, truth)
    # The learner is within tolerance on this noise level: nothing to correct.
    assert result.n_corrected == 0
