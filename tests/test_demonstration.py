"""The Demonstration core type: validation, resampling, slicing, relative poses, gap filling."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from thirdhand import (
    BodyInfo,
    ConstraintEvent,
    Demonstration,
    DemonstrationError,
    InteractionInterval,
    Labels,
    PlanStep,
    se3,
)
from thirdhand.demonstration import FreeDofs, labels_from_dict, labels_to_dict


def _demo(n: int = 100, rate: float = 100.0, seed: int = 0) -> Demonstration:
    rng = np.random.default_rng(seed)
    t = np.arange(n) / rate
    pos = {"a": rng.normal(size=(n, 3)), "b": rng.normal(size=(n, 3))}
    quat = {"a": se3.random_quat(rng, n), "b": se3.random_quat(rng, n)}
    return Demonstration(t, [BodyInfo("a"), BodyInfo("b", "finger", hand="left")], pos, quat)


def test_basic_properties() -> None:
    d = _demo()
    assert d.n_frames == 100 and d.body_names == ["a", "b"]
    assert d.rate == pytest.approx(100.0)
    assert d.duration == pytest.approx(0.99)
    assert d.info("b").hand == "left"
    assert d.bodies_of_kind("finger") == ["b"]
    pos, quat, valid = d.stacked()
    assert pos.shape == (2, 100, 3) and quat.shape == (2, 100, 4) and valid.all()


def test_arrays_are_read_only() -> None:
    d = _demo()
    with pytest.raises(ValueError):
        d.pos("a")[0, 0] = 1.0


@pytest.mark.parametrize(
    ("t", "match"),
    [
        ([], "empty"),
        ([0.0, 0.1, 0.1], "not strictly increasing at frame 2"),
        ([0.0, np.nan], "frame 1 is not finite"),
    ],
)
def test_bad_time_axis(t: list[float], match: str) -> None:
    n = len(t)
    with pytest.raises(DemonstrationError, match=match):
        Demonstration(
            t,
            [BodyInfo("a")],
            {"a": np.zeros((n, 3))},
            {"a": np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))},
        )


def test_zero_quaternion_names_body_and_frame() -> None:
    q = np.tile([0.0, 0, 0, 1], (5, 1))
    q[3] = 0
    with pytest.raises(DemonstrationError, match=r"body 'a' frame 3: zero-norm quaternion"):
        Demonstration(np.arange(5.0), [BodyInfo("a")], {"a": np.zeros((5, 3))}, {"a": q})


def test_unit_mix_up_detected() -> None:
    p = np.zeros((5, 3))
    p[2] = [1500.0, 20.0, 3.0]  # millimetres
    with pytest.raises(DemonstrationError, match=r"frame 2.*millimetres"):
        Demonstration(
            np.arange(5.0), [BodyInfo("a")], {"a": p}, {"a": np.tile([0.0, 0.0, 0.0, 1.0], (5, 1))}
        )


def test_shape_and_metadata_errors() -> None:
    with pytest.raises(DemonstrationError, match=r"body 'a': positions must have shape \(5, 3\)"):
        Demonstration(
            np.arange(5.0),
            [BodyInfo("a")],
            {"a": np.zeros((4, 3))},
            {"a": np.tile([0.0, 0.0, 0.0, 1.0], (5, 1))},
        )
    with pytest.raises(DemonstrationError, match="kind must be one of"):
        BodyInfo("a", kind="robot")  # type: ignore[arg-type]
    with pytest.raises(DemonstrationError, match="appears twice"):
        Demonstration(
            np.arange(2.0),
            [BodyInfo("a"), BodyInfo("a")],
            {"a": np.zeros((2, 3))},
            {"a": np.tile([0.0, 0.0, 0.0, 1.0], (2, 1))},
        )


def test_label_naming_unknown_body() -> None:
    lab = Labels(interactions=(InteractionInterval("a", "ghost", 0.0, 1.0),))
    with pytest.raises(DemonstrationError, match="unknown body: ghost"):
        Demonstration(
            np.arange(3.0),
            [BodyInfo("a")],
            {"a": np.zeros((3, 3))},
            {"a": np.tile([0.0, 0.0, 0.0, 1.0], (3, 1))},
            labels=lab,
        )


def test_valid_mask_and_nan_storage() -> None:
    p = np.ones((4, 3))
    p[1] = np.nan
    d = Demonstration(
        np.arange(4.0), [BodyInfo("a")], {"a": p}, {"a": np.tile([0, 0, 0, 1.005], (4, 1))}
    )
    assert d.valid("a").tolist() == [True, False, True, True]
    assert np.isnan(d.quat("a")[1]).all()
    np.testing.assert_allclose(d.quat("a")[0], [0, 0, 0, 1])  # rounding within 0.01 renormalised
    with pytest.raises(DemonstrationError, match="frame 0: quaternion has norm 149112"):
        Demonstration(
            np.arange(4.0), [BodyInfo("a")], {"a": p}, {"a": np.tile([0, 0, 0, 149112], (4, 1))}
        )
    assert d.missing_fraction("a") == 0.25
    with pytest.raises(DemonstrationError, match="marked valid but pose is not finite"):
        Demonstration(
            np.arange(4.0),
            [BodyInfo("a")],
            {"a": p},
            {"a": np.tile([0.0, 0.0, 0.0, 1.0], (4, 1))},
            {"a": np.ones(4, bool)},
        )


def test_position_only_body_gets_identity() -> None:
    p = np.ones((3, 3))
    p[1] = np.nan
    d = Demonstration(
        np.arange(3.0), [BodyInfo("m", oriented=False)], {"m": p}, {"m": np.full((3, 4), np.nan)}
    )
    assert d.valid("m").tolist() == [True, False, True]
    np.testing.assert_array_equal(d.quat("m")[0], [0, 0, 0, 1])


def test_resample_reproduces_linear_and_constant_rotation_motion() -> None:
    t = np.arange(0, 2.0001, 0.01)
    axis_angle = 0.5 * t[:, None] * [0, 0, 1]  # constant angular velocity: slerp is exact
    q = Rotation.from_rotvec(axis_angle).as_quat()
    p = np.column_stack([t, 2 * t, -t])
    d = Demonstration(t, [BodyInfo("a")], {"a": p}, {"a": q})
    r = d.resample(37.0)
    np.testing.assert_allclose(r.pos("a"), np.column_stack([r.t, 2 * r.t, -r.t]), atol=1e-12)
    ref = Rotation.from_rotvec(0.5 * r.t[:, None] * [0, 0, 1]).as_quat()
    assert np.all(se3.quat_angle(r.quat("a"), ref) < 1e-9)
    assert r.rate == pytest.approx(37.0)


def test_resample_never_bridges_long_gaps() -> None:
    t = np.arange(100) / 100.0
    p = np.zeros((100, 3))
    p[20:60] = np.nan  # a 0.41 s gap
    p[80:83] = np.nan  # a 0.04 s gap
    d = Demonstration(t, [BodyInfo("a")], {"a": p}, {"a": np.tile([0, 0, 0, 1.0], (100, 1))})
    r = d.resample(200.0, max_gap=0.1)
    gap_long = (r.t > 0.195) & (r.t < 0.595)
    assert not r.valid("a")[gap_long].any()
    gap_short = (r.t > 0.795) & (r.t < 0.825)
    assert r.valid("a")[gap_short].all()


def test_fill_gaps_is_opt_in_and_bounded() -> None:
    t = np.arange(50) / 100.0
    p = np.column_stack([t, t, t])
    p[10:13] = np.nan  # 40 ms between valid neighbours
    p[30:45] = np.nan  # 160 ms
    d = Demonstration(t, [BodyInfo("a")], {"a": p}, {"a": np.tile([0, 0, 0, 1.0], (50, 1))})
    assert not d.valid("a")[10:13].any()
    f = d.fill_gaps(0.05)
    assert f.valid("a")[10:13].all() and not f.valid("a")[30:45].any()
    np.testing.assert_allclose(f.pos("a")[10:13], np.column_stack([t, t, t])[10:13], atol=1e-12)


def test_slice_and_select_clip_labels() -> None:
    d = _demo()
    lab = Labels(
        interactions=(InteractionInterval("a", "b", 0.2, 0.5),),
        constraints=(ConstraintEvent(0.7, "a", "b", "fixed"),),
        plan=(PlanStep("a", "b", "c1", 0.7),),
    )
    d = d.replace(labels=lab)
    s = d.slice(0.3, 0.6)
    assert s.t[0] == pytest.approx(0.3) and s.t[-1] == pytest.approx(0.6)
    assert s.labels.interactions[0].start == pytest.approx(0.3)
    assert s.labels.constraints == ()
    assert d.select(["a"]).labels.interactions == ()
    with pytest.raises(DemonstrationError, match="no body named 'zz'"):
        d.select(["zz"])
    with pytest.raises(DemonstrationError, match="holds no frame"):
        d.slice(5.0, 6.0)


def test_relative_pose_of_rigidly_attached_bodies_is_constant(rng: np.random.Generator) -> None:
    n = 60
    qa = se3.random_quat(rng, n)
    pa = rng.normal(size=(n, 3))
    p_ab, q_ab = np.array([0.1, -0.2, 0.3]), se3.random_quat(rng)
    pb, qb = se3.pose_compose(pa, qa, np.broadcast_to(p_ab, (n, 3)), np.broadcast_to(q_ab, (n, 4)))
    qb = qb * rng.choice([-1.0, 1.0], size=(n, 1))  # sign flips must not matter
    pa[5] = np.nan
    d = Demonstration(
        np.arange(n) / 100, [BodyInfo("a"), BodyInfo("b")], {"a": pa, "b": pb}, {"a": qa, "b": qb}
    )
    p, q, v = d.relative_pose("a", "b")
    assert not v[5] and v.sum() == n - 1
    np.testing.assert_allclose(p[v], np.broadcast_to(p_ab, (n - 1, 3)), atol=1e-12)
    assert np.all(se3.quat_angle(q[v], q_ab) < 1e-7)
    assert np.all(np.sum(q[v][1:] * q[v][:-1], axis=1) > 0)


def test_labels_dict_round_trip() -> None:
    lab = Labels(
        interactions=(InteractionInterval("a", "b", 0.2, 0.5),),
        constraints=(
            ConstraintEvent(
                0.7,
                "a",
                "b",
                "revolute",
                (0.1, 0.2, 0.3),
                (0, 0, 0, 1.0),
                ((0, 0),) * 3 + ((-np.pi, np.pi),) + ((0, 0),) * 2,
                "c3",
            ),
        ),
        plan=(PlanStep("a", "b", "c3", 0.7),),
    )
    assert labels_from_dict(labels_to_dict(lab)) == lab
    with pytest.raises(DemonstrationError, match="malformed labels"):
        labels_from_dict({"interactions": [{"a": "x"}]})


def test_constraint_event_checks() -> None:
    with pytest.raises(DemonstrationError, match="type must be one of"):
        ConstraintEvent(0.0, "a", "b", "glued")
    with pytest.raises(DemonstrationError, match=r"a->b: free DOFs: DOF tx: range .* min > max"):
        ConstraintEvent(0.0, "a", "b", "fixed", free_dofs=((1, 0),) + ((0, 0),) * 5)
    with pytest.raises(DemonstrationError, match=r"shape \(6, 2\)"):
        ConstraintEvent(0.0, "a", "b", "fixed", free_dofs=((0, 0),) * 5)
    with pytest.raises(DemonstrationError, match=r"DOF rz: range .* not finite"):
        ConstraintEvent(0.0, "a", "b", "fixed", free_dofs=((0, 0),) * 5 + ((0, math.inf),))
    # Pairs are converted to the one free-DOF value, equal to one built by name.
    pairs = ((0, 0),) * 3 + ((-1, 1),) + ((0, 0),) * 2
    ev = ConstraintEvent(0.0, "a", "b", "revolute", free_dofs=pairs)  # type: ignore[arg-type]
    assert ev.free_dofs == FreeDofs(rx=(-1.0, 1.0)) and ev.free_dofs.free() == ["rx"]
    assert hash(ev) == hash(dataclasses.replace(ev))


def test_free_dofs_value() -> None:
    fd = FreeDofs(tz=(0.0, 0.05), rx=(-math.pi, math.pi), ry=(0.2, 0.2))
    expected = [[0.0, 0.05], [-math.pi, math.pi], [0.2, 0.2]]
    np.testing.assert_array_equal(fd.array()[[2, 3, 4]], expected)
    assert FreeDofs.from_array(fd.array()) == fd
    assert fd.free() == ["tz", "rx"]  # ry has no width: locked at 0.2 rad
    assert dataclasses.replace(fd, tz=(0.0, 0.0)).free() == ["rx"]
    with pytest.raises(ValueError, match="DOF ty: expected a range"):
        FreeDofs(ty=(1.0,))  # type: ignore[arg-type]
    with pytest.raises(KeyError, match="unknown DOF 'Tx'"):
        fd["Tx"]
    with pytest.raises(dataclasses.FrozenInstanceError):
        fd.tx = (0.0, 1.0)  # type: ignore[misc]


def test_continuous_quaternions() -> None:
    d = _demo()
    c = d.with_continuous_quaternions()
    q = c.quat("a")
    assert np.all(np.sum(q[1:] * q[:-1], axis=1) >= 0)
    assert np.all(se3.quat_angle(q, d.quat("a")) < 1e-7)
