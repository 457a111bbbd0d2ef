"""OptiTrack Motive CSV: hand-written exports in the real layouts, round trips, bad files.

No real Motive export is available in the shared data folder; the files below
follow the layouts of public Motive exports (format 1.21 without row labels,
1.23 with Type/Name/ID, 1.25 with a Parent row and a TimeCode column).
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from thirdhand.demonstration import BodyInfo, Demonstration
from thirdhand.errors import FormatError
from thirdhand.io import detect, load, motive, save

# Motive 1.23 (Motive 2.x): a rigid body "seat" with its rigid-body marker and the
# physical marker, a second rigid body "leg 1", an unlabelled marker. 28 columns.
V123 = (
    "Format Version,1.23,Take Name,chair_01,Take Notes,,Capture Frame Rate,120.000000,"
    "Export Frame Rate,120.000000,Capture Start Time,2026-11-20 10.15.02.120 AM,"
    "Capture Start Frame,51234,Total Frames in Take,4,Total Exported Frames,4,"
    "Rotation Type,Quaternion,Length Units,Meters,Coordinate Space,Global\n"
    "\n"
    ",Type,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,"
    "Rigid Body,Rigid Body Marker,Rigid Body Marker,Rigid Body Marker,Rigid Body Marker,"
    "Marker,Marker,Marker,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,"
    "Rigid Body,Rigid Body,Marker,Marker,Marker\n"
    ",Name,seat,seat,seat,seat,seat,seat,seat,seat,seat:Marker1,seat:Marker1,seat:Marker1,"
    "seat:Marker1,seat:Marker1,seat:Marker1,seat:Marker1,leg 1,leg 1,leg 1,leg 1,leg 1,leg 1,"
    "leg 1,leg 1,Unlabeled 1001,Unlabeled 1001,Unlabeled 1001\n"
    ",ID,1,1,1,1,1,1,1,1,1:1,1:1,1:1,1:1,1:1,1:1,1:1,2,2,2,2,2,2,2,2,"
    "9F:0000,9F:0000,9F:0000\n"
    ",,Rotation,Rotation,Rotation,Rotation,Position,Position,Position,Mean Marker Error,"
    "Position,Position,Position,Marker Quality,Position,Position,Position,Rotation,Rotation,"
    "Rotation,Rotation,Position,Position,Position,Mean Marker Error,Position,Position,Position\n"
    "Frame,Time (Seconds),X,Y,Z,W,X,Y,Z,,X,Y,Z,,X,Y,Z,X,Y,Z,W,X,Y,Z,,X,Y,Z\n"
    "0,0.000000,0.000000,0.000000,0.000000,1.000000,0.125000,0.850000,-0.310000,0.000210,"
    "0.150000,0.870000,-0.300000,1.000000,0.150100,0.870200,-0.299900,0.600000,0.000000,"
    "0.000000,0.800000,-0.420000,0.050000,0.210000,0.000180,1.500000,0.020000,2.250000\n"
    "1,0.008333,0.000000,0.600000,0.000000,0.800000,0.126000,0.851000,-0.312000,0.000200,"
    "0.151000,0.871000,-0.302000,0.990000,0.151100,0.871200,-0.301900,,,,,,,,,"
    "1.500000,0.020000,2.250000\n"
    "2,0.016667,,,,,,,,,0.152000,0.872000,-0.304000,0.980000,,,,0.500000,0.500000,0.500000,"
    "0.500000,-0.410000,0.051000,0.212000,0.000190,,,\n"
    "3,0.025000,0.280000,0.000000,0.000000,0.960000,0.128000,0.853000,-0.316000,0.000220,"
    "0.153000,0.873000,-0.306000,1.000000,0.153100,0.873200,-0.305900,0.000000,0.000000,"
    "-0.600000,0.800000,-0.400000,0.052000,0.214000,0.000200,1.500000,0.020000,2.250000\n"
)
V123_DATA_LINE = 8

SEAT_POS = [[0.125, 0.85, -0.31], [0.126, 0.851, -0.312], [np.nan] * 3, [0.128, 0.853, -0.316]]
SEAT_QUAT = [[0.0, 0.0, 0.0, 1.0], [0.0, 0.6, 0.0, 0.8], [np.nan] * 4, [0.28, 0.0, 0.0, 0.96]]
LEG_POS = [[-0.42, 0.05, 0.21], [np.nan] * 3, [-0.41, 0.051, 0.212], [-0.4, 0.052, 0.214]]
LEG_QUAT = [[0.6, 0.0, 0.0, 0.8], [np.nan] * 4, [0.5, 0.5, 0.5, 0.5], [0.0, 0.0, -0.6, 0.8]]

# Motive 3.x (format 1.25): Parent row, TimeCode column, millimetres, a take that
# starts at frame 600 (6 s).
V125_MM = (
    "Format Version,1.25,Take Name,bench_07,Take Notes,,Capture Frame Rate,100.000000,"
    "Export Frame Rate,100.000000,Capture Start Time,2026-11-21 02.40.11.500 PM,"
    "Capture Start Frame,600,Total Frames in Take,3,Total Exported Frames,3,"
    "Rotation Type,Quaternion,Length Units,Millimeters,Coordinate Space,Global\n"
    "\n"
    ",Type,,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,"
    "Rigid Body\n"
    ",Name,,screwdriver,screwdriver,screwdriver,screwdriver,screwdriver,screwdriver,"
    "screwdriver,screwdriver\n"
    ',ID,,"B7A1","B7A1","B7A1","B7A1","B7A1","B7A1","B7A1","B7A1"\n'
    ",Parent,,,,,,,,,\n"
    ",,,Rotation,Rotation,Rotation,Rotation,Position,Position,Position,Mean Marker Error\n"
    "Frame,Time (Seconds),TimeCode,X,Y,Z,W,X,Y,Z,\n"
    "600,6.000000,00:00:06:00.0,0.000000,0.000000,0.000000,1.000000,1234.500000,"
    "87.250000,-412.125000,0.210000\n"
    "601,6.010000,00:00:06:01.0,,,,,,,,\n"
    "602,6.020000,00:00:06:02.0,0.000000,0.000000,0.600000,0.800000,1240.000000,90.000000,"
    "-415.750000,0.190000\n"
)

# Format 1.21 (Motive 1.10): the same header rows without labels, "Time" column.
V121 = (
    "Format Version,1.21,Take Name,Take 2016-01-05,Capture Frame Rate,120.000000,"
    "Export Frame Rate,120.000000,Total Frames in Take,2,Total Exported Frames,2,"
    "Rotation Type,Quaternion,Length Units,Centimeters,Coordinate Space,Global\n"
    "\n"
    ",,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,"
    "Rigid Body,Marker,Marker,Marker\n"
    ",,Rigid Body 1,Rigid Body 1,Rigid Body 1,Rigid Body 1,Rigid Body 1,Rigid Body 1,"
    "Rigid Body 1,Rigid Body 1,Rigid Body 1:Marker1,Rigid Body 1:Marker1,"
    "Rigid Body 1:Marker1\n"
    ',,"CF51","CF51","CF51","CF51","CF51","CF51","CF51","CF51","83","83","83"\n'
    ",,Rotation,Rotation,Rotation,Rotation,Position,Position,Position,Error Per Marker,"
    "Position,Position,Position\n"
    "Frame,Time,X,Y,Z,W,X,Y,Z,,X,Y,Z\n"
    "0,0.000000,0.000000,0.000000,0.000000,-1.000000,6.000200,1.915000,7.661100,0.000400,"
    "1.000000,1.900000,0.980000\n"
    "1,0.008333,0.000000,0.000000,0.000000,-1.000000,6.000400,1.916100,7.659400,0.001100,,,\n"
)


def _write(tmp_path: Path, text: str, name: str = "take.csv", newline: str = "\n") -> Path:
    p = tmp_path / name
    p.write_bytes(text.replace("\n", newline).encode("utf-8"))
    return p


# ------------------------------------------------------------------- reading
@pytest.mark.parametrize("newline", ["\n", "\r\n"])
def test_read_v123_exact_values(tmp_path: Path, newline: str) -> None:
    demo = motive.read(_write(tmp_path, V123, newline=newline))
    assert demo.body_names == ["seat", "leg 1"]
    assert demo.t.tolist() == [0.0, 1 / 120, 2 / 120, 3 / 120]
    np.testing.assert_array_equal(demo.pos("seat"), SEAT_POS)
    np.testing.assert_array_equal(demo.quat("seat"), SEAT_QUAT)
    np.testing.assert_array_equal(demo.pos("leg 1"), LEG_POS)
    np.testing.assert_array_equal(demo.quat("leg 1"), LEG_QUAT)
    assert demo.valid("seat").tolist() == [True, True, False, True]
    assert demo.valid("leg 1").tolist() == [True, False, True, True]
    assert all(b.kind == "part" and b.oriented for b in demo.bodies)
    m = demo.meta
    assert m["format"] == "motive" and m["format_version"] == "1.23"
    assert m["take_name"] == "chair_01"
    assert m["capture_frame_rate"] == 120.0 and m["export_frame_rate"] == 120.0
    assert m["length_units"] == "Meters" and m["rotation_type"] == "Quaternion"
    assert m["coordinate_space"] == "Global" and m["up_axis"] == "y"
    assert m["motive_ids"] == {"seat": "1", "leg 1": "2"}
    assert m["capture_start_time"] == "2026-11-20 10.15.02.120 AM"
    assert m["motive_header"]["Capture Start Frame"] == "51234"


def test_read_parent_row_timecode_millimetres(tmp_path: Path) -> None:
    demo = motive.read(_write(tmp_path, V125_MM), kinds={"screwdriver": "tool"})
    assert demo.body_names == ["screwdriver"]
    assert demo.info("screwdriver").kind == "tool"
    assert demo.t.tolist() == [600 / 100, 601 / 100, 602 / 100]
    expected = np.array([[1234.5, 87.25, -412.125], [np.nan] * 3, [1240.0, 90.0, -415.75]])
    np.testing.assert_array_equal(demo.pos("screwdriver"), expected / 1000.0)
    np.testing.assert_array_equal(
        demo.quat("screwdriver"), [[0, 0, 0, 1.0], [np.nan] * 4, [0, 0, 0.6, 0.8]]
    )
    assert demo.valid("screwdriver").tolist() == [True, False, True]
    assert demo.meta["length_units"] == "Millimeters"
    assert demo.meta["format_version"] == "1.25"
    assert demo.meta["motive_ids"] == {"screwdriver": "B7A1"}


def test_read_unlabelled_rows_of_format_121_in_centimetres(tmp_path: Path) -> None:
    demo = motive.read(_write(tmp_path, V121), include_markers=True)
    assert demo.body_names == ["Rigid Body 1", "Rigid Body 1:Marker1"]
    np.testing.assert_array_equal(
        demo.pos("Rigid Body 1"),
        np.array([[6.0002, 1.915, 7.6611], [6.0004, 1.9161, 7.6594]]) / 100,
    )
    np.testing.assert_array_equal(demo.quat("Rigid Body 1"), [[0, 0, 0, -1.0]] * 2)
    marker = demo.info("Rigid Body 1:Marker1")
    assert not marker.oriented
    assert demo.valid("Rigid Body 1:Marker1").tolist() == [True, False]
    np.testing.assert_array_equal(
        demo.pos("Rigid Body 1:Marker1")[0], np.array([1.0, 1.9, 0.98]) / 100
    )
    assert demo.meta["motive_ids"]["Rigid Body 1"] == "CF51"


def test_include_markers_keeps_labelled_physical_markers_only(tmp_path: Path) -> None:
    demo = motive.read(_write(tmp_path, V123), include_markers=True)
    assert demo.body_names == ["seat", "seat:Marker1", "leg 1"]
    m = demo.info("seat:Marker1")
    assert not m.oriented and m.kind == "part"
    np.testing.assert_array_equal(
        demo.pos("seat:Marker1"),
        [
            [0.1501, 0.8702, -0.2999],
            [0.1511, 0.8712, -0.3019],
            [np.nan] * 3,
            [0.1531, 0.8732, -0.3059],
        ],
    )
    assert demo.valid("seat:Marker1").tolist() == [True, True, False, True]
    np.testing.assert_array_equal(demo.quat("seat:Marker1")[0], [0, 0, 0, 1.0])


def test_utf8_bom_and_header_up_axis(tmp_path: Path) -> None:
    text = V123.replace("Coordinate Space,Global", "Coordinate Space,Global,Up Axis,Z", 1)
    p = tmp_path / "bom.csv"
    p.write_bytes(b"\xef\xbb\xbf" + text.encode())
    assert motive.sniff(p)
    demo = motive.read(p, up_axis="y")
    assert demo.meta["up_axis"] == "z"
    assert demo.n_frames == 4


def test_length_unit_override(tmp_path: Path) -> None:
    text = V125_MM.replace("Length Units,Millimeters", "Length Units,Meters")
    p = _write(tmp_path, text)
    with pytest.raises(FormatError, match="millimetres"):
        motive.read(p)
    demo = motive.read(p, length_units="mm")
    assert demo.pos("screwdriver")[0, 0] == 1234.5 / 1000.0


def test_time_column_is_cross_checked_and_frames_define_the_axis(tmp_path: Path) -> None:
    # Motive rounds the Time column to microseconds; the axis is frame / rate exactly.
    demo = motive.read(_write(tmp_path, V123))
    assert demo.t[1] == 1 / 120 and demo.t[1] != 0.008333
    # A Time column starting its own clock at a custom start frame is honoured.
    text = V123.replace("\n0,0.000000,", "\n600,0.000000,").replace(
        "\n1,0.008333,", "\n601,0.008333,"
    )
    text = text.replace("\n2,0.016667,", "\n602,0.016667,").replace(
        "\n3,0.025000,", "\n603,0.025000,"
    )
    demo = motive.read(_write(tmp_path, text, "offset.csv"))
    np.testing.assert_allclose(demo.t, np.arange(4) / 120, rtol=0, atol=1e-15)


# ----------------------------------------------------------------- registry
def test_load_detects_motive_and_save_writes_it(tmp_path: Path) -> None:
    p = _write(tmp_path, V123)
    assert detect(p) == "motive"
    demo = load(p)
    assert demo.body_names == ["seat", "leg 1"]
    out = tmp_path / "copy.csv"
    save(demo, out)
    assert detect(out) == "motive"
    assert load(out).equals(demo)
    assert not motive.sniff(tmp_path)
    other = tmp_path / "plain.csv"
    other.write_text("a,b\n1,2\n")
    assert not motive.sniff(other)


# --------------------------------------------------------------- round trip
def _random_demo(rng: np.random.Generator, *, n: int, t0: float, rate: float) -> Demonstration:
    names = ["seat", "leg, front", 'tool "A"', "/human/rh/thumb"]
    infos = [BodyInfo(nm, oriented=k != 3) for k, nm in enumerate(names)]
    pos, quat, valid = {}, {}, {}
    for info in infos:
        v = rng.random(n) > 0.2
        v[rng.integers(0, n - 10) :][:7] = False  # a gap
        q = rng.normal(size=(n, 4))
        pos[info.name] = rng.normal(scale=1.5, size=(n, 3)) * rng.choice([1e-7, 1.0, 5.0])
        quat[info.name] = q / np.linalg.norm(q, axis=1, keepdims=True)
        valid[info.name] = v
    t = t0 + np.arange(n) / rate
    return Demonstration(t, infos, pos, quat, valid, meta={"up_axis": "z", "take_name": "rt"})


@pytest.mark.parametrize(("t0", "rate"), [(0.0, 120.0), (3.2571, 100.0), (-1.5, 239.76)])
def test_round_trip_is_bit_exact(
    tmp_path: Path, rng: np.random.Generator, t0: float, rate: float
) -> None:
    demo = _random_demo(rng, n=500, t0=t0, rate=rate)
    p = tmp_path / "rt.csv"
    motive.write(demo, p)
    back = motive.read(p, include_markers=True)
    assert back.body_names == demo.body_names
    assert np.array_equal(back.t, demo.t)
    for name in demo.body_names:
        assert np.array_equal(back.valid(name), demo.valid(name))
        assert np.array_equal(back.pos(name), demo.pos(name), equal_nan=True)
        assert np.array_equal(back.quat(name), demo.quat(name), equal_nan=True)
        assert back.info(name).oriented == demo.info(name).oriented
    assert back.meta["up_axis"] == "z" and back.meta["take_name"] == "rt"
    assert back.meta["export_frame_rate"] == rate
    assert [f.name for f in tmp_path.iterdir()] == ["rt.csv"]  # no temp file left


def test_write_refuses_an_irregular_axis_and_keeps_the_old_file(
    tmp_path: Path, rng: np.random.Generator
) -> None:
    demo = _random_demo(rng, n=50, t0=0.0, rate=100.0)
    t = demo.t.copy()
    t[20:] += 0.004
    bad = demo.replace(t=t)
    p = _write(tmp_path, V123, "keep.csv")
    with pytest.raises(FormatError, match="regular time axis") as err:
        motive.write(bad, p)
    assert "keep.csv" in str(err.value)
    assert p.read_text() == V123
    assert [f.name for f in tmp_path.iterdir()] == ["keep.csv"]


# ------------------------------------------------------------ malformed input
def _replace_line(text: str, lineno: int, new: str | None) -> str:
    lines = text.split("\n")
    if new is None:
        del lines[lineno - 1]
    else:
        lines[lineno - 1] = new
    return "\n".join(lines)


def _data_row(k: int) -> str:
    return V123.split("\n")[V123_DATA_LINE - 1 + k]


ROW2 = _data_row(2)
ROW3 = _data_row(3)
MALFORMED: dict[str, tuple[str, int, str]] = {
    "empty": ("", 1, "empty file"),
    "header only": ("\n".join(V123.split("\n")[:7]) + "\n", 8, "no data row"),
    "truncated header": ("\n".join(V123.split("\n")[:4]), 5, "truncated header"),
    "row cut short": (V123.rstrip("\n").rsplit(",", 9)[0] + "\n", 11, "expected 28 columns"),
    "non-numeric cell": (V123.replace("0.851000", "0.85l000"), 9, "'0.85l000'"),
    "extra column": (_replace_line(V123, 10, ROW2 + ",0.5"), 10, "got 29 columns"),
    "frames not increasing": (
        _replace_line(V123, 11, ROW3.replace("3,", "2,", 1)),
        11,
        "frame numbers must increase",
    ),
    "time not increasing": (
        _replace_line(V123, 11, ROW3.replace("0.025000", "0.010000", 1)),
        11,
        "time must increase",
    ),
    "time off the frame grid": (
        _replace_line(V123, 11, ROW3.replace("0.025000", "0.030000", 1)),
        11,
        "Time column says",
    ),
    "blank frame": (_replace_line(V123, 10, ROW2[1:]), 10, "blank Frame"),
    "zero-norm quaternion": (
        _replace_line(V123, 11, ROW3.replace("0.280000,0.000000,0.000000,0.960000", "0,0,0,0")),
        11,
        "zero-norm quaternion",
    ),
    "missing Name row": (_replace_line(V123, 4, None), 6, "missing header row 'Name'"),
    "missing component row": (_replace_line(V123, 6, None), 6, "Rotation/Position"),
    "unknown length unit": (
        V123.replace("Length Units,Meters", "Length Units,Furlongs"),
        1,
        "unknown length unit 'Furlongs'",
    ),
    "millimetres labelled metres": (
        V123.replace("0.128000,0.853000", "128.000000,853.000000"),
        11,
        "are these millimetres",
    ),
    "metres labelled millimetres": (
        V123.replace("Length Units,Meters", "Length Units,Millimeters"),
        1,
        "look like metres",
    ),
    "no rigid body": (
        V123.replace("Rigid Body,", "Marker,").replace(",Rigid Body\n", ",Marker\n"),
        3,
        "no rigid body",
    ),
    "euler rotation": (
        V123.replace("Rotation Type,Quaternion", "Rotation Type,XYZ"),
        1,
        "only Quaternion",
    ),
    "not motive": ("Frame,Time\n0,0\n", 1, "not a Motive CSV export"),
    "old format": (
        V123.replace("Format Version,1.23", "Format Version,1.1"),
        1,
        "unsupported Format Version",
    ),
    "no export rate": (
        V123.replace("Capture Frame Rate,120.000000,Export Frame Rate,120.000000,", ""),
        1,
        "neither Export Frame Rate",
    ),
    "header wider than data": (
        _replace_line(V123, 3, V123.split("\n")[2] + ",Marker"),
        3,
        "header row has 29 columns",
    ),
}


@pytest.mark.parametrize("case", list(MALFORMED))
def test_malformed_files_name_file_and_line(tmp_path: Path, case: str) -> None:
    text, line, fragment = MALFORMED[case]
    p = _write(tmp_path, text, "bad_take.csv")
    with pytest.raises(FormatError) as err:
        motive.read(p)
    msg = str(err.value)
    assert "bad_take.csv" in msg
    assert f"line {line}" in msg, msg
    assert fragment in msg, msg
    assert err.value.line == line


def test_malformed_cells_name_the_column_and_body(tmp_path: Path) -> None:
    with pytest.raises(FormatError) as err:
        motive.read(_write(tmp_path, V123.replace("0.851000", "0.85l000")))
    assert err.value.where == "column 8 Y"
    text = _replace_line(V123, 11, ROW3.replace("0.280000,0.000000,0.000000,0.960000", "0,0,0,0"))
    with pytest.raises(FormatError) as err:
        motive.read(_write(tmp_path, text, "zero.csv"))
    assert err.value.where == "body 'seat'"


def test_bad_options(tmp_path: Path) -> None:
    p = _write(tmp_path, V123)
    with pytest.raises(FormatError, match="kinds names bodies not in the file: chair"):
        motive.read(p, kinds={"chair": "part"})
    with pytest.raises(FormatError, match="kind must be one of"):
        motive.read(p, kinds={"seat": "furniture"})
    with pytest.raises(FormatError, match="length_units option"):
        motive.read(p, length_units="inches")
    with pytest.raises(FormatError, match="include_markers=True"):
        motive.read(_write(tmp_path, MALFORMED["no rigid body"][0], "markers.csv"))


def test_header_rows_checked_by_label_and_content(tmp_path: Path) -> None:
    twice = _replace_line(V123, 5, V123.split("\n")[3] + "\n" + V123.split("\n")[4])
    with pytest.raises(FormatError, match="'Name' appears twice") as err:
        motive.read(_write(tmp_path, twice, "twice.csv"))
    assert err.value.line == 5
    garbled = _replace_line(V121, 3, ",," + ",".join(["Thing"] * 11))
    with pytest.raises(FormatError, match="expected the Type row") as err:
        motive.read(_write(tmp_path, garbled, "garbled.csv"))
    assert err.value.line == 3
    euler = V123.replace("X,Y,Z,W,X,Y,Z,,X,Y,Z,,X,Y,Z,X", "X,Y,Z,V,X,Y,Z,,X,Y,Z,,X,Y,Z,X")
    with pytest.raises(FormatError, match="no W column") as err:
        motive.read(_write(tmp_path, euler, "euler.csv"))
    assert err.value.where == "body 'seat'" and err.value.line == 7


def test_write_refuses_what_motive_cannot_hold(tmp_path: Path, rng: np.random.Generator) -> None:
    demo = _random_demo(rng, n=20, t0=0.0, rate=120.0)
    renamed = demo.replace(
        bodies=[BodyInfo("line\nbreak") if b.name == "seat" else b for b in demo.bodies],
        tracks={
            ("line\nbreak" if n == "seat" else n): (demo.pos(n), demo.quat(n), demo.valid(n))
            for n in demo.body_names
        },
    )
    with pytest.raises(FormatError, match="line breaks"):
        motive.write(renamed, tmp_path / "x.csv")
    with pytest.raises(FormatError, match="no body"):
        motive.write(demo.select([]), tmp_path / "x.csv")
    assert not any(tmp_path.iterdir())


def test_round_trip_of_awkward_floats(tmp_path: Path) -> None:
    special = np.array([-0.0, 5e-324, 1e-300, 49.99999999999999, 1 / 3, -2.5e-17, 0.1, 7.0])
    n = special.size
    pos = np.column_stack([special, special[::-1], np.full(n, -1e-5)])
    quat = np.tile([0.0, -0.0, np.sqrt(0.5), np.sqrt(0.5)], (n, 1))
    demo = Demonstration(np.arange(n) / 30.0, [BodyInfo("b")], {"b": pos}, {"b": quat})
    p = tmp_path / "awkward.csv"
    motive.write(demo, p)
    back = motive.read(p)
    assert np.array_equal(back.pos("b"), demo.pos("b"))
    assert np.array_equal(np.signbit(back.pos("b")), np.signbit(demo.pos("b")))
    assert np.array_equal(back.quat("b"), demo.quat("b"))
    assert np.array_equal(back.t, demo.t)


def test_frames_numbered_at_the_capture_rate_of_a_downsampled_export(tmp_path: Path) -> None:
    text = V123.replace("Capture Frame Rate,120.000000", "Capture Frame Rate,240.000000")
    for k in (3, 2, 1):  # frames 0 2 4 6 at 240 Hz, times at 120 Hz
        text = text.replace(f"\n{k},0.0", f"\n{2 * k},0.0")
    demo = motive.read(_write(tmp_path, text))
    assert demo.t.tolist() == [0.0, 2 / 240, 4 / 240, 6 / 240]
    assert demo.meta["capture_frame_rate"] == 240.0


@settings(max_examples=25, deadline=None)
@given(
    pos=arrays(np.float64, (6, 3), elements=st.floats(-49.0, 49.0, allow_subnormal=True)),
    quat=arrays(
        np.float64,
        (6, 4),
        elements=st.one_of(
            st.floats(-1.0, -0.1, exclude_max=True), st.floats(0.1, 1.0, exclude_min=True)
        ),
    ),
    valid=arrays(np.bool_, 6),
    start=st.integers(-1000, 10**6),
)
def test_round_trip_property(
    pos: np.ndarray, quat: np.ndarray, valid: np.ndarray, start: int
) -> None:
    t = (start + np.arange(6)) / 120.0
    quat = quat / np.linalg.norm(quat, axis=1, keepdims=True)  # a Demonstration holds unit ones
    demo = Demonstration(t, [BodyInfo("b")], {"b": pos}, {"b": quat}, {"b": valid})
    with tempfile.TemporaryDirectory() as tmp:
        p = Path(tmp) / "prop.csv"
        motive.write(demo, p)
        back = motive.read(p)
    assert np.array_equal(back.t, demo.t)
    assert np.array_equal(back.valid("b"), demo.valid("b"))
    assert np.array_equal(back.pos("b"), demo.pos("b"), equal_nan=True)
    assert np.array_equal(back.quat("b"), demo.quat("b"), equal_nan=True)
