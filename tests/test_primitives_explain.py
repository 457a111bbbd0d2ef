"""Constraint motions explained by library skills, stored in the task's primitives block."""

from __future__ import annotations

import copy
import itertools
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.ndimage import uniform_filter1d

from thirdhand.errors import TaskFileError
from thirdhand.primitives import PrimitiveError
from thirdhand.primitives.explain import explain_constraint_motions
from thirdhand.primitives.pose_channels import accumulated_rotation
from thirdhand.primitives.segments import ConstraintSegment, constraint_segments
from thirdhand.primitives.skill_library import skill_library_from_record
from thirdhand.primitives.stage import primitives_stage
from thirdhand.synth import make_scene
from thirdhand.taskfile import TaskFile, load_task, save_task

K = 4


@pytest.fixture(scope="module")
def chairs() -> list:
    return [make_scene("chair", seed=s, sensor=None) for s in range(2)]


@pytest.fixture(scope="module")
def block(chairs: list) -> dict:
    stage = primitives_stage(chairs, promp_weights=5, skills=K, names=["chair0", "chair1"])
    return stage.model_dump(mode="json", by_alias=True)


def _roles(block: dict) -> dict[str, int]:
    """Skills by what they do, from the library's summary (not from the labels)."""
    summary = block["skill_library"]["summary"]
    speed = np.array([s["typical_speed_m_s"] for s in summary])
    turn = np.array([s["typical_angular_speed_rad_s"] for s in summary])
    roles = {
        "transport": int(np.argmax(speed)),
        # turning on the spot: the most angle per metre
        "turn": int(np.argmax(turn / (speed + 0.01))),
    }
    rest = [k for k in range(K) if k not in roles.values()]
    roles["rest"] = min(rest, key=lambda k: speed[k])
    assert len(set(roles.values())) == 3
    roles["approach"] = (set(range(K)) - set(roles.values())).pop()
    return roles


def _true_turns(demo, leg: str) -> int:
    """Screwing turns of a leg, counted on the noise-free track: fast spins once seated."""
    p, q, _ = demo.relative_pose("seating", leg)
    ev = next(e for e in demo.labels.constraints if e.child == leg)
    sel = demo.t <= ev.time + 1e-9
    seated = np.linalg.norm(p - np.asarray(ev.pos), axis=1) < 0.013
    dt = float(demo.t[1] - demo.t[0])
    rot = accumulated_rotation(q)
    w = np.linalg.norm(uniform_filter1d(np.gradient(rot, dt, axis=0), 5, axis=0), axis=1)
    spinning = (w > 1.0) & seated & sel
    return int(np.sum(spinning[1:] & ~spinning[:-1]))


def test_accumulated_rotation_does_not_wrap() -> None:
    # five quarter turns about z: 2.5 π rad, where a log map wraps at π
    angle = np.linspace(0.0, 2.5 * np.pi, 200)
    q = np.stack(
        [np.zeros_like(angle), np.zeros_like(angle), np.sin(angle / 2), np.cos(angle / 2)], 1
    )
    q[::3] *= -1.0  # sign flips change nothing
    rot = accumulated_rotation(q)
    np.testing.assert_allclose(rot[:, 2], angle, atol=1e-12)
    np.testing.assert_allclose(rot[:, :2], 0.0, atol=1e-12)


def _event():
    from thirdhand.demonstration import ConstraintEvent

    return ConstraintEvent(time=2.0, parent="a", child="b", type="fixed", symbol="c1")


@pytest.mark.slow
def test_every_leg_is_transport_insert_then_turns_and_rests(chairs: list, block: dict) -> None:
    roles = _roles(block)
    T, A, S, R = (roles[k] for k in ("transport", "approach", "turn", "rest"))
    legs = 0
    for key, c in block["constraints"].items():
        examples = c["skills"]
        assert [e["source"] for e in examples] == ["chair0", "chair1"]
        for demo, ex in zip(chairs, examples, strict=True):
            steps = ex["steps"]
            seq = [s["skill"] for s in steps]
            # steps tile the motion: contiguous, in time order
            for a, b in itertools.pairwise(steps):
                assert a["end"] == b["start"] and a["start"] < a["end"]
            if c["child"] == "back":
                assert S not in seq and seq[-2:] == [T, A]
                continue
            legs += 1
            n = _true_turns(demo, c["child"])
            assert 4 <= n <= 6  # the scene's range of turns
            if seq[0] == R:  # the leg lay still before it was picked up
                seq = seq[1:]
            assert seq == [T, A, S] + [R, S] * (n - 1), (key, seq, n)
    assert legs == 8


@pytest.mark.slow
def test_the_saved_library_round_trips_and_parses_as_it_was_fitted(
    chairs: list, block: dict, tmp_path: Path
) -> None:
    lib = block["skill_library"]
    assert lib["schema"] == "thirdhand.skill-library/1" and lib["n_skills"] == K
    assert [s["id"] for s in lib["summary"]] == list(range(K))
    assert sum(s["share"] for s in lib["summary"]) == pytest.approx(1.0)
    task = TaskFile.new(stages={"primitives": block})
    path = tmp_path / "task.json"
    save_task(task, path)
    again = load_task(path)
    assert again.stages.primitives is not None
    assert again.stages.primitives.model_dump(mode="json", by_alias=True) == block
    # the library read back from the file explains the motions exactly as it did
    fitted = skill_library_from_record(again.stages.primitives.skill_library)
    segs = [
        replace(sg, source=name)
        for demo, name in zip(chairs, ["chair0", "chair1"], strict=True)
        for sg in constraint_segments(demo)
    ]
    res = explain_constraint_motions(segs, library=fitted)
    assert res.steps_by_key() == {k: c["skills"] for k, c in block["constraints"].items()}


def test_a_library_from_other_demonstrations_explains_a_new_one(chairs: list) -> None:
    """Learned once, reused: chair 0's library parses chair 1's legs into the same roles."""
    fitted = explain_constraint_motions(constraint_segments(chairs[0]), n_skills=K).library
    res = explain_constraint_motions(constraint_segments(chairs[1]), library=fitted)
    turn = int(np.argmax(fitted.model_.means_[:, 1] - fitted.model_.means_[:, 0]))
    for ex in res.explanations:
        child = next(e.child for e in chairs[1].labels.constraints if e.symbol == ex.key)
        n = ex.skills.count(turn)
        assert n == (_true_turns(chairs[1], child) if child.startswith("leg") else 0), ex


@pytest.mark.slow
@pytest.mark.parametrize(
    ("edit", "where"),
    [
        (
            lambda b: b["constraints"]["c1"]["skills"][0]["steps"][1].update(skill=9),
            "stages.primitives.constraints.c1.skills[0].steps[1].skill: unknown skill 9",
        ),
        (
            lambda b: b["constraints"]["c2"]["skills"][1]["steps"][2].update(start=-1.0),
            "stages.primitives.constraints.c2.skills[1].steps[2].start: -1.0 s is before",
        ),
        (
            lambda b: b["skill_library"]["skills"]["means"].pop(),
            "stages.primitives.skill_library.skills.means: expected 4 × 2 numbers",
        ),
        (
            lambda b: b["skill_library"]["summary"][1].pop("share"),
            "stages.primitives.skill_library.summary[1].share: required field is missing",
        ),
        (
            lambda b: b["skill_library"]["summary"][0].update(share="0.5"),
            "stages.primitives.skill_library.summary[0].share: Input should be a valid number",
        ),
        (
            lambda b: b.update(skill_library={"n_skills": 1, "rate_hz": 20.0, "skills": []}),
            "stages.primitives.skill_library: a library of ProMP skills written by an earlier",
        ),
        (
            lambda b: b.pop("skill_library"),
            "stages.primitives.constraints.c1.skills: refers to skills, but "
            "skill_library is missing",
        ),
    ],
)
def test_a_malformed_skill_block_is_one_line_naming_where(
    block: dict, tmp_path: Path, edit, where: str
) -> None:
    bad = copy.deepcopy(json.loads(json.dumps(block)))
    edit(bad)
    good = TaskFile.new(stages={"primitives": block})
    text = json.loads(good.model_dump_json(by_alias=True))
    text["stages"]["primitives"] = bad
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(text))
    with pytest.raises(TaskFileError) as err:
        load_task(path)
    msg = str(err.value)
    assert "\n" not in msg and where in msg and str(path) in msg


def test_a_block_without_skills_needs_no_library(block: dict) -> None:
    from thirdhand.task.stages import PrimitivesBlock

    bare = copy.deepcopy(block)
    bare.pop("skill_library")
    for c in bare["constraints"].values():
        c.pop("skills")
    assert PrimitivesBlock.model_validate(bare).skill_library is None


def test_motions_too_short_are_named_not_parsed() -> None:
    t = np.linspace(0.0, 0.1, 13)  # 3 grid samples at 20 Hz: shorter than the parser's 5
    seg = ConstraintSegment(_event(), t, np.zeros((13, 3)), np.tile([0.0, 0.0, 0.0, 1.0], (13, 1)))
    with pytest.raises(PrimitiveError, match="shorter than 5 samples at 20 Hz"):
        explain_constraint_motions([seg])
    # beside a motion that can be parsed, the short one is kept with a note
    t2 = np.linspace(0.0, 2.0, 241)  # still, then 0.1 m/s
    x = np.clip(t2 - 1.0, 0.0, None) * 0.1
    move = ConstraintSegment(
        _event(), t2, np.outer(x, [1.0, 0.0, 0.0]), np.tile([0.0, 0.0, 0.0, 1.0], (241, 1))
    )
    res = explain_constraint_motions([seg, move], n_skills=2)
    assert res.library.n_skills_ == 2
    assert res.explanations[0].steps == () and "shorter than" in res.explanations[0].note
    steps = res.explanations[1].steps
    assert [s.skill for s in steps] in ([0, 1], [1, 0])
    assert steps[0].start == 0.0 and steps[-1].end == 2.0 and steps[0].end == steps[1].start
    assert abs(steps[1].start - 1.0) < 0.3  # the move starts at 1 s (0.4-s smoothing)
    ex = res.steps_by_key()["c1"]
    assert ex[0]["steps"] == [] and "note" in ex[0] and "note" not in ex[1]
    with pytest.raises(PrimitiveError, match="1 to 100 skills"):
        explain_constraint_motions([seg], n_skills=0)
    with pytest.raises(PrimitiveError, match="no constraint motion"):
        explain_constraint_motions([])


@pytest.mark.slow
def test_noisy_chair_legs_share_their_turn_skill() -> None:
    """With tracker noise and gaps (the demo's sensor), every screwing turn is one skill."""
    demo = make_scene("chair", seed=0)
    segs = constraint_segments(demo)
    res = explain_constraint_motions(segs, n_skills=K)
    turn = _roles({"skill_library": res.library_block()})["turn"]
    for seg, ex in zip(segs, res.explanations, strict=True):
        n_turn = ex.skills.count(turn)
        if seg.event.child.startswith("leg"):
            assert n_turn == _true_turns_noisy(demo, seg), (seg.key, ex.skills)
        else:
            assert n_turn == 0


def _true_turns_noisy(demo, seg: ConstraintSegment) -> int:
    clean = make_scene("chair", seed=0, sensor=None)
    return _true_turns(clean, seg.event.child)
