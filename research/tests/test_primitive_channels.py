"""Level channels of two-arm recordings: object frame, signed wrench, body rates, logs.

Every expected value is worked out by hand from a synthetic recording whose
poses are known in closed form (100 Hz, no noise, ``window=1``).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from research.primitive_channels import (
    LEVEL_UNITS,
    LOG_UNIT,
    object_frame_position,
    stream_channels,
)
from thirdhand.io.figueroa import ArmTrack, LabelledStream
from thirdhand.primitives.checks import PrimitiveError

N = 200
DT = 0.01
T = np.arange(N) * DT


def _still(pos: list[float], rot: Rotation) -> ArmTrack:
    return ArmTrack(
        np.tile(pos, (N, 1)), np.tile(rot.as_quat(), (N, 1)), np.zeros((N, 3)), np.zeros((N, 3))
    )


def _stream(*arms: ArmTrack) -> LabelledStream:
    return LabelledStream("pair", T, tuple(arms), np.ones(N, dtype=np.int64))


def _moved(arm: ArmTrack, rot: Rotation, shift: np.ndarray) -> ArmTrack:
    """The same arm after a rigid motion ``x → rot x + shift`` of the whole scene."""
    quat = (rot * Rotation.from_quat(arm.quat)).as_quat()
    quat *= np.sign(np.sum(quat * arm.quat, axis=1, keepdims=True) + 1e-300)
    return ArmTrack(rot.apply(arm.pos) + shift, quat, arm.force, arm.torque)


def test_object_frame_position_and_velocity_of_a_tool_moving_past_a_turned_holder() -> None:
    # the holder is turned 90° about base z: its x axis is the base's y axis; the tool
    # moves along base +y at 0.2 m/s from 0.1 m above the holder
    holder = _still([0.5, 0.0, 0.3], Rotation.from_euler("z", 90, degrees=True))
    tool = _still([0.5, 0.0, 0.4], Rotation.identity())
    tool = ArmTrack(tool.pos + np.outer(T, [0.0, 0.2, 0.0]), tool.quat, tool.force, tool.torque)
    _, lev = stream_channels(_stream(tool, holder), levels=("objpos", "objvel"), window=1)
    assert lev.shape == (N, 6)
    # base +y is the holder's +x; base z is its z
    expected_pos = np.column_stack([0.2 * T, np.zeros(N), np.full(N, 0.1)])
    np.testing.assert_allclose(lev[:, :3] * LEVEL_UNITS["objpos"], expected_pos, atol=1e-12)
    np.testing.assert_allclose(lev[:, 3:] * LEVEL_UNITS["objvel"], [[0.2, 0, 0]] * N, atol=1e-9)


def test_object_frame_velocity_of_a_still_tool_over_a_turning_object() -> None:
    # the holder turns about base z at 0.5 rad/s; the tool stands still 0.1 m along base x:
    # seen from the object it circles backwards, v = −ω × p with |v| = 0.05 m/s
    w = 0.5
    rot = Rotation.from_rotvec(np.outer(w * T, [0.0, 0.0, 1.0]))
    holder = ArmTrack(np.zeros((N, 3)), rot.as_quat(), np.zeros((N, 3)), np.zeros((N, 3)))
    tool = _still([0.1, 0.0, 0.0], Rotation.identity())
    _, lev = stream_channels(_stream(tool, holder), levels=("objpos", "objvel"), window=1)
    p = lev[:, :3] * LEVEL_UNITS["objpos"]
    np.testing.assert_allclose(
        p, np.column_stack([0.1 * np.cos(w * T), -0.1 * np.sin(w * T), 0 * T]), atol=1e-12
    )
    v = lev[:, 3:] * LEVEL_UNITS["objvel"]
    expected = -np.cross([0.0, 0.0, w], p)
    # central differences of a circle of radius 0.1 at ω dt = 0.005: relative error ω²dt²/6
    np.testing.assert_allclose(v[1:-1], expected[1:-1], atol=0.05 * (w * DT) ** 2)
    np.testing.assert_allclose(np.linalg.norm(v[1:-1], axis=1), 0.05, rtol=1e-5)


def test_cylindrical_object_frame_ignores_a_turn_about_the_holders_flange_axis() -> None:
    # the holder (tilted 30° about base x) turns about its own z axis at 0.5 rad/s; the
    # tool, 0.05 m from that axis and 0.2 m along it, turns with the object and also
    # slides along the axis at 0.1 m/s
    w = 0.5
    tilt = Rotation.from_euler("x", 30, degrees=True)
    rot = tilt * Rotation.from_rotvec(np.outer(w * T, [0.0, 0.0, 1.0]))
    holder = ArmTrack(np.full((N, 3), 0.3), rot.as_quat(), np.zeros((N, 3)), np.zeros((N, 3)))
    local = np.column_stack([np.full(N, 0.05), np.zeros(N), 0.2 + 0.1 * T])
    tool_pos = holder.pos + rot.apply(local)
    tool = ArmTrack(tool_pos, np.tile([0.0, 0.0, 0.0, 1.0], (N, 1)), holder.force, holder.force)
    names = ("objpos", "objcyl", "objcylvel")
    _, lev = stream_channels(_stream(tool, holder), levels=names, window=1)
    assert lev.shape == (N, 3 + 2 + 2)
    np.testing.assert_allclose(lev[:, :3] * LEVEL_UNITS["objpos"], local, atol=1e-12)
    np.testing.assert_allclose(lev[:, 3] * LEVEL_UNITS["objcyl"], 0.05, atol=1e-12)
    np.testing.assert_allclose(lev[:, 4] * LEVEL_UNITS["objcyl"], local[:, 2], atol=1e-12)
    np.testing.assert_allclose(lev[:, 5:] * LEVEL_UNITS["objcylvel"], [[0, 0.1]] * N, atol=1e-9)
    # a turn of the object under a tool still in the base frame moves objpos round the
    # axis, but neither the distance from the axis nor the position along it
    still = ArmTrack(np.tile(tool_pos[0], (N, 1)), tool.quat, tool.force, tool.torque)
    _, lev = stream_channels(_stream(still, holder), levels=names, window=1)
    obj = lev[:, :3] * LEVEL_UNITS["objpos"]
    assert np.ptp(obj[:, 0]) > 0.002  # 0.05 m · (1 − cos 1 rad)
    np.testing.assert_allclose(lev[:, 3] * LEVEL_UNITS["objcyl"], 0.05, atol=1e-12)
    np.testing.assert_allclose(lev[:, 4] * LEVEL_UNITS["objcyl"], 0.2, atol=1e-12)
    np.testing.assert_allclose(lev[:, 5:], 0.0, atol=1e-9)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_object_frame_and_own_frame_channels_ignore_a_rigid_motion_of_the_scene(seed: int) -> None:
    rng = np.random.default_rng(seed)
    # a holder and a tool both turning and moving along smooth, arbitrary paths
    wh, wt = rng.normal(size=3), rng.normal(size=3)
    holder = ArmTrack(
        np.outer(np.sin(T), rng.normal(size=3)) * 0.1,
        Rotation.from_rotvec(np.outer(T, wh)).as_quat(),
        rng.normal(size=(N, 3)),
        rng.normal(size=(N, 3)),
    )
    tool = ArmTrack(
        np.outer(T**2, rng.normal(size=3)) * 0.1 + rng.normal(size=3),
        (
            Rotation.from_rotvec(rng.normal(size=3)) * Rotation.from_rotvec(np.outer(T, wt))
        ).as_quat(),
        rng.normal(size=(N, 3)),
        rng.normal(size=(N, 3)),
    )
    motion, shift = Rotation.from_rotvec(rng.normal(size=3)), rng.normal(size=3)
    names = (
        "objpos",
        "objvel",
        "holdangular",
        "objcyl",
        "objcylvel",
        "forcevec",
        "torquevec",
        "bodyangular",
        "logspeed",
        "angular",
    )
    _, before = stream_channels(_stream(tool, holder), levels=names, window=3)
    moved = _stream(_moved(tool, motion, shift), _moved(holder, motion, shift))
    _, after = stream_channels(moved, levels=names, window=3)
    np.testing.assert_allclose(after, before, atol=1e-9)
    # the base-frame difference is not invariant: it turns with the scene
    _, rel0 = stream_channels(_stream(tool, holder), levels=("relpos",), window=1)
    _, rel1 = stream_channels(moved, levels=("relpos",), window=1)
    np.testing.assert_allclose(rel1, motion.apply(rel0), atol=1e-9)
    assert np.abs(rel1 - rel0).max() > 1.0


def test_body_angular_velocity_is_about_the_arms_own_axes() -> None:
    # turned 90° about base z, then spinning at 0.5 rad/s about its own x axis: in the
    # base frame that axis is +y; about its own axes the rate is (0.5, 0, 0)
    rot = Rotation.from_euler("z", 90, degrees=True) * Rotation.from_rotvec(
        np.outer(0.5 * T, [1.0, 0.0, 0.0])
    )
    arm = ArmTrack(np.zeros((N, 3)), rot.as_quat(), np.zeros((N, 3)), np.zeros((N, 3)))
    _, lev = stream_channels(_stream(arm), levels=("bodyangular", "angular"), window=1)
    np.testing.assert_allclose(
        lev[:, :3] * LEVEL_UNITS["bodyangular"], [[0.5, 0, 0]] * N, atol=1e-9
    )
    np.testing.assert_allclose(lev[:, 3] * LEVEL_UNITS["angular"], 0.5, atol=1e-9)
    # as the holder of a pair: the same three columns, once, for the second arm only
    tool = _still([0.0, 0.0, 0.1], Rotation.from_euler("y", 30, degrees=True))
    _, pair = stream_channels(_stream(tool, arm), levels=("holdangular",), window=1)
    assert pair.shape == (N, 3)
    np.testing.assert_allclose(pair * LEVEL_UNITS["holdangular"], [[0.5, 0, 0]] * N, atol=1e-9)


def test_signed_wrench_and_log_magnitudes() -> None:
    arm = _still([0.0, 0.0, 0.0], Rotation.identity())
    force = np.zeros((N, 3))
    force[:, 2] = np.where(T < 1.0, 4.0, -4.0)  # pressing, then pulling, with the same magnitude
    arm = ArmTrack(arm.pos + np.outer(T, [0.06, 0.0, 0.0]), arm.quat, force, np.zeros((N, 3)))
    names = ("forcevec", "force", "logforce", "logspeed", "logtorque")
    _, lev = stream_channels(_stream(arm), levels=names, window=1)
    assert lev.shape == (N, 3 + 4)
    np.testing.assert_allclose(lev[:, 2] * LEVEL_UNITS["forcevec"], force[:, 2])
    np.testing.assert_allclose(lev[:, 3] * LEVEL_UNITS["force"], 4.0)  # the magnitude cannot tell
    # log1p of the magnitude in its linear unit, in thirds of an e-fold
    np.testing.assert_allclose(lev[:, 4], np.log1p(4.0 / LEVEL_UNITS["force"]) / LOG_UNIT)
    np.testing.assert_allclose(
        lev[:, 5], np.log1p(0.06 / LEVEL_UNITS["speed"]) / LOG_UNIT, rtol=1e-9
    )
    np.testing.assert_allclose(lev[:, 6], 0.0)  # no torque: log1p(0) = 0


def test_object_frame_position_function_and_pair_channel_errors() -> None:
    holder = _still([1.0, 2.0, 3.0], Rotation.from_euler("x", 180, degrees=True))
    tool = _still([1.0, 2.5, 3.0], Rotation.identity())
    # the holder's y axis points along base −y after a half turn about x
    np.testing.assert_allclose(
        object_frame_position(tool, holder), [[0.0, -0.5, 0.0]] * N, atol=1e-12
    )
    with pytest.raises(PrimitiveError, match="level 'objvel' needs two arms, got 1"):
        stream_channels(_stream(tool, holder), levels=("objvel",), arms=(0,))


def test_cli_levels_help_names_every_level_channel() -> None:
    import inspect

    from research import primitive_channels as channels
    from research.primitives_evaluate import evaluate

    help_text = inspect.signature(evaluate).parameters["levels"].annotation
    words = set(str(help_text).replace(",", " ").replace(";", " ").split())
    assert set(channels.LEVEL_UNITS) <= words
