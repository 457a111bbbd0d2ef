"""Articulated-object track files (tum-vision/articulation): real files, round trips, errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from thirdhand import io
from thirdhand.demonstration import BodyInfo, Demonstration
from thirdhand.errors import FormatError
from thirdhand.io import articulation
from thirdhand.se3 import random_quat


def _all_files(root: Path) -> list[Path]:
    folder = root / "articulation"
    return sorted([*folder.glob("*.txt"), *folder.rglob("*.log")])


def test_every_real_file_loads(shared_data: Path) -> None:
    files = _all_files(shared_data)
    assert len(files) == 53  # the shared track files (data README): 2 .txt, 51 .log
    for f in files:
        assert articulation.sniff(f), f
        demo = articulation.read(f)
        raw = np.loadtxt(f)
        assert demo.body_names == [f.stem]
        assert demo.n_frames == raw.shape[0]
        np.testing.assert_array_equal(demo.pos(f.stem), raw[:, :3])
        assert demo.rate == pytest.approx(articulation.DEFAULT_RATE_HZ)
        assert demo.meta["rate_assumed"] is True
        assert demo.meta["rate_hz"] == articulation.DEFAULT_RATE_HZ
        oriented = raw.shape[1] == 9
        assert demo.info(f.stem).oriented is oriented
        assert demo.valid(f.stem).all()
        if oriented:
            q = raw[:, 3:7] / np.linalg.norm(raw[:, 3:7], axis=1, keepdims=True)
            np.testing.assert_allclose(demo.quat(f.stem), q, rtol=0, atol=1e-15)
            assert demo.meta["width"] == raw[:, 7].tolist()
            assert demo.meta["height"] == raw[:, 8].tolist()
        else:
            np.testing.assert_array_equal(
                demo.quat(f.stem), np.tile([0, 0, 0, 1.0], (raw.shape[0], 1))
            )
            assert "width" not in demo.meta
    position_only = [f for f in files if not articulation.read(f).info(f.stem).oriented]
    # Every .log is position-only (cabinet_one, drawer_one, cabinet_two, second_set/*).
    assert {f.suffix for f in position_only} == {".log"}
    assert len(position_only) == 51


def test_rate_option_sets_time_axis(shared_data: Path) -> None:
    demo = articulation.read(shared_data / "articulation" / "drawer.txt", rate=30.0)
    np.testing.assert_array_equal(demo.t, np.arange(19) / 30.0)
    assert demo.meta["rate_assumed"] is False
    with pytest.raises(FormatError, match="rate must be a positive"):
        articulation.read(shared_data / "articulation" / "drawer.txt", rate=0.0)


def test_real_files_round_trip_exactly(shared_data: Path, tmp_path: Path) -> None:
    for f in _all_files(shared_data):
        demo = articulation.read(f)
        out = tmp_path / f.parent.name / f.name
        out.parent.mkdir(exist_ok=True)
        articulation.write(demo, out)
        back = articulation.read(out)
        assert back.equals(demo), f
        assert back.bodies == demo.bodies
        assert back.meta.get("width") == demo.meta.get("width")
        assert back.meta.get("height") == demo.meta.get("height")


def test_synthetic_round_trip_with_gaps(rng: np.random.Generator, tmp_path: Path) -> None:
    n = 40
    valid = rng.random(n) > 0.25
    for oriented in (True, False):
        body = BodyInfo("handle", "part", oriented=oriented)
        demo = Demonstration(
            np.arange(n) / 10.0,
            [body],
            {"handle": rng.normal(size=(n, 3))},
            {"handle": random_quat(rng, n)},
            {"handle": valid},
        )
        path = tmp_path / "handle.log"
        articulation.write(demo, path)
        back = articulation.read(path)
        assert back.equals(demo)
        np.testing.assert_array_equal(back.valid("handle"), valid)
        assert len(path.read_text().splitlines()[0].split()) == (7 if oriented else 3)


def test_write_refuses_several_bodies(rng: np.random.Generator, tmp_path: Path) -> None:
    bodies = [BodyInfo("a"), BodyInfo("b")]
    demo = Demonstration(
        [0.0, 1.0],
        bodies,
        {b.name: rng.normal(size=(2, 3)) for b in bodies},
        {b.name: random_quat(rng, 2) for b in bodies},
    )
    with pytest.raises(FormatError, match=r"holds one body.*has 2"):
        articulation.write(demo, tmp_path / "x.txt")


@pytest.mark.parametrize(
    ("text", "line", "pattern"),
    [
        ("", None, "empty file"),
        ("\n  \n", None, "empty file"),
        ("1 2 3\n4 five 6\n", 2, "'five' is not a number"),
        ("1 2 3\n4 5 6 7\n", 2, "expected 3 numbers per row .*got 4"),
        ("1 2 3 4 5 6\n", 1, "expected 3 or 7 or 9 numbers per row, got 6"),
        ("0.1 0.2 0.3 0 0 0 1\n0.1 0.2 0.3 0 0 0 0\n", 2, "zero-norm quaternion"),
        ("0.1 0.2 0.3\n120.5 -340 1200\n", 2, "millimetres"),
        ("0.1 0.2 0.3\nnan 0.2 0.3\n", 2, "all numbers or all nan"),
    ],
)
def test_malformed_files(tmp_path: Path, text: str, line: int | None, pattern: str) -> None:
    path = tmp_path / "track.txt"
    path.write_text(text)
    with pytest.raises(FormatError, match=pattern) as err:
        articulation.read(path)
    assert err.value.line == line
    assert "track.txt" in str(err.value)


def test_sniff(tmp_path: Path) -> None:
    cases = {
        "a.txt": ("\n1 2 3\n", True),
        "b.log": ("1 2 3 4 5 6 7\n", True),
        "c.txt": ("1 2 3 4 5 6 7 8 9\n", True),
        "d.txt": ("1 2 3 4\n", False),
        "e.txt": ("x y z\n1 2 3\n", False),
        "f.csv": ("1 2 3\n", False),
        "g.txt": ("", False),
    }
    for name, (text, expected) in cases.items():
        (tmp_path / name).write_text(text)
        assert articulation.sniff(tmp_path / name) is expected, name


def test_registry_detects_and_saves(shared_data: Path, tmp_path: Path) -> None:
    for name in io.FORMATS:
        try:
            io.format_module(name)
        except ModuleNotFoundError:
            pytest.skip(f"format module {name!r} not in the tree yet")
    door = shared_data / "articulation" / "door.txt"
    assert io.detect(door) == "articulation"
    assert io.detect(shared_data / "articulation" / "cabinet_one" / "001.log") == "articulation"
    demo = io.load(door)
    io.save(demo, tmp_path / "door.txt")
    assert io.load(tmp_path / "door.txt").equals(demo)
