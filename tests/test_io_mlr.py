"""The 3rdHand / MLR recording folder: real excerpt, round trips, malformed input."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from thirdhand import io
from thirdhand.demonstration import (
    BodyInfo,
    ConstraintEvent,
    Demonstration,
    InteractionInterval,
    Labels,
    PlanStep,
)
from thirdhand.errors import FormatError
from thirdhand.io import kvg, mlr
from thirdhand.se3 import random_quat

EXCERPT = ("3rdhand", "toolbox_coop_4_excerpt")


@pytest.fixture
def excerpt(shared_data: Path) -> Path:
    return shared_data.joinpath(*EXCERPT)


def _raw_blocks(path: Path) -> np.ndarray:
    """poses.dat parsed independently of the reader: shape (n_frames, n_rows, 7)."""
    blocks = re.findall(r"\[([^\]]*)\]", path.read_text())
    return np.array(
        [[[float(x) for x in ln.split()] for ln in b.strip().splitlines()] for b in blocks]
    )


def _raw_rows(meta: Path) -> dict[str, int]:
    return {
        m[1]: int(m[2])
        for m in re.finditer(r"(\S+)\s*=\s*\{[^}]*\brn\s*=\s*(\d+)", meta.read_text())
    }


# ------------------------------------------------------------------ real data
def test_excerpt_loads_eleven_bodies_at_100_hz(excerpt: Path) -> None:
    demo = mlr.read(excerpt)
    assert len(demo) == 11
    assert demo.n_frames == 100
    assert demo.rate == pytest.approx(100.0, rel=0.02)
    times = np.loadtxt(excerpt / "poses.dat.times")
    np.testing.assert_array_equal(demo.t, times[:, 1])
    assert demo.bodies_of_kind("finger") == [n for n in demo.body_names if n.startswith("/human/")]
    assert demo.bodies_of_kind("part") == ["/toolbox/side_left", "/toolbox/side_front"]
    assert demo.info("/human/rh/thumb") == BodyInfo(
        "/human/rh/thumb", "finger", "right", "/human/rh"
    )
    assert demo.info("/human/lh/middle").hand == "left"
    assert demo.info("/human/th/index").hand == "other"
    assert demo.info("/human/th/index").hand_body == "/human/th"
    assert 8 not in {s["rn"] for s in demo.meta["mlr"]["sensors"].values()}


def test_excerpt_missing_fractions_match_zero_rows(excerpt: Path) -> None:
    demo = mlr.read(excerpt)
    raw = _raw_blocks(excerpt / "poses.dat")
    rows = _raw_rows(excerpt / "meta.kvg")
    assert set(rows) == set(demo.body_names)
    for name, rn in rows.items():
        zero = np.all(raw[:, rn] == 0, axis=1)
        frac = demo.missing_fraction(name)
        assert 0.0 < frac < 1.0
        assert frac == pytest.approx(zero.mean(), abs=1e-12)
        np.testing.assert_array_equal(demo.valid(name), ~zero)


def test_excerpt_quaternion_reordered_to_xyzw(excerpt: Path) -> None:
    demo = mlr.read(excerpt)
    raw = _raw_blocks(excerpt / "poses.dat")
    rn = _raw_rows(excerpt / "meta.kvg")["/human/lh/thumb"]
    w, x, y, z = raw[0, rn, 3:]
    q = np.array([x, y, z, w]) / np.linalg.norm([x, y, z, w])
    np.testing.assert_allclose(demo.quat("/human/lh/thumb")[0], q, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(demo.pos("/human/lh/thumb")[0], raw[0, rn, :3])
    assert np.isnan(demo.pos("/human/rh/thumb")[0]).all()


def test_excerpt_round_trip_exact(excerpt: Path, tmp_path: Path) -> None:
    demo = mlr.read(excerpt)
    out = tmp_path / "copy"
    mlr.write(demo, out)
    back = mlr.read(out)
    assert back.equals(demo)
    assert back.bodies == demo.bodies
    # The copy carries thirdhand's writer mark: read as written, no second G4 repair.
    assert demo.meta["mlr"].pop("polhemus_repair") is True
    assert back.meta["mlr"].pop("polhemus_repair") is False
    assert back.meta["mlr"] == demo.meta["mlr"]
    assert _raw_rows(out / "meta.kvg") == _raw_rows(excerpt / "meta.kvg")
    assert _raw_blocks(out / "poses.dat").shape == _raw_blocks(excerpt / "poses.dat").shape


def test_registry_detects_mlr_folder(excerpt: Path) -> None:
    for name in io.FORMATS:
        try:
            io.format_module(name)
        except ModuleNotFoundError:
            pytest.skip(f"format module {name!r} not in the tree yet")
    assert io.detect(excerpt) == "mlr"
    assert io.detect(excerpt / "poses.dat") == "mlr"
    demo = io.load(excerpt)
    assert len(demo) == 11


def test_registry_saves_folder_as_mlr(excerpt: Path, tmp_path: Path) -> None:
    demo = mlr.read(excerpt)
    io.save(demo, tmp_path / "rec", format="mlr")
    assert mlr.read(tmp_path / "rec").equals(demo)
    io.save(demo, tmp_path / "rec", format="mlr", overwrite=True)
    assert (tmp_path / "rec.bak" / "poses.dat").is_file()


@pytest.mark.parametrize(
    ("name", "section", "type_", "expected"),
    [
        (
            "/human/rh/thumb",
            "agents",
            "digit",
            BodyInfo("/human/rh/thumb", "finger", "right", "/human/rh"),
        ),
        (
            "/human/lh/index",
            "agents",
            "digit",
            BodyInfo("/human/lh/index", "finger", "left", "/human/lh"),
        ),
        (
            "/human/th/index",
            "agents",
            "digit",
            BodyInfo("/human/th/index", "finger", "other", "/human/th"),
        ),
        ("/human/rh", "agents", "hand", BodyInfo("/human/rh", "hand", "right")),
        ("/human/head", "agents", "head", BodyInfo("/human/head", "head")),
        ("/screwdriver", "objects", "screwdriver", BodyInfo("/screwdriver", "tool")),
        ("/tools/driver", "objects", "tool", BodyInfo("/tools/driver", "tool")),
        ("/toolbox/side_left", "objects", "side_short", BodyInfo("/toolbox/side_left", "part")),
        ("/toolbox/handle", "objects", "handle", BodyInfo("/toolbox/handle", "part")),
        ("/robot/gripper", "agents", "gripper", BodyInfo("/robot/gripper", "other")),
    ],
)
def test_kind_from_name_and_type(name: str, section: str, type_: str, expected: BodyInfo) -> None:
    assert mlr.derive_body(name, section, type_) == expected


# ------------------------------------------------------------------- labels
def _copy_excerpt(excerpt: Path, dst: Path) -> Path:
    dst.mkdir()
    for name in ("poses.dat", "poses.dat.times", "meta.kvg"):
        shutil.copyfile(excerpt / name, dst / name)
    return dst


def test_labels_attach_with_hand_expanded_to_fingers(excerpt: Path, tmp_path: Path) -> None:
    folder = _copy_excerpt(excerpt, tmp_path / "rec")
    (folder / "ann_kvg.kvg").write_text(
        " TS /human/rh /toolbox/side_front { lock { from=10  to=20 }  lock { from=40  to=45 } }\n"
        " TS /human/th/index /toolbox/side_left { lock { from=5  to=7 } }\n"
        " CE /toolbox/side_front /toolbox/side_left { lock { from=30  to=99 } }\n"
        " CE /toolbox/side_left /toolbox/side_front { lock { from=50  to=60 } }\n"
    )
    demo = mlr.read(folder)
    t = demo.t
    fingers = ["/human/rh/thumb", "/human/rh/index", "/human/rh/middle"]
    expected = [
        InteractionInterval(f, "/toolbox/side_front", t[s], t[e])
        for f in fingers
        for s, e in ((10, 20), (40, 45))
    ] + [InteractionInterval("/human/th/index", "/toolbox/side_left", t[5], t[7])]
    assert list(demo.labels.interactions) == expected
    cons = demo.labels.constraints
    assert [(c.time, c.parent, c.child, c.type, c.removed) for c in cons] == [
        (t[30], "/toolbox/side_front", "/toolbox/side_left", "fixed", False),
        (t[50], "/toolbox/side_left", "/toolbox/side_front", "fixed", False),
        (t[60], "/toolbox/side_left", "/toolbox/side_front", "fixed", True),
    ]
    assert demo.meta["labels_source"] == "ann_kvg.kvg"
    out = tmp_path / "out"
    mlr.write(demo, out)
    text = (out / "ann_kvg.kvg").read_text()
    assert "TS /human/rh /toolbox/side_front" in text
    assert "/human/rh/thumb" not in text
    assert mlr.read(out).labels == demo.labels


def test_label_naming_unknown_body_raises(excerpt: Path, tmp_path: Path) -> None:
    folder = _copy_excerpt(excerpt, tmp_path / "rec")
    (folder / "ann_kvg.kvg").write_text(
        " TS /human/rh /toolbox/side_front { lock { from=1  to=2 } }\n"
        " TS /human/lh /toolbox/side_back { lock { from=1  to=2 } }\n"
    )
    with pytest.raises(FormatError, match=r"ann_kvg\.kvg line 2.*/toolbox/side_back") as err:
        mlr.read(folder)
    assert err.value.line == 2


def test_label_frame_beyond_recording_raises(excerpt: Path, tmp_path: Path) -> None:
    folder = _copy_excerpt(excerpt, tmp_path / "rec")
    (folder / "ann_kvg.kvg").write_text(
        "CE /toolbox/side_front /toolbox/side_left { lock { from=3107 to=22547 } }\n"
    )
    with pytest.raises(FormatError, match=r"ann_kvg\.kvg line 1.*frame 3107.*100 frames"):
        mlr.read(folder)


def test_elan_labels_attach_on_media_time(excerpt: Path, tmp_path: Path) -> None:
    pympi = pytest.importorskip("pympi")
    folder = _copy_excerpt(excerpt, tmp_path / "rec")
    eaf = pympi.Elan.Eaf()
    eaf.add_tier("TS /human/lh /toolbox/side_left")
    eaf.add_annotation("TS /human/lh /toolbox/side_left", 120, 450)
    eaf.add_tier("CE /toolbox/side_front /toolbox/side_left")
    eaf.add_annotation("CE /toolbox/side_front /toolbox/side_left", 500, 1000)
    eaf.add_tier("notes")
    eaf.add_annotation("notes", 0, 10, "ignored")
    pympi.Elan.to_eaf(str(folder / "elan.eaf"), eaf)
    demo = mlr.read(folder)
    t0 = demo.t[0]
    assert [(i.a, i.start, i.end) for i in demo.labels.interactions] == [
        (f"/human/lh/{f}", t0 + 0.12, t0 + 0.45) for f in ("thumb", "index", "middle")
    ]
    assert [(c.time, c.removed) for c in demo.labels.constraints] == [(t0 + 0.5, False)]
    # Media time 0 taken as recording time 0 puts the labels 14 h before the recording.
    with pytest.raises(FormatError, match="outside the recording"):
        mlr.read(folder, elan_offset=0.0)
    assert not mlr.read(folder, labels=False).labels
    (folder / "ann_kvg.kvg").write_text(
        " TS /human/lh /toolbox/side_left { lock { from=1  to=2 } }\n"
    )
    both = mlr.read(folder)
    assert both.meta["labels_source"] == "ann_kvg.kvg"
    assert len(both.labels.interactions) == 3 and not both.labels.constraints


def test_hand_label_kept_when_the_hand_is_a_body(tmp_path: Path) -> None:
    bodies = [
        BodyInfo("/human/rh", "hand", "right"),
        BodyInfo("/human/rh/thumb", "finger", "right", "/human/rh"),
        BodyInfo("box", "part"),
    ]
    p = tmp_path / "ann_kvg.kvg"
    p.write_text("TS /human/rh box { lock { from=1 to=2 } }\n")
    lab = kvg.read_annotations(p, rate=10.0, bodies=bodies)
    assert lab.interactions == (InteractionInterval("/human/rh", "box", 0.1, 0.2),)


# --------------------------------------------------------------- synthetic
def _synthetic(rng: np.random.Generator) -> Demonstration:
    n = 50
    t = 1000.0 + np.cumsum(rng.uniform(0.005, 0.015, n))
    bodies = [
        BodyInfo("/human/rh/thumb", "finger", "right", "/human/rh"),
        BodyInfo("/human/rh/index", "finger", "right", "/human/rh"),
        BodyInfo("p2_index", "finger", "left", "p2/left", person="p2"),
        BodyInfo("/tools/screwdriver", "tool"),
        BodyInfo("/human/head", "head"),
        BodyInfo("seat", "part"),
        BodyInfo("marker", "other", oriented=False),
        BodyInfo("/human/lh/ring", "finger", None, None, person="7"),
        BodyInfo("thumb2", "finger", "right", "p3"),
    ]
    pos, quat, valid = {}, {}, {}
    for b in bodies:
        pos[b.name] = rng.uniform(-2, 2, (n, 3))
        quat[b.name] = random_quat(rng, n)
        valid[b.name] = rng.random(n) > 0.2
    labels = Labels(
        interactions=(
            InteractionInterval("/human/rh/thumb", "seat", t[3], t[9]),
            InteractionInterval("/human/rh/index", "seat", t[3], t[9]),
            InteractionInterval("p2_index", "/tools/screwdriver", t[1], t[2]),
            InteractionInterval("/human/rh/index", "seat", t[20], t[30]),
        ),
        constraints=(
            ConstraintEvent(
                t[10],
                "seat",
                "/tools/screwdriver",
                "revolute",
                symbol="c2",
                pos=(0.1, 0.2, 0.3),
                quat=(0.0, 0.0, 0.6, 0.8),
                free_dofs=((0, 0),) * 5 + ((-3.14, 3.14),),
            ),
            ConstraintEvent(
                t[15],
                "seat",
                "/tools/screwdriver",
                "revolute",
                symbol="c2",
                pos=(0.1, 0.2, 0.3),
                quat=(0.0, 0.0, 0.6, 0.8),
                free_dofs=((0, 0),) * 5 + ((-3.14, 3.14),),
                removed=True,
            ),
            ConstraintEvent(t[20], "seat", "marker", "fixed"),
        ),
        plan=(PlanStep("seat", "marker", "c1", t[20]), PlanStep("seat", "/human/head")),
    )
    return Demonstration(t, bodies, pos, quat, valid, labels=labels)


def test_synthetic_round_trip_exact(rng: np.random.Generator, tmp_path: Path) -> None:
    demo = _synthetic(rng)
    mlr.write(demo, tmp_path / "rec")
    back = mlr.read(tmp_path / "rec")
    assert back.bodies == demo.bodies
    assert back.labels == demo.labels
    assert back.equals(demo)
    for name in demo.body_names:
        np.testing.assert_array_equal(back.quat(name), demo.quat(name))
        np.testing.assert_array_equal(back.pos(name), demo.pos(name))
    mlr.write(back, tmp_path / "again")
    for f in ("poses.dat", "poses.dat.times", "meta.kvg", "ann_kvg.kvg"):
        assert (tmp_path / "again" / f).read_text() == (tmp_path / "rec" / f).read_text()


def test_write_refuses_overwrite_and_keeps_backup(rng: np.random.Generator, tmp_path: Path) -> None:
    demo = _synthetic(rng)
    folder = tmp_path / "rec"
    mlr.write(demo, folder)
    first = (folder / "poses.dat").read_text()
    with pytest.raises(FormatError, match="already exists"):
        mlr.write(demo, folder)
    shorter = demo.slice(end=demo.t[10])
    mlr.write(shorter, folder, overwrite=True)
    assert (tmp_path / "rec.bak" / "poses.dat").read_text() == first
    assert mlr.read(folder).n_frames == 11
    assert not [p for p in tmp_path.iterdir() if "tmp" in p.name]


# --------------------------------------------------------------- malformed
GOOD_META = "objects {\n  a = { type = part, rn = 0 }\n  b = { type = part, rn = 1 }\n}\n"
ROW = "0.1 0.2 0.3 1 0 0 0"


def _folder(tmp_path: Path, poses: str, times: str | None = None, meta: str = GOOD_META) -> Path:
    folder = tmp_path / "bad"
    folder.mkdir(exist_ok=True)
    (folder / "poses.dat").write_text(poses)
    n = poses.count("[")
    (folder / "poses.dat.times").write_text(
        times if times is not None else "".join(f"{i + 1} {0.01 * i}\n" for i in range(n))
    )
    (folder / "meta.kvg").write_text(meta)
    return folder


def _poses(n: int = 3) -> str:
    return "".join(f"[ {ROW}\n  {ROW} ]\n" for _ in range(n))


def test_small_good_folder_reads(tmp_path: Path) -> None:
    demo = mlr.read(_folder(tmp_path, _poses()))
    assert demo.body_names == ["a", "b"]
    np.testing.assert_array_equal(demo.quat("a")[0], [0, 0, 0, 1])


@pytest.mark.parametrize(
    ("poses", "times", "meta", "file", "line", "pattern"),
    [
        ("", None, GOOD_META, "poses.dat", None, "empty"),
        (
            _poses(2) + f"[ {ROW}\n  {ROW}\n",
            "1 0\n2 0.01\n3 0.02\n",
            GOOD_META,
            "poses.dat",
            5,
            "never closed",
        ),
        (
            _poses(1) + f"[ {ROW}\n  0.1 x 0.3 1 0 0 0 ]\n",
            None,
            GOOD_META,
            "poses.dat",
            4,
            "'x' is not a number",
        ),
        (
            _poses(1) + f"[ {ROW}\n  0.1 0.2 0.3 1 0 0 ]\n",
            None,
            GOOD_META,
            "poses.dat",
            4,
            "expected 7 numbers per row.*got 6",
        ),
        (_poses(2) + f"[ {ROW} ]\n", None, GOOD_META, "poses.dat", 5, "expected 2 sensor rows"),
        (f"{ROW}\n{ROW}\n", None, GOOD_META, "poses.dat", 1, "outside a"),
        (_poses(1) + f"  {ROW}\n", None, GOOD_META, "poses.dat", 3, "outside a"),
        (_poses(1) + "]\n", None, GOOD_META, "poses.dat", 3, "'\\]' without a matching"),
        (f"[ {ROW}\n[ {ROW} ]\n", None, GOOD_META, "poses.dat", 2, "inside an unclosed block"),
        (_poses(3), "1 0\n2 0.01\n", GOOD_META, "poses.dat.times", 2, "2 time stamps for the 3"),
        (_poses(3), "1 0\n2 0.02\n3 0.01\n", GOOD_META, "poses.dat.times", 3, "must increase"),
        (
            _poses(1) + f"[ {ROW}\n  0.1 0.2 0.3 0 0 0 0 ]\n",
            None,
            GOOD_META,
            "poses.dat",
            4,
            "zero-norm quaternion",
        ),
        (
            _poses(1) + f"[ {ROW}\n  100.5 220 310 1 0 0 0 ]\n",
            None,
            GOOD_META,
            "poses.dat",
            4,
            "millimetres",
        ),
        (
            _poses(2),
            None,
            "objects {\n  a = { type = part, rn = 0 }\n",
            "meta.kvg",
            1,
            "unbalanced braces",
        ),
        (
            _poses(2),
            None,
            "objects {\n  a = { type = part, rn = 5 }\n}\n",
            "meta.kvg",
            2,
            "rn = 5 but poses.dat has 2",
        ),
        (
            _poses(2),
            None,
            "objects {\n  a = { rn = 0 }\n  a = { rn = 1 }\n}\n",
            "meta.kvg",
            3,
            "appears twice",
        ),
    ],
)
def test_malformed_folder_raises(
    tmp_path: Path,
    poses: str,
    times: str | None,
    meta: str,
    file: str,
    line: int | None,
    pattern: str,
) -> None:
    folder = _folder(tmp_path, poses, times, meta)
    with pytest.raises(FormatError, match=pattern) as err:
        mlr.read(folder)
    assert Path(err.value.path).name == file
    assert err.value.line == line
    assert file in str(err.value)


def test_sensor_error_names_frame_and_body(tmp_path: Path) -> None:
    folder = _folder(tmp_path, _poses(1) + f"[ {ROW}\n  0.1 0.2 0.3 0 0 0 0 ]\n")
    with pytest.raises(FormatError, match=r"frame 1, sensor row 1 = b"):
        mlr.read(folder)


def test_missing_files_raise(tmp_path: Path) -> None:
    folder = _folder(tmp_path, _poses())
    (folder / "poses.dat.times").unlink()
    with pytest.raises(FormatError, match=r"poses\.dat\.times: missing"):
        mlr.read(folder)
    (folder / "meta.kvg").unlink()
    with pytest.raises(FormatError, match=r"meta\.kvg: missing"):
        mlr.read(folder)
    with pytest.raises(FormatError, match="no such folder"):
        mlr.read(tmp_path / "nowhere")


def test_sniff(tmp_path: Path) -> None:
    folder = _folder(tmp_path, _poses())
    assert mlr.sniff(folder)
    assert mlr.sniff(folder / "poses.dat")
    assert not mlr.sniff(folder / "meta.kvg")
    assert not mlr.sniff(tmp_path)


def _tracks(n: int = 300, sensors: int = 4) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """100 Hz, every sensor still at its own place 0.3–0.6 m from the source."""
    t = np.arange(n) / 100.0
    home = 0.3 + 0.1 * np.arange(sensors)
    pos = np.zeros((n, sensors, 3))
    pos[:, :, 0] = home
    return t, pos, np.ones((n, sensors), dtype=bool)


def test_acquisition_reports_at_the_source_and_their_settling_are_dropped() -> None:
    t, pos, seen = _tracks()
    pos[100:110, 1] = 2e-4  # one sensor reported at the source for 0.1 s
    pos[110, 1, 0] = 0.15  # its filter on the way back
    valid, resets = mlr.acquisition_validity(t, pos, seen)
    assert resets == []  # one sensor of four: no reset
    gap = ~valid[:, 1]
    # The reports (frames 100-109) and every sample within 0.1 s of them (frames
    # 90 and 119 are 0.1 s away: on the edge, either way).
    assert gap[91:119].all() and not gap[:90].any() and not gap[120:].any()
    assert valid[:, [0, 2, 3]].all()


def test_acquisition_frame_reset_drops_what_came_before() -> None:
    t, pos, seen = _tracks()
    pos[100:120] = 1e-4  # every sensor at the source for 0.2 s ...
    pos[120:, :, :2] = -pos[120:, :, :2]  # ... then back, mirrored: another frame
    valid, resets = mlr.acquisition_validity(t, pos, seen)
    assert resets == [pytest.approx(t[119] + mlr.SETTLE_S)]
    assert not valid[:129].any() and valid[130:].all()
    # The same episode without a change of frame drops the episode only.
    t, pos, seen = _tracks()
    pos[100:120] = 1e-4
    valid, resets = mlr.acquisition_validity(t, pos, seen)
    assert resets == []
    assert valid[:90].all() and not valid[91:129].any() and valid[130:].all()


def test_real_start_up_dropout_and_frame_reset(shared_data: Path) -> None:
    # toolbox_coop_4: every sensor goes to the G4's source at 1.6-2.5 s and comes
    # back in a mirrored frame; the first 2.6 s are dropped, none after.
    demo = io.load(shared_data / "3rdhand" / "toolbox_coop_4")
    (reset,) = demo.meta["mlr"]["frame_resets_s"]
    assert 2.5 < reset - demo.t[0] < 2.7
    for b in demo.body_names:
        p = demo.pos(b)
        tracked = np.isfinite(p[:, 0])
        assert not tracked[demo.t <= reset].any()
        assert np.linalg.norm(p[tracked], axis=1).min() > 0.05  # nothing at the source
