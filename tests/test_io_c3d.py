"""C3D reader and writer: Kabsch recovery, body frames from data, round trips, bad files."""

from __future__ import annotations

import site
from collections.abc import Sequence
from pathlib import Path

import ezc3d
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

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
from thirdhand.io import c3d, load


# ------------------------------------------------------------------ helpers
def random_cluster(rng: np.random.Generator, m: int) -> np.ndarray:
    """Irregular marker cluster of ``m`` points within ~8 cm, shape (m, 3), metres."""
    return rng.uniform(-0.08, 0.08, size=(m, 3))


def random_poses(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Random positions (n, 3) metres and uniform orientations (n, 4)."""
    return rng.uniform(-1.0, 1.0, size=(n, 3)), se3.random_quat(rng, n)


def place(ref: np.ndarray, pos: np.ndarray, quat: np.ndarray) -> np.ndarray:
    """World positions of a cluster at each pose, shape (n, m, 3)."""
    return pos[:, None] + se3.quat_rotate(quat[:, None], ref[None])


def write_raw(
    path: Path,
    labels: Sequence[str],
    xyz_mm: np.ndarray,
    *,
    rate: float = 100.0,
    units: str | None = "mm",
    residuals: np.ndarray | None = None,
    first_frame: int = 0,
) -> None:
    """Write a C3D file with plain ezc3d (no THIRDHAND group); ``xyz_mm`` is (T, M, 3)."""
    n, m, _ = xyz_mm.shape
    c = ezc3d.c3d()
    pts = np.ones((4, m, n))
    pts[:3] = xyz_mm.transpose(2, 1, 0)
    c["parameters"]["POINT"]["RATE"]["value"] = np.array([rate])
    c["parameters"]["POINT"]["LABELS"]["value"] = list(labels)
    c["header"]["points"]["first_frame"] = first_frame
    c["data"]["points"] = pts
    res = np.zeros((1, m, n)) if residuals is None else residuals.T[None]
    c["data"]["meta_points"] = {"residuals": res, "camera_masks": np.zeros((7, m, n), bool)}
    if units is not None:
        c.add_parameter("POINT", "UNITS", [units])
    c.write(str(path))


def sample_demo(rng: np.random.Generator, n: int = 240) -> Demonstration:
    """Three bodies (one position-only), smooth random motion, gaps, labels and meta."""
    t = 0.25 + np.arange(n) / 120.0
    bodies = [
        BodyInfo("seat"),
        BodyInfo(
            "/human/rh/thumb", kind="finger", hand="right", hand_body="p1/right", oriented=False
        ),
        BodyInfo("leg 1", kind="part", person="p1"),
    ]
    pos, quat, valid = {}, {}, {}
    for b in bodies:
        pos[b.name] = rng.uniform(-1, 1, 3) + np.cumsum(rng.normal(0, 0.004, (n, 3)), axis=0)
        quat[b.name] = Rotation.from_rotvec(np.cumsum(rng.normal(0, 0.05, (n, 3)), 0)).as_quat()
        valid[b.name] = rng.random(n) > 0.1
    # Label times inside the recording, whatever its length (the core type checks it).
    start, end = float(t[n // 4]), float(t[n // 2])
    labels = Labels(
        interactions=(InteractionInterval("seat", "leg 1", start, end),),
        constraints=(ConstraintEvent(end, "seat", "leg 1", "revolute", symbol="c2"),),
        plan=(PlanStep("seat", "leg 1", "c2", end),),
    )
    meta = {"scene": "chair", "note": "spaces  and \\ backslashes ", "n": 3}
    return Demonstration(t, bodies, pos, quat, valid, labels=labels, meta=meta)


def assert_same_motion(a: Demonstration, b: Demonstration, *, pos_tol: float, ang_tol: float):
    assert a.body_names == b.body_names
    assert a.bodies == b.bodies
    np.testing.assert_allclose(b.t, a.t, rtol=0, atol=1e-12)
    for name in a.body_names:
        ta, tb = a.track(name), b.track(name)
        np.testing.assert_array_equal(ta.valid, tb.valid)
        v = ta.valid
        assert np.max(np.abs(ta.pos[v] - tb.pos[v])) < pos_tol
        assert np.max(se3.quat_angle(ta.quat[v], tb.quat[v])) < ang_tol


# ---------------------------------------------------------------- Kabsch fit
def test_fit_cluster_recovers_poses_exactly_with_missing_markers(rng):
    ref = random_cluster(rng, 5)
    pos, quat = random_poses(rng, 60)
    xyz = place(ref, pos, quat)
    # Hide 0-2 markers per frame, and 3+ in a few frames (which must come out invalid).
    hide = rng.random((60, 5)) < 0.25
    hide[[7, 19, 40]] = [True, True, True, False, False]
    hide[[8, 33]] = True
    xyz[hide] = np.nan
    p, q, rms = c3d.fit_cluster(ref, xyz)
    ok = (~hide).sum(axis=1) >= 3
    np.testing.assert_array_equal(np.all(np.isfinite(p), axis=1), ok)
    assert np.max(np.abs(p[ok] - pos[ok])) < 1e-12
    assert np.max(se3.quat_angle(q[ok], quat[ok])) < 1e-7
    assert np.max(rms[ok]) < 1e-12
    # Sign-continuous output.
    qo = q[ok]
    assert np.all(np.sum(qo[1:] * qo[:-1], axis=1) >= 0)


def test_canonical_cluster_is_centred_principal_right_handed_and_pose_invariant(rng):
    ref = random_cluster(rng, 6)
    can = c3d.canonical_cluster(ref)
    np.testing.assert_allclose(can.mean(axis=0), 0.0, atol=1e-15)
    cov = can.T @ can
    np.testing.assert_allclose(cov - np.diag(np.diag(cov)), 0.0, atol=1e-14)
    assert cov[0, 0] > cov[1, 1] > cov[2, 2]
    # Same distances: a rigid transform of the input.
    d = np.linalg.norm(ref[:, None] - ref[None], axis=2)
    np.testing.assert_allclose(np.linalg.norm(can[:, None] - can[None], axis=2), d, atol=1e-14)
    # Right-handed: no reflection relative to the input.
    _, q, _ = se3.kabsch(can, ref[None])
    assert np.allclose(place(can, np.zeros((1, 3)), q)[0] - ref, -ref.mean(0), atol=1e-12)
    # Deterministic whatever pose the cluster was seen in.
    pos, quat = random_poses(rng, 4)
    for k in range(4):
        moved = se3.quat_rotate(quat[k], ref) + pos[k]
        np.testing.assert_allclose(c3d.canonical_cluster(moved), can, atol=1e-12)


def test_reference_cluster_from_data_gives_exact_relative_motion(rng):
    ref = random_cluster(rng, 4)
    pos, quat = random_poses(rng, 80)
    xyz = place(ref, pos, quat)
    xyz[:5, 2] = np.nan  # first frames incomplete: the body frame comes from frame 5 on
    xyz[rng.random((80, 4)) < 0.1] = np.nan
    est = c3d.reference_cluster(xyz)
    np.testing.assert_allclose(est, c3d.canonical_cluster(ref), atol=1e-12)
    p, q, _ = c3d.fit_cluster(est, xyz)
    ok = np.all(np.isfinite(p), axis=1)
    # Fitted pose = true pose composed with one constant body-frame change.
    dp, dq = se3.relative_pose(pos[ok], quat[ok], p[ok], q[ok])
    assert np.max(np.abs(dp - dp[0])) < 1e-12
    assert np.max(se3.quat_angle(dq, dq[0])) < 1e-7


def test_reference_cluster_without_any_complete_frame(rng):
    ref = random_cluster(rng, 5)
    pos, quat = random_poses(rng, 40)
    xyz = place(ref, pos, quat)
    xyz[0::2, 0] = np.nan  # markers 0 and 4 are never seen together
    xyz[1::2, 4] = np.nan
    est = c3d.reference_cluster(xyz)
    np.testing.assert_allclose(est, c3d.canonical_cluster(ref), atol=1e-12)


def test_reference_cluster_needs_three_seen_markers():
    xyz = np.full((10, 4, 3), np.nan)
    xyz[:, :2] = 1.0
    assert np.all(np.isnan(c3d.reference_cluster(xyz)))


# ------------------------------------------------------------------ prefixes
def test_prefix_grouping():
    labels = [
        "Seat:M1", "Seat:M2", "Back_M1", "Seat:M3", "Back_M2", "Back_M3",
        "chair/leg1/m1", "chair/leg1/m2", "chair/leg1/m3", "Loose", "Pair_a", "Pair_b",
        "Sub:Leg_A", "Sub:Leg_B", "Sub:Leg_C",
    ]  # fmt: skip
    groups = c3d.group_by_prefix(labels)
    assert groups == {
        "Seat": ["Seat:M1", "Seat:M2", "Seat:M3"],
        "Back": ["Back_M1", "Back_M2", "Back_M3"],
        "chair/leg1": ["chair/leg1/m1", "chair/leg1/m2", "chair/leg1/m3"],
        "Sub": ["Sub:Leg_A", "Sub:Leg_B", "Sub:Leg_C"],
    }
    assert c3d.label_prefix("Loose") is None
    assert c3d.label_prefix("/human/rh/thumb:M2") == "/human/rh/thumb"


# ---------------------------------------------------------------- round trip
def test_round_trip_within_float32_tolerance(tmp_path, rng):
    demo = sample_demo(rng)
    path = tmp_path / "demo.c3d"
    c3d.write(demo, path)
    back = c3d.read(path)
    # float32 millimetres: ~1e-7 relative, i.e. ~1e-7 m at 1 m and ~1e-6 rad on 5 cm clusters.
    assert_same_motion(demo, back, pos_tol=1e-6, ang_tol=1e-5)
    assert back.labels == demo.labels
    assert back.meta == demo.meta
    assert not list(tmp_path.glob("*.tmp*"))


def test_round_trip_through_registry_and_custom_clusters(tmp_path, rng):
    demo = sample_demo(rng, n=50)
    cluster = random_cluster(rng, 6)
    path = tmp_path / "custom.c3d"
    c3d.write(demo, path, clusters={"seat": cluster})
    assert c3d.sniff(path)
    back = load(path)
    assert_same_motion(demo, back, pos_tol=1e-6, ang_tol=1e-5)
    raw = ezc3d.c3d(str(path))
    labels = raw["parameters"]["POINT"]["LABELS"]["value"]
    assert labels[:6] == [f"seat:M{k}" for k in range(1, 7)]
    assert labels[6] == "/human/rh/thumb"
    assert raw["parameters"]["POINT"]["UNITS"]["value"] == ["mm"]
    # Missing frames: NaN with residual -1.
    miss = ~demo.track("seat").valid
    res = raw["data"]["meta_points"]["residuals"][0, 0]
    assert np.all(res[miss] == -1) and np.all(res[~miss] == 0)
    assert np.all(np.isnan(raw["data"]["points"][0, 0, miss]))


def test_round_trip_of_a_large_description(tmp_path, rng):
    demo = sample_demo(rng, n=20)
    big = " ".join(f"word{i}" for i in range(8000))  # ~70 kB: several DOC parameters
    demo = demo.replace(meta={"text": big})
    path = tmp_path / "big.c3d"
    c3d.write(demo, path)
    assert "DOC3" in ezc3d.c3d(str(path))["parameters"][c3d.GROUP]
    assert c3d.read(path).meta == {"text": big}


def test_markers_from_demonstration(rng):
    demo = sample_demo(rng, n=30)
    cluster = random_cluster(rng, 3)
    labels, xyz = c3d.markers_from_demonstration(demo, {"leg 1": cluster})
    assert labels == [
        "seat:M1", "seat:M2", "seat:M3", "seat:M4", "/human/rh/thumb",
        "leg 1:M1", "leg 1:M2", "leg 1:M3",
    ]  # fmt: skip
    assert xyz.shape == (30, 8, 3)
    seat, thumb, leg = (demo.track(n) for n in demo.body_names)
    want = place(c3d.default_cluster("seat"), seat.pos, seat.quat)
    np.testing.assert_allclose(xyz[:, :4], want, equal_nan=True)
    np.testing.assert_allclose(xyz[:, 4], thumb.pos, equal_nan=True)
    np.testing.assert_allclose(xyz[:, 5:], place(cluster, leg.pos, leg.quat), equal_nan=True)
    assert np.all(np.isnan(xyz[~seat.valid, :4]))


def test_round_trip_of_awkward_names(tmp_path):
    n = 6
    bodies = [BodyInfo("Sitz_ä"), BodyInfo(" thumb ", kind="finger", oriented=False)]
    demo = Demonstration(
        np.arange(n) / 10.0,
        bodies,
        {b.name: np.full((n, 3), 0.1) for b in bodies},
        {b.name: np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)) for b in bodies},
    )
    path = tmp_path / "names.c3d"
    c3d.write(demo, path)
    assert_same_motion(demo, c3d.read(path), pos_tol=1e-6, ang_tol=1e-5)
    raw = c3d.read(path, stored_clusters=False, markers_as_bodies=True)
    assert raw.body_names == ["Sitz_ä", "thumb"]


def test_default_cluster_is_deterministic_and_not_coplanar():
    a, b = c3d.default_cluster("seat"), c3d.default_cluster("seat")
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c3d.default_cluster("leg1"))
    dist = np.linalg.norm(a, axis=1)
    assert np.all((dist > 0.025) & (dist < 0.06))
    vol = abs(np.linalg.det(a[1:] - a[0])) / 6
    assert vol > 1e-6  # tetrahedron volume, m³


def test_write_rejects_bad_input(tmp_path, rng):
    demo = sample_demo(rng, n=20)
    path = tmp_path / "bad.c3d"
    with pytest.raises(FormatError, match="collinear"):
        c3d.write(demo, path, clusters={"seat": [[0, 0, 0], [0.1, 0, 0], [0.2, 0, 0]]})
    with pytest.raises(FormatError, match=r"m >= 3"):
        c3d.write(demo, path, clusters={"seat": [[0, 0, 0], [0.1, 0, 0]]})
    with pytest.raises(FormatError, match="position-only"):
        c3d.write(demo, path, clusters={"/human/rh/thumb": random_cluster(rng, 4)})
    t = demo.t.copy()
    t[5:] += 0.002
    with pytest.raises(FormatError, match=r"frame 5.*regular"):
        c3d.write(demo.replace(t=t), path)
    with pytest.raises(FormatError, match="meta cannot be stored"):
        c3d.write(demo.replace(meta={"x": object()}), path)
    assert not path.exists()
    c3d.write(demo.replace(meta={"x": np.float32(1.5), "a": np.arange(3)}), path)
    assert c3d.read(path).meta == {"x": 1.5, "a": [0, 1, 2]}


# ----------------------------------------------------- files from elsewhere
def rigid_pair_scene(rng: np.random.Generator, n: int = 120):
    """Body A turning about z at a known rate, body B rigidly attached to it."""
    angle = np.linspace(0.0, 2.5, n)
    q_a = Rotation.from_rotvec(angle[:, None] * np.array([0.0, 0.0, 1.0])).as_quat()
    p_a = np.column_stack([np.linspace(0, 0.5, n), 0.2 * np.sin(angle), 1.0 + 0 * angle])
    p_ab, q_ab = np.array([0.3, -0.1, 0.05]), Rotation.from_euler("xyz", [0.3, -0.2, 1.1]).as_quat()
    p_b, q_b = se3.pose_compose(p_a, q_a, p_ab, q_ab)
    ref_a, ref_b = random_cluster(rng, 4), random_cluster(rng, 5)
    xyz = np.concatenate([place(ref_a, p_a, q_a), place(ref_b, p_b, q_b)], axis=1)
    return angle, xyz, (p_ab, q_ab)


def test_foreign_file_gives_right_relative_motion(tmp_path, rng):
    angle, xyz, _ = rigid_pair_scene(rng)
    n = xyz.shape[0]
    labels = [f"Tray:M{k}" for k in range(4)] + [f"Lid_{k}" for k in range(5)] + ["Loose"]
    xyz = np.concatenate([xyz, rng.uniform(-1, 1, (n, 1, 3))], axis=1) * 1000.0
    residuals = np.ones((n, 10))
    residuals[rng.random((n, 10)) < 0.1] = -1.0  # missing by residual
    xyz[residuals < 0] = 0.0  # ... and written as zeros, as many systems do
    xyz[3, 6] = np.nan  # missing by NaN
    residuals[3, 6] = 0.5
    path = tmp_path / "foreign.c3d"
    write_raw(path, labels, xyz, rate=200.0, residuals=residuals, first_frame=40)
    demo = c3d.read(path)
    assert demo.body_names == ["Tray", "Lid"]
    np.testing.assert_allclose(demo.t, (40 + np.arange(n)) / 200.0)
    assert demo.meta["units"] == "mm" and demo.meta["markers"]["Lid"] == labels[4:9]
    # Pose of the lid in the tray: constant.
    p, q, v = demo.relative_pose("Tray", "Lid")
    assert v.sum() > 0.8 * n
    assert np.max(np.abs(p[v] - p[v][0])) < 1e-6
    assert np.max(se3.quat_angle(q[v], q[v][0])) < 1e-5
    # Rotation of the tray from its first valid frame: the known angle about z.
    tray = demo.track("Tray")
    first = int(np.argmax(tray.valid))
    turned = se3.quat_angle(tray.quat[first], tray.quat[tray.valid])
    np.testing.assert_allclose(turned, np.abs(angle[tray.valid] - angle[first]), atol=1e-5)
    # The lone marker is dropped by default, kept as a position-only body on demand.
    both = c3d.read(path, markers_as_bodies=True)
    assert both.body_names == ["Tray", "Lid", "Loose"]
    assert not both.info("Loose").oriented
    np.testing.assert_allclose(
        both.track("Loose").pos[2], xyz[2, 9] / 1000.0, rtol=1e-6, equal_nan=True
    )


def test_non_rigid_prefix_group_is_not_a_body(tmp_path, rng):
    _, xyz, _ = rigid_pair_scene(rng, n=50)
    skin = xyz[:, :3] + np.cumsum(rng.normal(0, 0.01, (50, 3, 3)), axis=0)  # drifting apart
    labels = [f"Tray:M{k}" for k in range(4)] + [f"Lid:M{k}" for k in range(5)]
    labels += ["Arm:elbow", "Arm:wrist", "Arm:hand"]
    path = tmp_path / "skin.c3d"
    write_raw(path, labels, np.concatenate([xyz, skin], axis=1) * 1000.0)
    demo = c3d.read(path)
    assert demo.body_names == ["Tray", "Lid"]
    assert demo.meta["c3d_nonrigid_groups"]["Arm"] > 0.005
    assert c3d.read(path, max_rms=1.0).body_names == ["Tray", "Lid", "Arm"]
    loose = c3d.read(path, markers_as_bodies=True)
    assert loose.body_names == ["Tray", "Lid", "Arm:elbow", "Arm:wrist", "Arm:hand"]
    named = c3d.read(path, bodies={"Arm": labels[-3:]})  # the user's word is kept
    assert named.body_names == ["Arm"]


def test_foreign_file_with_noise_stated_tolerance(tmp_path, rng):
    angle, xyz, _ = rigid_pair_scene(rng, n=400)
    xyz = xyz + rng.normal(0.0, 0.3e-3, xyz.shape)  # 0.3 mm marker noise
    xyz[rng.random(xyz.shape[:2]) < 0.05] = np.nan
    labels = [f"Tray:M{k}" for k in range(4)] + [f"Lid:M{k}" for k in range(5)]
    path = tmp_path / "noisy.c3d"
    write_raw(path, labels, xyz * 1000.0)
    demo = c3d.read(path)
    assert 0.1e-3 < demo.meta["c3d_fit_rms_m"]["Tray"] < 0.5e-3
    p, q, v = demo.relative_pose("Tray", "Lid")
    p_med = np.median(p[v], axis=0)
    # B sits ~0.3 m from A's markers: A's orientation noise (~0.3 mm / 4 cm) is amplified.
    dev = np.linalg.norm(p[v] - p_med, axis=1)
    assert np.sqrt(np.mean(dev**2)) < 3e-3 and np.max(dev) < 1e-2
    assert np.max(se3.quat_angle(q[v], q[v][0])) < np.radians(4.0)
    tray = demo.track("Tray")
    first = int(np.argmax(tray.valid))
    turned = se3.quat_angle(tray.quat[first], tray.quat[tray.valid])
    err = turned - np.abs(angle[tray.valid] - angle[first])
    assert np.max(np.abs(err)) < np.radians(2.0)


def test_body_option_on_own_file_keeps_stored_geometry(tmp_path, rng):
    demo = sample_demo(rng, n=40)
    path = tmp_path / "own.c3d"
    c3d.write(demo, path)
    seat = [f"seat:M{k}" for k in range(1, 5)]
    back = c3d.read(path, bodies={"seat": seat}, markers_as_bodies=True)
    assert back.body_names[0] == "seat" and len(back) == 1 + 1 + 4
    assert back.info("/human/rh/thumb").hand == "right"
    assert_same_motion(demo.select(["seat"]), back.select(["seat"]), pos_tol=1e-6, ang_tol=1e-5)
    # Without the stored geometry the seat frame is the data's: same motion up to a fixed offset.
    raw = c3d.read(path, stored_clusters=False)
    a, b = demo.track("seat"), raw.track("seat")
    dp, dq = se3.relative_pose(a.pos[a.valid], a.quat[a.valid], b.pos[a.valid], b.quat[a.valid])
    assert np.max(np.abs(dp - dp[0])) < 1e-6
    assert np.max(se3.quat_angle(dq, dq[0])) < 1e-5


def test_body_option_and_units(tmp_path, rng):
    _, xyz, _ = rigid_pair_scene(rng, n=30)
    labels = [f"a{k}" for k in range(4)] + [f"b{k}" for k in range(5)]
    path = tmp_path / "units.c3d"
    write_raw(path, labels, xyz * 100.0, units="cm")
    demo = c3d.read(path, bodies={"A": labels[:4], "B": labels[4:]})
    assert demo.body_names == ["A", "B"]
    p, q, v = demo.relative_pose("A", "B")
    assert v.all()
    assert np.max(np.abs(p - p[0])) < 1e-6
    assert np.max(se3.quat_angle(q, q[0])) < 1e-5
    assert c3d.read(path).body_names == []  # no prefixes in these labels
    loose = c3d.read(path, markers_as_bodies=True)
    assert len(loose) == 9 and not any(b.oriented for b in loose.bodies)
    np.testing.assert_allclose(loose.track("a0").pos, xyz[:, 0], atol=1e-6)
    with pytest.raises(FormatError, match=r"units\.c3d \(body B\).*'b9'"):
        c3d.read(path, bodies={"A": labels[:4], "B": ["b0", "b1", "b9"]})
    with pytest.raises(FormatError, match=r"\(body A\).*at least 3"):
        c3d.read(path, bodies={"A": labels[:2]})
    with pytest.raises(FormatError, match=r"POINT:UNITS.*furlong"):
        c3d.read(path, units="furlong")
    write_raw(path, labels, xyz * 100.0, units="parsec")
    with pytest.raises(FormatError, match=r"POINT:UNITS.*parsec"):
        c3d.read(path)
    write_raw(path, labels, xyz, units=None)  # no POINT:UNITS: millimetres
    assert c3d.read(path, markers_as_bodies=True).meta["units"] == "mm"


def test_blank_and_repeated_labels_are_made_unique(tmp_path, rng):
    path = tmp_path / "unlabelled.c3d"
    write_raw(path, ["*", "", "*", "a"], rng.uniform(1, 100, (4, 4, 3)))
    demo = c3d.read(path, markers_as_bodies=True)
    assert demo.body_names == ["*", "marker2", "*#2", "a"]


@pytest.mark.parametrize("rate", [0.0, np.nan])
def test_bad_rate(tmp_path, rng, rate):
    path = tmp_path / "rate.c3d"
    write_raw(path, ["a", "b", "c"], rng.uniform(0, 100, (5, 3, 3)), rate=100.0)
    # ezc3d refuses to write such a rate: patch POINT:RATE (group 1) and the header.
    data = bytearray(path.read_bytes())
    start = (data[0] - 1) * 512
    at = data.index(b"\x01RATE", start) + 5 + 2
    ptype, ndim = data[at], data[at + 1]
    assert ptype == 4
    value_at = at + 2 + ndim
    data[value_at : value_at + 4] = np.float32(rate).tobytes()
    data[20:24] = np.float32(rate).tobytes()
    path.write_bytes(bytes(data))
    with pytest.raises(FormatError, match=r"rate\.c3d \((POINT:RATE|header)\).*positive"):
        c3d.read(path)


# ------------------------------------------------------------- bad files
def test_malformed_files_raise_format_error_naming_the_file(tmp_path, rng):
    good = tmp_path / "good.c3d"
    c3d.write(sample_demo(rng, n=100), good)
    data = good.read_bytes()
    cases = {
        "empty.c3d": b"",
        "header_only.c3d": data[:300],
        "no_params.c3d": data[:520],
        "cut_data.c3d": data[: len(data) - 1000],
        "garbage.c3d": rng.integers(0, 256, 4000, dtype=np.uint8).tobytes(),
        "keyed_garbage.c3d": b"\x02\x50" + rng.integers(0, 256, 4000, dtype=np.uint8).tobytes(),
        "text.c3d": b"Format Version,1.23\nTake Name,x\n" * 50,
    }
    for name, content in cases.items():
        path = tmp_path / name
        path.write_bytes(content)
        with pytest.raises(FormatError, match=name.replace(".", r"\.")):
            c3d.read(path)
    with pytest.raises(FormatError, match=r"truncated.*frame"):
        c3d.read(tmp_path / "cut_data.c3d")


def test_truncated_file_on_request(tmp_path, rng):
    demo = sample_demo(rng, n=100)
    good = tmp_path / "good.c3d"
    c3d.write(demo, good)
    data = good.read_bytes()
    cut = tmp_path / "cut.c3d"
    cut.write_bytes(data[: len(data) - 1000])
    part = c3d.read(cut, allow_truncated=True)
    k = part.n_frames
    assert 0 < k < 100
    assert_same_motion(demo.slice(end=demo.t[k - 1]), part, pos_tol=1e-6, ang_tol=1e-5)
    raw = c3d.read(cut, allow_truncated=True, stored_clusters=False)
    assert "truncated" in raw.meta["c3d_truncated"]


def test_damaged_parameter_records_are_caught_before_ezc3d(tmp_path, rng):
    """Bytes flipped in the parameter section that used to crash ezc3d (segfault)."""
    good = tmp_path / "good.c3d"
    c3d.write(sample_demo(rng, n=10), good)
    data = bytearray(good.read_bytes())
    start = (data[0] - 1) * 512
    # The first group record's description length, made > 127.
    nlen = abs(int(np.frombuffer(bytes(data[start + 4 : start + 5]), np.int8)[0]))
    desc_at = start + 4 + 2 + nlen + 2
    bad = bytearray(data)
    bad[desc_at] = 0xFF
    path = tmp_path / "damaged.c3d"
    path.write_bytes(bytes(bad))
    with pytest.raises(FormatError, match=r"damaged\.c3d.*description length"):
        c3d.read(path)
    bad = bytearray(data)
    bad[start + 3] = 99  # processor type
    path.write_bytes(bytes(bad))
    with pytest.raises(FormatError, match="processor type"):
        c3d.read(path)


def test_too_many_frames(tmp_path, rng):
    n = c3d.MAX_FRAMES + 1000
    path = tmp_path / "long.c3d"
    # ezc3d writes every frame but can index (and read back) only 65535.
    write_raw(path, ["a"], rng.uniform(0, 100, (n, 1, 3)))
    with pytest.raises(
        FormatError, match=r"long\.c3d \(frame 65535\).*about 665.. frames, more than"
    ):
        c3d.read(path)
    demo = Demonstration(
        np.arange(n) / 100.0,
        [BodyInfo("a", oriented=False)],
        {"a": np.zeros((n, 3))},
        {"a": np.zeros((n, 4))},
    )
    with pytest.raises(FormatError, match="at most 65535 frames"):
        c3d.write(demo, path)


def test_sniff(tmp_path, rng):
    path = tmp_path / "demo.c3d"
    c3d.write(sample_demo(rng, n=5), path)
    renamed = tmp_path / "recording.dat"
    renamed.write_bytes(path.read_bytes())
    assert c3d.sniff(renamed)
    assert c3d.read(renamed).n_frames == 5
    text = tmp_path / "take.csv"
    text.write_text("Format Version,1.23\n")
    assert not c3d.sniff(text)
    assert not c3d.sniff(tmp_path)


def test_sample_file_shipped_with_ezc3d():
    """ezc3d's wheel ships no example .c3d (checked for 1.7.2); test one if it ever does."""
    files = sorted(f for d in site.getsitepackages() for f in Path(d, "ezc3d").rglob("*.c3d"))
    if not files:
        pytest.skip("the installed ezc3d package ships no sample .c3d file")
    demo = c3d.read(files[0], markers_as_bodies=True)
    assert demo.n_frames > 0 and len(demo) > 0
