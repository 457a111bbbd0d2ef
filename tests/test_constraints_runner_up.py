"""The runner-up type of a learned joint: from the detector to the task file, the review
panel and the clarification round."""

from __future__ import annotations

import math

import numpy as np
import pytest

from thirdhand.constraints.detect import detect_constraints
from thirdhand.constraints.select import fit_constraint
from thirdhand.learn.run import learn_task
from thirdhand.review.clarify import clarification_queue
from thirdhand.review.edits import Confirm, apply_edit
from thirdhand.review.panel_html import constraint_html
from thirdhand.synth import SensorModel, make_scene
from thirdhand.task.constraint import RunnerUp
from thirdhand.taskfile import dump_task, parse_task


def test_alternative_is_the_fits_geometry_in_the_tracks_frame() -> None:
    """A 25° arc of 0.4 m radius about z through (0.1, 0.2, 0): the revolute runner-up of a
    prismatic fit, or the winner, carries that axis, origin, radius and turn."""
    ang = np.linspace(0.0, math.radians(25.0), 200)
    centre = np.array([0.1, 0.2, 0.0])
    p = centre + 0.4 * np.column_stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)])
    q = np.column_stack([np.zeros((200, 2)), np.sin(ang / 2), np.cos(ang / 2)])
    fit = fit_constraint(p, q, models=("fixed", "prismatic", "revolute"))
    assert fit.type == "revolute" and fit.runner_up is not None
    alt = fit.alternative()
    assert alt["type"] == "revolute"
    assert abs(abs(alt["axis"][2]) - 1.0) < 1e-6
    assert alt["radius"] == pytest.approx(0.4, abs=1e-6)
    assert alt["travel"] == pytest.approx(math.radians(25.0), abs=1e-6)
    # the origin is on the axis: its distance from the centre is along z only
    assert np.linalg.norm((np.asarray(alt["origin"]) - centre)[:2]) < 1e-6
    ru = RunnerUp.model_validate(fit.runner_up.alternative())
    assert ru.type == fit.runner_up.type and 0.0 <= ru.probability < 0.5


def test_a_learned_drawer_carries_its_runner_up_to_the_task_and_the_review() -> None:
    demo = make_scene("drawer", seed=0, sensor=SensorModel())
    (inst,) = detect_constraints(demo).instances
    assert inst.type == "prismatic" and inst.runner_up is not None
    assert inst.to_dict()["runner_up"]["type"] == inst.runner_up.type
    task = learn_task([demo], segment=False, primitives=False, reward=False, grasps=False).task
    (c,) = task.constraints
    assert c.type == "prismatic" and c.runner_up is not None
    assert c.runner_up.type == inst.runner_up.type
    assert c.runner_up.probability == pytest.approx(inst.runner_up.confidence)
    # the instance record in stages.constraints keeps it too
    assert task.stages.constraints is not None
    (rec,) = task.stages.constraints.demos[0].instances
    assert rec.runner_up == c.runner_up
    # round trip through the file
    again = parse_task(dump_task(task))
    assert again.constraints[0].runner_up == c.runner_up
    # the review panel names it with its geometry
    page = constraint_html(c)
    assert "runner-up" in page and c.runner_up.type in page
    # the clarification score counts it: wrong if it holds as the other type
    (q,) = [q for q in clarification_queue(task) if q.dof is None]
    assert q.score == pytest.approx(1.0 - c.confidence * (1.0 - c.runner_up.probability))
    assert f"or {c.runner_up.type}" in q.text
    # a person's decision drops it
    done = apply_edit(task, Confirm(c.id))
    assert done.constraints[0].runner_up is None and "runner-up" not in constraint_html(
        done.constraints[0]
    )


def test_a_runner_up_is_validated() -> None:
    with pytest.raises(ValueError, match="probability"):
        RunnerUp.model_validate({"type": "revolute", "probability": 1.5})
    with pytest.raises(ValueError, match="type"):
        RunnerUp.model_validate({"type": "hinge", "probability": 0.5})
