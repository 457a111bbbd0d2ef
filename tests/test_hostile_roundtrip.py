"""Round trips: every writable format carries a recording exactly, or ``convert`` refuses.

Exactly: bodies and their kinds, frame times and label times to the
nanosecond (labels not snapped onto frames), the meta (part geometry), poses to
the precision of the format's numbers. A format that cannot is named with what
it would lose, and nothing is written unless ``--lossy``; whatever ``convert``
writes, ``info`` reads back.
"""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cli_helpers import call
from thirdhand import BodyInfo, Demonstration, io, se3
from thirdhand.demonstration import InteractionInterval, Labels
from thirdhand.errors import OutputError
from thirdhand.io.roundtrip import losses
from thirdhand.segment.pipeline import segment_demonstration
from thirdhand.synth import make_scene

#: Every writable recording format, by the name ``convert`` writes it under.
TARGETS = {
    "native": "r.parquet",
    "motive": "r.csv",
    "c3d": "r.c3d",
    "rosbag-mcap": "r.mcap",
    "rosbag-bag": "r.bag",
    "mlr": "r_mlr",
}


def demo_of(label_times: list[tuple[float, float]], *, n: int = 90, seed: int = 0) -> Demonstration:
    """Three bodies at 120 Hz with labels off the frame grid and part geometry in ``meta``."""
    rng = np.random.default_rng(seed)
    bodies = [BodyInfo("rh_index", "finger", "right"), BodyInfo("seat"), BodyInfo("leg")]
    t = np.arange(n) / 120.0
    labels = Labels(
        interactions=tuple(
            InteractionInterval("rh_index", "seat", float(a), float(b)) for a, b in label_times
        )
    )
    meta = {
        "units": "m",
        "geometry": {
            "seat": {"bbox_min_m": [-0.15, -0.01, -0.15], "bbox_max_m": [0.15, 0.01, 0.15]}
        },
        "scene": "test",
    }
    return Demonstration(
        t,
        bodies,
        {b.name: rng.uniform(-1.0, 1.0, (n, 3)) for b in bodies},
        {b.name: se3.random_quat(rng, n) for b in bodies},
        labels=labels,
        meta=meta,
    )


def _path(folder: Path, name: str, tag: str) -> Path:
    return folder / f"{tag}-{name}"


@pytest.fixture(scope="module")
def sources(tmp_path_factory: pytest.TempPathFactory) -> tuple[Demonstration, dict[str, Path]]:
    """One recording (labels 0.3 ms off the frames) written in every format."""
    folder = tmp_path_factory.mktemp("sources")
    demo = demo_of([(0.1003, 0.4017), (0.5, 0.61)])
    return demo, {fmt: _written(demo, _path(folder, name, "src")) for fmt, name in TARGETS.items()}


def _written(demo: Demonstration, path: Path) -> Path:
    io.save(demo, path)
    return path


@pytest.mark.parametrize(("src", "dst"), list(itertools.product(TARGETS, TARGETS)))
def test_every_format_pair_carries_or_refuses(
    src: str,
    dst: str,
    sources: tuple[Demonstration, dict[str, Path]],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    demo, paths = sources
    source = paths[src]
    assert losses(demo, io.load(source)) == [], f"{src} does not carry the recording"
    target = _path(tmp_path, TARGETS[dst], "dst")
    rc, _out, err = call(capsys, "convert", str(source), str(target))
    assert rc == 0, err
    rc, out, err = call(capsys, "info", str(target), "--json")
    assert rc == 0, err
    assert json.loads(out)["n_frames"] == demo.n_frames
    assert losses(demo, io.load(target)) == []


def test_the_synthetic_chair_through_csv_and_mlr_segments_alike(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The CSV and MLR copies keep the part boxes: segmentation labels every pair alike."""
    demo = make_scene("chair", seed=0)
    src = tmp_path / "chair.parquet"
    io.save(demo, src)
    reference = segment_demonstration(demo).to_dict()
    for name in ("chair.csv", "chair_mlr"):
        rc, _out, err = call(capsys, "convert", str(src), str(tmp_path / name))
        assert rc == 0, err
        copy = io.load(tmp_path / name)
        assert copy.meta["geometry"] == demo.meta["geometry"]
        assert copy.labels == demo.labels
        assert segment_demonstration(copy).to_dict() == reference


@settings(
    max_examples=15,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(
    times=st.lists(
        st.tuples(st.floats(0.0, 0.3, allow_nan=False), st.floats(0.0, 0.4, allow_nan=False)).map(
            lambda ab: (ab[0], ab[0] + ab[1] + 1e-3)
        ),
        min_size=1,
        max_size=4,
    ),
    fmt=st.sampled_from(sorted(TARGETS)),
)
def test_label_times_come_back_to_the_nanosecond(
    times: list[tuple[float, float]], fmt: str, tmp_path_factory: pytest.TempPathFactory
) -> None:
    demo = demo_of(times)
    path = _path(tmp_path_factory.mktemp("rt"), TARGETS[fmt], "h")
    io.save(demo, path)
    assert losses(demo, io.load(path)) == []


@pytest.mark.parametrize("name", ["s.parquet", "o.mcap"])
def test_meta_no_file_can_hold_is_named_and_nothing_written(name: str, tmp_path: Path) -> None:
    """Meta with a NaN in it is not JSON: no format carries it, so every writer names it
    in one line and leaves nothing behind."""
    demo = demo_of([(0.1003, 0.4017)])
    demo = demo.replace(meta={**demo.meta, "offset": float("nan")})
    with pytest.raises(OutputError, match=r"\$\.meta\.offset = nan") as err:
        io.save(demo, tmp_path / name)
    assert "\n" not in str(err.value)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("name", ["o.csv", "o.c3d", "o.txt"])
def test_what_its_own_reader_refuses_is_never_written(
    name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A position-only body, a rate that changes: refused in one line, nothing left."""
    n = 50
    t = np.concatenate([np.arange(25) / 100, 0.25 + np.arange(25) / 50])
    rng = np.random.default_rng(0)
    demo = Demonstration(
        t,
        [BodyInfo("o", oriented=False)],
        {"o": rng.uniform(-1.0, 1.0, (n, 3))},
        {"o": np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))},
    )
    src = tmp_path / "s.parquet"
    io.save(demo, src)
    rc, _out, err = call(capsys, "convert", str(src), str(tmp_path / name), "--lossy")
    assert rc == 1 and err.count("\n") == 1, err
    assert ".tmp" not in err
    assert not (tmp_path / name).exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.parquet"]
