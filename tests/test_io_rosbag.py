"""ROS 1 / ROS 2 bags: the real Niekum IKEA bags, round trips, tf composition, malformed input."""

from __future__ import annotations

import importlib.util
from collections.abc import Sequence
from pathlib import Path
from typing import Any, cast

import numpy as np
import pytest
from numpy.typing import ArrayLike
from rosbags.highlevel import AnyReader
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from thirdhand import se3
from thirdhand.demonstration import (
    BodyInfo,
    ConstraintEvent,
    Demonstration,
    InteractionInterval,
    Labels,
    PlanStep,
)
from thirdhand.errors import FormatError
from thirdhand.io import FORMATS, rosbag

NS = 1_000_000_000
T0 = 1_700_000_000 * NS
IKEA = "niekum/ikea_table_leg_pos_1"


# ------------------------------------------------------------------ helpers
def _store(version: int, extra: dict[str, str] | None = None) -> Typestore:
    store = get_typestore(Stores.ROS1_NOETIC if version == 1 else Stores.LATEST)
    if version == 1:
        store.register(
            get_types_from_msg(
                "geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"
            )
        )
    for name, text in (extra or {}).items():
        store.register(get_types_from_msg(text, name))
    return store


class Msgs:
    """Builds messages of one typestore."""

    def __init__(self, store: Typestore) -> None:
        self.store = store
        self.t = store.types

    def header(self, stamp: int, frame: str = "world") -> Any:
        time = self.t["builtin_interfaces/msg/Time"](sec=stamp // NS, nanosec=stamp % NS)
        h = self.t["std_msgs/msg/Header"]
        if "seq" in dict(self.store.fielddefs["std_msgs/msg/Header"][1]):
            return h(seq=0, stamp=time, frame_id=frame)
        return h(stamp=time, frame_id=frame)

    def pose(self, p: ArrayLike, q: ArrayLike) -> Any:
        t = self.t
        x, y, z = np.asarray(p, dtype=float).tolist()
        qx, qy, qz, qw = np.asarray(q, dtype=float).tolist()
        return t["geometry_msgs/msg/Pose"](
            position=t["geometry_msgs/msg/Point"](x=x, y=y, z=z),
            orientation=t["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw),
        )

    def pose_stamped(self, stamp: int, p: ArrayLike, q: ArrayLike) -> Any:
        return self.t["geometry_msgs/msg/PoseStamped"](
            header=self.header(stamp), pose=self.pose(p, q)
        )

    def transform(self, stamp: int, parent: str, child: str, p: ArrayLike, q: ArrayLike) -> Any:
        t = self.t
        x, y, z = np.asarray(p, dtype=float).tolist()
        qx, qy, qz, qw = np.asarray(q, dtype=float).tolist()
        tr = t["geometry_msgs/msg/Transform"](
            translation=t["geometry_msgs/msg/Vector3"](x=x, y=y, z=z),
            rotation=t["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw),
        )
        return t["geometry_msgs/msg/TransformStamped"](
            header=self.header(stamp, parent), child_frame_id=child, transform=tr
        )

    def tf(self, *transforms: Any) -> Any:
        return self.t["tf2_msgs/msg/TFMessage"](transforms=list(transforms))


def write_raw(
    path: Path, store: Typestore, version: int, entries: Sequence[tuple[str, str, int, Any]]
) -> Path:
    """Write ``(topic, msgtype, receive_ns, message)`` entries as a ROS 1 or ROS 2 bag."""
    writer = Writer1(path) if version == 1 else Writer2(path, version=9)
    with writer as w:
        conns: dict[str, Any] = {}
        for topic, typ, stamp, msg in entries:
            if topic not in conns:
                conns[topic] = w.add_connection(topic, typ, typestore=store)
            data = store.serialize_ros1(msg, typ) if version == 1 else store.serialize_cdr(msg, typ)
            w.write(conns[topic], stamp, data)
    return path


def synthetic_demo(rng: np.random.Generator, n: int = 40) -> Demonstration:
    t = 5.25 + np.cumsum(rng.uniform(0.005, 0.02, n))
    bodies = [
        BodyInfo("seat", "part"),
        BodyInfo("/human/rh/thumb", "finger", hand="right", hand_body="p1/right"),
        BodyInfo("marker 1", "tool", oriented=False),
    ]
    pos = {b.name: rng.uniform(-1, 1, (n, 3)) for b in bodies}
    quat = {b.name: se3.random_quat(rng, n) for b in bodies}
    valid = {b.name: rng.random(n) > 0.3 for b in bodies}
    valid["seat"][:] = True
    valid["seat"][7] = False
    for v in valid.values():
        v[7] = False  # a frame where no body is seen
    labels = Labels(
        interactions=(InteractionInterval("seat", "/human/rh/thumb", 5.3, 5.5),),
        constraints=(ConstraintEvent(5.4, "seat", "marker 1", "fixed"),),
        plan=(PlanStep("seat", "marker 1", "c1", 5.4),),
    )
    return Demonstration(
        t, bodies, pos, quat, valid, labels=labels, meta={"start_time_ns": T0, "subject": 3}
    )


def assert_same(a: Demonstration, b: Demonstration) -> None:
    assert b.bodies == a.bodies
    assert b.labels == a.labels
    np.testing.assert_allclose(b.t, a.t, rtol=0, atol=1e-9)
    for name in a.body_names:
        np.testing.assert_array_equal(b.valid(name), a.valid(name))
        np.testing.assert_array_equal(b.pos(name), a.pos(name))
        np.testing.assert_array_equal(b.quat(name), a.quat(name))


def identity(n: int = 0) -> tuple[float, float, float, float]:
    return (0.0, 0.0, 0.0, 1.0)


# ------------------------------------------------------------ real data
@pytest.mark.parametrize("part", [1, 2, 3, 4])
def test_niekum_bags_load(shared_data: Path, part: int) -> None:
    path = shared_data / IKEA / f"part{part}.bag"
    demo = rosbag.read(path)
    assert demo.body_names == ["ar_0", "ar_13"]
    assert all(info.kind == "part" for info in demo.bodies)
    assert 20.0 < demo.n_frames / demo.duration < 25.0
    assert demo.meta["topics"] == {"/ar_world_model": "world"}
    assert set(demo.meta["unused_topics"]) == {
        "/l_arm_controller_loose/state",
        "/l_gripper_controller/state",
        "/r_gripper_controller/state",
    }
    assert demo.t[0] == 0.0
    assert 1.383e9 < demo.meta["start_time_unix"] < 1.384e9
    # Every part has frames where one of the AR tags is hidden.
    assert not all(demo.valid(n).all() for n in demo.body_names)


def test_niekum_visibility_matches_raw_messages(shared_data: Path) -> None:
    path = shared_data / IKEA / "part1.bag"
    demo = rosbag.read(path)
    visible: dict[int, list[bool]] = {0: [], 13: []}
    position: dict[int, list[tuple[float, float, float]]] = {0: [], 13: []}
    with AnyReader([path]) as reader:
        conns = [c for c in reader.connections if c.topic == "/ar_world_model"]
        for conn, _, data in reader.messages(conns):
            msg: Any = reader.deserialize(data, conn.msgtype)
            for obj in msg.objects:
                visible[obj.id].append(obj.currently_visible)
                p = obj.pose.pose.position
                position[obj.id].append((p.x, p.y, p.z))
    for oid in (0, 13):
        v = np.array(visible[oid])
        np.testing.assert_array_equal(demo.valid(f"ar_{oid}"), v)
        np.testing.assert_array_equal(demo.pos(f"ar_{oid}")[v], np.array(position[oid])[v])
    assert (~demo.valid("ar_13")).sum() > 0


def test_niekum_parts_read_as_one_recording(shared_data: Path) -> None:
    paths = [shared_data / IKEA / f"part{i}.bag" for i in range(1, 5)]
    whole = rosbag.read(paths, names={"ar_0": "table", "ar_13": "leg"})
    parts = [rosbag.read(p) for p in paths]
    assert whole.body_names == ["table", "leg"]
    assert whole.n_frames == sum(p.n_frames for p in parts)
    assert whole.meta["start_time_ns"] == parts[0].meta["start_time_ns"]
    last = parts[3].meta["start_time_ns"] - parts[0].meta["start_time_ns"]
    np.testing.assert_allclose(whole.t[-parts[3].n_frames :], parts[3].t + last / NS, atol=1e-9)


def test_a_folder_of_bag_parts_is_one_recording_for_every_command(
    shared_data: Path, tmp_path: Path
) -> None:
    from thirdhand import io
    from thirdhand.cli import main

    folder = shared_data / IKEA
    assert io.detect(folder) == "rosbag"
    whole = io.load(folder)
    paths = [folder / f"part{i}.bag" for i in range(1, 5)]
    np.testing.assert_array_equal(whole.t, rosbag.read(paths).t)
    assert main(["info", str(folder)]) == 0
    assert main(["convert", str(folder), str(tmp_path / "ikea.parquet")]) == 0
    back = io.load(tmp_path / "ikea.parquet")
    assert back.body_names == whole.body_names
    np.testing.assert_array_equal(back.t, whole.t)


def test_folder_of_bag_parts_read_in_name_order(tmp_path: Path, rng: np.random.Generator) -> None:
    from thirdhand.io import detect, load

    demo = synthetic_demo(rng)
    (tmp_path / "parts").mkdir()
    rosbag.write(demo, tmp_path / "parts" / "part1.bag")
    (tmp_path / "parts" / "readme.txt").write_text("one recording in parts\n")
    assert rosbag.sniff(tmp_path / "parts")
    assert detect(tmp_path / "parts") == "rosbag"
    assert_same(demo, load(tmp_path / "parts"))


# ------------------------------------------------------------ round trips
@pytest.mark.parametrize(
    ("name", "options"),
    [
        ("demo.bag", {}),
        ("demo_tf.bag", {"mode": "tf"}),
        ("demo_mcap", {}),
        ("demo_sqlite", {"storage": "sqlite3", "mode": "tf"}),
        ("demo_tf_mcap", {"mode": "tf", "storage": "mcap"}),
        ("demo.mcap", {}),
        ("demo.db3", {"mode": "tf"}),
    ],
)
def test_round_trip(tmp_path: Path, rng: np.random.Generator, name: str, options: dict) -> None:
    demo = synthetic_demo(rng)
    path = tmp_path / name
    rosbag.write(demo, path, **options)
    assert rosbag.sniff(path)
    back = rosbag.read(path)
    assert_same(demo, back)
    assert back.meta["subject"] == 3
    assert back.meta["start_time_ns"] == T0
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]


def test_written_bag_is_plain_ros(tmp_path: Path, rng: np.random.Generator) -> None:
    demo = synthetic_demo(rng)
    rosbag.write(demo, tmp_path / "demo.bag")
    with AnyReader([tmp_path / "demo.bag"]) as reader:
        topics = {c.topic: c.msgtype for c in reader.connections}
        conn = next(c for c in reader.connections if c.topic == "/thirdhand/seat/pose")
        stamps = [
            cast(Any, reader.deserialize(d, conn.msgtype)).header.stamp
            for _, _, d in reader.messages([conn])
        ]
    assert topics == {
        "/thirdhand/meta": "std_msgs/msg/String",
        "/thirdhand/seat/pose": "geometry_msgs/msg/PoseStamped",
        "/thirdhand/human/rh/thumb/pose": "geometry_msgs/msg/PoseStamped",
        "/thirdhand/marker_1/pose": "geometry_msgs/msg/PoseStamped",
    }
    assert len(stamps) == demo.valid("seat").sum()
    expected = T0 + np.round(demo.t[demo.valid("seat")] * NS).astype(np.int64)
    np.testing.assert_array_equal([s.sec * NS + s.nanosec for s in stamps], expected)


def test_write_refuses_to_overwrite(tmp_path: Path, rng: np.random.Generator) -> None:
    demo = synthetic_demo(rng)
    other = demo.select(["seat"])
    for name in ("a.bag", "folder"):
        path = tmp_path / name
        rosbag.write(demo, path)
        with pytest.raises(FormatError, match="already exists"):
            rosbag.write(other, path)
        assert rosbag.read(path).body_names == demo.body_names
        rosbag.write(other, path, overwrite=True)
        assert rosbag.read(path).body_names == ["seat"]
    # The replaced bags are kept as backups; no temporary file is left.
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "a.bag",
        "a.bag.bak",
        "folder",
        "folder.bak",
    ]
    assert rosbag.read(tmp_path / "folder.bak").body_names == demo.body_names


def test_failed_write_leaves_old_bag_and_no_debris(
    tmp_path: Path, rng: np.random.Generator, monkeypatch: pytest.MonkeyPatch
) -> None:
    demo = synthetic_demo(rng)
    for name in ("a.bag", "folder"):
        rosbag.write(demo, tmp_path / name)

    def broken(*args: Any, **kwargs: Any) -> Any:
        yield from ()
        raise RuntimeError("simulated failure half-way")

    monkeypatch.setattr(rosbag.writer, "_messages", broken)
    for name in ("a.bag", "folder"):
        with pytest.raises(RuntimeError, match="simulated failure"):
            rosbag.write(demo.select(["seat"]), tmp_path / name, overwrite=True)
        assert_same(demo, rosbag.read(tmp_path / name))
    # A failed write replaces nothing, backs nothing up and leaves no temporary file.
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.bag", "folder"]


def test_meta_must_be_json(tmp_path: Path, rng: np.random.Generator) -> None:
    demo = synthetic_demo(rng)
    bad = demo.replace(meta={"array": np.zeros(2)})
    with pytest.raises(FormatError, match="not JSON-able"):
        rosbag.write(bad, tmp_path / "x.bag")
    assert list(tmp_path.iterdir()) == []


def test_names_rename_own_bodies_and_labels(tmp_path: Path, rng: np.random.Generator) -> None:
    demo = synthetic_demo(rng)
    rosbag.write(demo, tmp_path / "d.bag", mode="tf")
    back = rosbag.read(tmp_path / "d.bag", names={"seat": "chair_seat"})
    assert back.body_names == ["chair_seat", "/human/rh/thumb", "marker 1"]
    assert back.labels.interactions[0].a == "chair_seat"
    assert back.labels.plan[0].parent == "chair_seat"
    np.testing.assert_array_equal(back.pos("chair_seat"), demo.pos("seat"))


def test_write_rejects_bad_options(tmp_path: Path, rng: np.random.Generator) -> None:
    demo = synthetic_demo(rng)
    with pytest.raises(FormatError, match=r"ROS 1 bag must end in \.bag"):
        rosbag.write(demo, tmp_path / "x", version=1)
    with pytest.raises(FormatError, match="ROS 1 bag"):
        rosbag.write(demo, tmp_path / "x.bag", version=2)
    with pytest.raises(FormatError, match="mode"):
        rosbag.write(demo, tmp_path / "x.bag", mode="joint")  # type: ignore[arg-type]
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------- tf trees
def test_tf_tree_with_static_transform_composes(tmp_path: Path, rng: np.random.Generator) -> None:
    m = Msgs(_store(1))
    table_p, table_q = np.array([1.0, 2.0, 0.5]), se3.random_quat(rng)
    new_table_p = np.array([1.5, 2.0, 0.5])
    tip_p, tip_q = np.array([0.0, 0.0, 0.3]), se3.random_quat(rng)
    leg_p, leg_q = rng.uniform(-1, 1, (6, 3)), se3.random_quat(rng, 6)
    leg_t = T0 + np.arange(6) * NS // 10
    entries: list[tuple[str, str, int, Any]] = [
        (
            "/tf_static",
            "tf2_msgs/msg/TFMessage",
            T0 - NS,
            m.tf(
                m.transform(T0 - NS, "world", "table", table_p, table_q),
                m.transform(T0 - NS, "leg", "tip", tip_p, tip_q),
            ),
        ),
        # The table is moved and its static transform republished before frame 4.
        (
            "/tf_static",
            "tf2_msgs/msg/TFMessage",
            int(leg_t[4]) - 1,
            m.tf(
                m.transform(int(leg_t[4]) - 1, "world", "table", new_table_p, table_q),
                m.transform(T0 - NS, "leg", "tip", tip_p, tip_q),
            ),
        ),
    ]
    for k in range(6):
        entries.append(
            (
                "/tf",
                "tf2_msgs/msg/TFMessage",
                int(leg_t[k]),
                m.tf(
                    m.transform(int(leg_t[k]), "/table", "leg", leg_p[k], leg_q[k]),
                ),
            )
        )
    path = write_raw(tmp_path / "tf.bag", m.store, 1, entries)
    demo = rosbag.read(path)
    assert demo.body_names == ["leg", "table", "tip"]
    assert demo.meta["tf_root_frame"] == "world"
    np.testing.assert_allclose(demo.t, np.arange(6) * 0.1, atol=1e-9)
    tp = np.where(np.arange(6)[:, None] >= 4, new_table_p, table_p)
    want_p, want_q = se3.pose_compose(tp, table_q, leg_p, leg_q)
    np.testing.assert_allclose(demo.pos("leg"), want_p, atol=1e-12)
    np.testing.assert_allclose(demo.quat("leg"), want_q, atol=1e-12)
    tip_wp, tip_wq = se3.pose_compose(want_p, want_q, tip_p, tip_q)
    np.testing.assert_allclose(demo.pos("tip"), tip_wp, atol=1e-12)
    np.testing.assert_allclose(demo.quat("tip"), tip_wq, atol=1e-12)
    np.testing.assert_allclose(demo.pos("table"), tp, atol=0)
    assert demo.valid("tip").all() and demo.valid("table").all()

    # In the table's frame the leg is exactly its own transform.
    in_table = rosbag.read(path, root_frame="table")
    assert in_table.body_names == ["leg", "tip"]
    np.testing.assert_array_equal(in_table.pos("leg"), leg_p)
    np.testing.assert_array_equal(in_table.quat("leg"), leg_q)


def test_tf_parent_is_interpolated_between_its_stamps(tmp_path: Path) -> None:
    m = Msgs(_store(2))
    q0 = (0.0, 0.0, np.sin(0.3), np.cos(0.3))
    entries: list[tuple[str, str, int, Any]] = []
    for k in range(4):  # a cart moving at 1 m/s along x, published at 10 Hz
        s = T0 + k * NS // 10
        entries.append(
            (
                "/tf",
                "tf2_msgs/msg/TFMessage",
                s,
                m.tf(
                    m.transform(s, "map", "cart", (0.1 * k, 0.0, 0.0), q0),
                ),
            )
        )
    for k in range(3):  # a box on the cart, published in between
        s = T0 + k * NS // 10 + NS // 40
        entries.append(
            (
                "/tf",
                "tf2_msgs/msg/TFMessage",
                s,
                m.tf(
                    m.transform(s, "cart", "box", (0.0, 0.2, 0.0), identity()),
                ),
            )
        )
    demo = rosbag.read(write_raw(tmp_path / "bag", m.store, 2, entries))
    assert demo.n_frames == 7
    box = demo.valid("box")
    assert box.sum() == 3 and not np.any(box & demo.valid("cart"))
    cart_x = demo.t[box]
    want, _ = se3.pose_compose(
        np.c_[cart_x, 0 * cart_x, 0 * cart_x], q0, (0.0, 0.2, 0.0), identity()
    )
    np.testing.assert_allclose(demo.pos("box")[box], want, atol=1e-12)
    np.testing.assert_allclose(demo.quat("box")[box], np.tile(q0, (3, 1)), atol=1e-12)


def test_pose_topic_in_a_tf_frame_is_moved_to_the_root(
    tmp_path: Path, rng: np.random.Generator
) -> None:
    m = Msgs(_store(1))
    table_p, table_q = np.array([1.0, -2.0, 0.7]), se3.random_quat(rng)
    cup_p, cup_q = rng.uniform(-1, 1, (3, 3)), se3.random_quat(rng, 3)
    entries: list[tuple[str, str, int, Any]] = [
        (
            "/tf_static",
            "tf2_msgs/msg/TFMessage",
            T0,
            m.tf(m.transform(T0, "world", "table", table_p, table_q)),
        )
    ]
    for k in range(3):
        s = T0 + k * NS // 10
        msg = m.pose_stamped(s, cup_p[k], cup_q[k])
        msg.header.frame_id = "table"
        entries.append(("/cup", "geometry_msgs/msg/PoseStamped", s, msg))
    demo = rosbag.read(write_raw(tmp_path / "cup.bag", m.store, 1, entries))
    assert demo.body_names == ["cup", "table"]
    want_p, want_q = se3.pose_compose(table_p, table_q, cup_p, cup_q)
    np.testing.assert_allclose(demo.pos("cup"), want_p, atol=1e-12)
    np.testing.assert_allclose(demo.quat("cup"), want_q, atol=1e-12)
    in_table = rosbag.read(tmp_path / "cup.bag", root_frame="table")
    np.testing.assert_array_equal(in_table.pos("cup"), cup_p)


# ------------------------------------------------ topics and time axis
def test_pose_topics_share_frames_within_tolerance(tmp_path: Path) -> None:
    m = Msgs(_store(1))
    entries = []
    for k in range(5):
        s = T0 + k * NS // 20
        entries.append(
            (
                "/a/pose",
                "geometry_msgs/msg/PoseStamped",
                s,
                m.pose_stamped(s, (k, 0, 0), identity()),
            )
        )
        s_b = s + 200_000  # 0.2 ms later: same frame
        entries.append(
            ("/b", "geometry_msgs/msg/PoseStamped", s_b, m.pose_stamped(s_b, (0, k, 0), identity()))
        )
        s_c = s + 20_000_000  # 20 ms later: frames of its own
        entries.append(
            ("/c", "geometry_msgs/msg/PoseStamped", s_c, m.pose_stamped(0, (0, 0, k), identity()))
        )
    path = write_raw(tmp_path / "p.bag", m.store, 1, entries)
    demo = rosbag.read(path, names={"/b": "bee"})
    assert demo.body_names == ["a/pose", "bee", "c"]
    assert demo.n_frames == 10
    np.testing.assert_array_equal(demo.valid("a/pose"), demo.valid("bee"))
    np.testing.assert_array_equal(demo.valid("c"), ~demo.valid("bee"))
    np.testing.assert_allclose(demo.t[demo.valid("c")], np.arange(5) * 0.05 + 0.02, atol=1e-9)
    np.testing.assert_array_equal(demo.pos("c")[demo.valid("c"), 2], np.arange(5))
    exact = rosbag.read(path, merge_tolerance=0.0)
    assert exact.n_frames == 15


def test_fast_streams_pair_up_without_doubling(tmp_path: Path) -> None:
    # 1 kHz streams with the default 1 ms tolerance: each frame takes one stamp per body.
    m = Msgs(_store(2))
    entries = []
    for k in range(50):
        for topic, dt in (("/a", 0), ("/b", 300_000)):
            s = T0 + k * NS // 1000 + dt
            entries.append(
                (
                    topic,
                    "geometry_msgs/msg/PoseStamped",
                    s,
                    m.pose_stamped(s, (k, 0, 0), identity()),
                )
            )
    demo = rosbag.read(write_raw(tmp_path / "fast", m.store, 2, entries))
    assert demo.n_frames == 50
    assert demo.valid("a").all() and demo.valid("b").all()
    np.testing.assert_allclose(demo.t, np.arange(50) / 1000, atol=1e-9)
    np.testing.assert_array_equal(demo.pos("b")[:, 0], np.arange(50))


def test_out_of_order_stamps_are_sorted(tmp_path: Path) -> None:
    m = Msgs(_store(1))
    order = [3, 0, 4, 1, 2]
    entries = [
        (
            "/obj",
            "geometry_msgs/msg/PoseStamped",
            T0 + i,
            m.pose_stamped(T0 + k * NS // 10, (k, 0, 0), identity()),
        )
        for i, k in enumerate(order)
    ]
    demo = rosbag.read(write_raw(tmp_path / "o.bag", m.store, 1, entries))
    np.testing.assert_allclose(demo.t, np.arange(5) * 0.1, atol=1e-9)
    np.testing.assert_array_equal(demo.pos("obj")[:, 0], np.arange(5))


def test_custom_world_model_detected_by_structure(tmp_path: Path) -> None:
    types = {
        "lab_msgs/msg/Thing": "uint16 id\ngeometry_msgs/Pose pose\nbool is_visible",
        "lab_msgs/msg/Scene": "std_msgs/Header header\nlab_msgs/Thing[] things",
    }
    store = _store(1, types)
    m = Msgs(store)
    thing, scene = store.types["lab_msgs/msg/Thing"], store.types["lab_msgs/msg/Scene"]
    entries = []
    for k in range(4):
        s = T0 + k * NS // 10
        things = [
            thing(id=7, pose=m.pose((k, 0, 0), identity()), is_visible=k != 2),
            thing(id=2, pose=m.pose((0, k, 0), identity()), is_visible=True),
        ]
        entries.append(
            ("/scene_objects", "lab_msgs/msg/Scene", s, scene(header=m.header(s), things=things))
        )
    entries.append(
        ("/status", "std_msgs/msg/String", T0, store.types["std_msgs/msg/String"](data="x"))
    )
    demo = rosbag.read(write_raw(tmp_path / "w.bag", store, 1, entries), names={"ar_7": "cup"})
    assert demo.body_names == ["ar_2", "cup"]
    np.testing.assert_array_equal(demo.valid("cup"), [True, True, False, True])
    assert demo.valid("ar_2").all()
    np.testing.assert_array_equal(demo.pos("cup")[[0, 1, 3], 0], [0, 1, 3])
    assert demo.meta["unused_topics"] == {"/status": "std_msgs/msg/String"}


def test_topics_option_selects_and_checks(tmp_path: Path, rng: np.random.Generator) -> None:
    demo = synthetic_demo(rng)
    path = tmp_path / "demo.bag"
    rosbag.write(demo, path)
    seat = rosbag.read(path, topics=["/thirdhand/seat/pose"])
    assert seat.body_names == ["seat"]
    assert seat.labels == Labels()
    with pytest.raises(FormatError, match=r"/nope.*not in the bag"):
        rosbag.read(path, topics=["/nope"])
    with pytest.raises(FormatError, match="carries no pose"):
        rosbag.read(path, topics=["/thirdhand/meta"])


# ------------------------------------------------------------ detection
def test_load_detects_bags(tmp_path: Path, rng: np.random.Generator) -> None:
    missing = [m for m in FORMATS.values() if importlib.util.find_spec(f"thirdhand.io.{m}") is None]
    if missing:
        pytest.skip(f"format modules not written yet: {', '.join(missing)}")
    from thirdhand.io import detect, load

    demo = synthetic_demo(rng)
    for name in ("d.bag", "d2", "d.mcap", "d.db3"):
        rosbag.write(demo, tmp_path / name)
        assert detect(tmp_path / name) == "rosbag"
        assert_same(demo, load(tmp_path / name))


def test_sniff(tmp_path: Path) -> None:
    (tmp_path / "x.bag").write_bytes(b"")
    (tmp_path / "x.csv").write_text("a,b\n")
    (tmp_path / "folder").mkdir()
    (tmp_path / "folder" / "metadata.yaml").write_text("x: 1\n")
    assert rosbag.sniff(tmp_path / "x.bag")
    assert not rosbag.sniff(tmp_path / "x.csv")
    assert not rosbag.sniff(tmp_path / "folder")
    (tmp_path / "folder" / "folder_0.mcap").write_bytes(b"")
    assert rosbag.sniff(tmp_path / "folder")


# ------------------------------------------------------------ malformed
def test_empty_file(tmp_path: Path) -> None:
    (tmp_path / "e.bag").write_bytes(b"")
    with pytest.raises(FormatError, match=r"e\.bag: empty file"):
        rosbag.read(tmp_path / "e.bag")


def test_truncated_and_corrupt_bags(tmp_path: Path, rng: np.random.Generator) -> None:
    rosbag.write(synthetic_demo(rng), tmp_path / "good.bag")
    data = (tmp_path / "good.bag").read_bytes()
    (tmp_path / "cut.bag").write_bytes(data[: len(data) // 2])
    (tmp_path / "junk.bag").write_bytes(b"not a bag at all\n" * 20)
    for name in ("cut.bag", "junk.bag"):
        with pytest.raises(FormatError, match=rf"{name}: damaged or unreadable bag"):
            rosbag.read(tmp_path / name)


def test_bag_without_pose_topic(tmp_path: Path) -> None:
    store = _store(2)
    msg = store.types["std_msgs/msg/String"](data="hello")
    path = write_raw(tmp_path / "s", store, 2, [("/chatter", "std_msgs/msg/String", T0, msg)])
    with pytest.raises(FormatError, match=r"no pose topic.*/chatter \(std_msgs/msg/String\)"):
        rosbag.read(path)


def test_zero_norm_quaternion_names_topic_and_stamp(tmp_path: Path) -> None:
    m = Msgs(_store(1))
    entries = [
        (
            "/obj",
            "geometry_msgs/msg/PoseStamped",
            T0 + k,
            m.pose_stamped(T0 + k * NS // 10, (0, 0, 0), q),
        )
        for k, q in enumerate([identity(), identity(), (0.0, 0.0, 0.0, 0.0)])
    ]
    path = write_raw(tmp_path / "z.bag", m.store, 1, entries)
    with pytest.raises(
        FormatError,
        match=r"\(topic /obj message 2\).*zero-norm quaternion at stamp 1700000000\.200000000 s",
    ):
        rosbag.read(path)


def test_conflicting_duplicate_stamps(tmp_path: Path) -> None:
    m = Msgs(_store(1))
    entries = [
        ("/obj", "geometry_msgs/msg/PoseStamped", T0 + k, m.pose_stamped(T0, (k, 0, 0), identity()))
        for k in range(2)
    ]
    path = write_raw(tmp_path / "d.bag", m.store, 1, entries)
    with pytest.raises(FormatError, match=r"topic /obj messages 0 and 1.*same stamp"):
        rosbag.read(path)
    # An exact repeat is dropped.
    entries[1] = (
        "/obj",
        "geometry_msgs/msg/PoseStamped",
        T0 + 1,
        m.pose_stamped(T0, (0, 0, 0), identity()),
    )
    assert rosbag.read(write_raw(tmp_path / "r.bag", m.store, 1, entries)).n_frames == 1


def test_tf_errors(tmp_path: Path) -> None:
    m = Msgs(_store(1))
    entries = [
        (
            "/tf",
            "tf2_msgs/msg/TFMessage",
            T0,
            m.tf(m.transform(T0, "world", "a", (0, 0, 0), identity())),
        ),
        (
            "/tf",
            "tf2_msgs/msg/TFMessage",
            T0 + 1,
            m.tf(m.transform(T0 + 1, "other", "a", (0, 0, 0), identity())),
        ),
    ]
    with pytest.raises(FormatError, match=r"topic /tf message 1.*two parents"):
        rosbag.read(write_raw(tmp_path / "p.bag", m.store, 1, entries))
    with pytest.raises(FormatError, match="root_frame 'nowhere' is not a tf frame"):
        rosbag.read(write_raw(tmp_path / "q.bag", m.store, 1, entries[:1]), root_frame="nowhere")


def test_missing_path(tmp_path: Path) -> None:
    with pytest.raises(FormatError, match="no such file"):
        rosbag.read(tmp_path / "absent.bag")
