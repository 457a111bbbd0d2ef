"""The MCAP reader against a file written by another writer (``mcap`` + ``mcap-ros2-support``).

The file is built here with the foreign writer, message by message (CDR encoded by
``mcap_ros2``, schemas as ROS 2 ``.msg`` text): a ``PoseStamped`` topic at 50 Hz and
a ``/tf`` tree ``world -> table -> leg`` at 100 Hz, plus a topic that carries no
pose. Our reader must give back the very poses and stamps written.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cli_helpers import call
from thirdhand import se3
from thirdhand.errors import FormatError
from thirdhand.io import load

mcap_ros2_writer = pytest.importorskip("mcap_ros2.writer")

NS = 1_000_000_000
T0 = 1_750_000_000 * NS + 123_456_789

SEP = "=" * 80 + "\n"
TIME = "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
HEADER = "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n"
POINT = "MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n"
VECTOR3 = "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n"
QUAT = "MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n"
POSE = (
    "MSG: geometry_msgs/Pose\ngeometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n"
)
TRANSFORM = (
    "MSG: geometry_msgs/Transform\ngeometry_msgs/Vector3 translation\n"
    "geometry_msgs/Quaternion rotation\n"
)
TRANSFORM_STAMPED = (
    "MSG: geometry_msgs/TransformStamped\nstd_msgs/Header header\nstring child_frame_id\n"
    "geometry_msgs/Transform transform\n"
)
POSE_STAMPED_DEF = "std_msgs/Header header\ngeometry_msgs/Pose pose\n" + "".join(
    SEP + d for d in (HEADER, TIME, POSE, POINT, QUAT)
)
TF_DEF = "geometry_msgs/TransformStamped[] transforms\n" + "".join(
    SEP + d for d in (TRANSFORM_STAMPED, HEADER, TIME, TRANSFORM, VECTOR3, QUAT)
)
FLOAT64_DEF = "float64 data\n"


def _header(stamp: int, frame: str) -> dict[str, object]:
    return {"stamp": {"sec": stamp // NS, "nanosec": stamp % NS}, "frame_id": frame}


def _quat(rng: np.random.Generator) -> np.ndarray:
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    return q if q[3] >= 0 else -q


def _pose_dict(p: np.ndarray, q: np.ndarray) -> dict[str, object]:
    return {
        "position": dict(zip("xyz", map(float, p), strict=True)),
        "orientation": dict(zip("xyzw", map(float, q), strict=True)),
    }


def _transform(stamp: int, parent: str, child: str, p: np.ndarray, q: np.ndarray) -> dict:
    return {
        "header": _header(stamp, parent),
        "child_frame_id": child,
        "transform": {
            "translation": dict(zip("xyz", map(float, p), strict=True)),
            "rotation": dict(zip("xyzw", map(float, q), strict=True)),
        },
    }


def _write_foreign(path: Path, *, poses: bool = True) -> dict[str, object]:
    """An MCAP written with ``mcap_ros2``; returns what was written."""
    rng = np.random.default_rng(21)
    n_tf, n_cam = 40, 20
    tf_stamps = T0 + np.arange(n_tf) * 10_000_000  # 100 Hz
    cam_stamps = T0 + 3_000_000 + np.arange(n_cam) * 20_000_000  # 50 Hz, 3 ms after
    table_p = rng.normal(scale=0.5, size=(n_tf, 3))
    table_q = np.array([_quat(rng) for _ in range(n_tf)])
    leg_p = rng.normal(scale=0.2, size=(n_tf, 3))
    leg_q = np.array([_quat(rng) for _ in range(n_tf)])
    cam_p = rng.normal(scale=1.0, size=(n_cam, 3))
    cam_q = np.array([_quat(rng) for _ in range(n_cam)])
    with open(path, "wb") as fh:
        w = mcap_ros2_writer.Writer(fh)
        battery = w.register_msgdef("std_msgs/msg/Float64", FLOAT64_DEF)
        if poses:
            pose_schema = w.register_msgdef("geometry_msgs/msg/PoseStamped", POSE_STAMPED_DEF)
            tf_schema = w.register_msgdef("tf2_msgs/msg/TFMessage", TF_DEF)
        events = []
        for i, s in enumerate(tf_stamps):
            events.append((int(s), 0, i))
        for i, s in enumerate(cam_stamps):
            events.append((int(s), 1, i))
        for stamp, kind, i in sorted(events):
            w.write_message("/battery", battery, {"data": 12.0 - i * 0.01}, log_time=stamp)
            if not poses:
                continue
            if kind == 0:
                msg = {
                    "transforms": [
                        _transform(stamp, "world", "table", table_p[i], table_q[i]),
                        _transform(stamp, "table", "leg", leg_p[i], leg_q[i]),
                    ]
                }
                w.write_message("/tf", tf_schema, msg, log_time=stamp + 500)
            else:
                msg = {"header": _header(stamp, "world"), "pose": _pose_dict(cam_p[i], cam_q[i])}
                w.write_message("/camera/pose", pose_schema, msg, log_time=stamp + 700)
        w.finish()
    return {
        "tf_stamps": tf_stamps,
        "cam_stamps": cam_stamps,
        "table": (table_p, table_q),
        "leg": (leg_p, leg_q),
        "camera": (cam_p, cam_q),
    }


def _same_rotation(q: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """|q . ref|, 1 when the two quaternions are the same rotation."""
    return np.abs(np.sum(q * ref, axis=1))


def test_foreign_mcap_poses_and_stamps_read_exactly(tmp_path: Path) -> None:
    path = tmp_path / "foreign.mcap"
    truth = _write_foreign(path)
    demo = load(path)
    assert set(demo.body_names) == {"table", "leg", "camera/pose"}
    tf_stamps = np.asarray(truth["tf_stamps"])
    cam_stamps = np.asarray(truth["cam_stamps"])
    # Time axis: the union of the stamps (3 ms apart, beyond the 1 ms merge tolerance).
    all_ns = np.union1d(tf_stamps, cam_stamps)
    assert demo.meta["start_time_ns"] == int(all_ns[0])
    np.testing.assert_array_equal(
        np.round(demo.t * NS).astype(np.int64), all_ns - all_ns[0], strict=True
    )
    in_tf = np.isin(all_ns, tf_stamps)
    in_cam = np.isin(all_ns, cam_stamps)
    np.testing.assert_array_equal(demo.valid("table"), in_tf)
    np.testing.assert_array_equal(demo.valid("leg"), in_tf)
    np.testing.assert_array_equal(demo.valid("camera/pose"), in_cam)

    table_p, table_q = truth["table"]  # type: ignore[misc]
    leg_p, leg_q = truth["leg"]  # type: ignore[misc]
    cam_p, cam_q = truth["camera"]  # type: ignore[misc]
    # Directly published values: bit for bit.
    np.testing.assert_array_equal(demo.pos("table")[in_tf], table_p)
    np.testing.assert_allclose(_same_rotation(demo.quat("table")[in_tf], table_q), 1.0, atol=1e-15)
    np.testing.assert_array_equal(demo.pos("camera/pose")[in_cam], cam_p)
    np.testing.assert_allclose(
        _same_rotation(demo.quat("camera/pose")[in_cam], cam_q), 1.0, atol=1e-15
    )
    # The leg composed along the tree world -> table -> leg.
    want_p, want_q = se3.pose_compose(table_p, table_q, leg_p, leg_q)
    np.testing.assert_allclose(demo.pos("leg")[in_tf], want_p, rtol=0, atol=1e-14)
    np.testing.assert_allclose(_same_rotation(demo.quat("leg")[in_tf], want_q), 1.0, atol=1e-14)
    assert demo.meta["ros_version"] == 2
    assert "/battery" in demo.meta["unused_topics"]


def test_foreign_mcap_without_pose_topic_is_one_clear_error(tmp_path: Path) -> None:
    path = tmp_path / "battery.mcap"
    _write_foreign(path, poses=False)
    with pytest.raises(FormatError) as err:
        load(path)
    text = str(err.value)
    assert "battery.mcap" in text and "no pose topic" in text and "/battery" in text
    assert "\n" not in text


def test_foreign_mcap_without_pose_topic_cli(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "battery.mcap"
    _write_foreign(path, poses=False)
    target = tmp_path / "out.parquet"
    rc, _, err = call(capsys, "convert", str(path), str(target))
    assert rc == 1
    assert err.count("\n") == 1 and "no pose topic" in err
    assert not target.exists()
