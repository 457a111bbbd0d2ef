"""thirdhand's LeRobot writer against a dataset written by lerobot 0.4.4 itself.

``tests/data/lerobot_reference/dataset`` was made once by LeRobot's own
``LeRobotDataset.create`` / ``add_frame`` / ``save_episode`` / ``finalize``
(``make.py`` beside it says how). The same frames written by thirdhand must
give the same ``meta/info.json``, the same parquet columns and arrow types, the
same episode metadata and the same statistics. The differences that remain,
each checked below by name:

- ``std`` of the video frames: LeRobot 0.4.4 squares uint8 pixels in uint8
  (``RunningQuantileStats.update``), the square wraps at 256 and its std is
  wrong (here 0 in two channels); thirdhand writes the pixels' true std.
- Numeric statistics agree to float32 rounding: LeRobot accumulates float32
  features in float32, thirdhand in float64.
- Parquet schema metadata: LeRobot's ``huggingface`` block carries a
  ``fingerprint`` of its cache; ``tasks.parquet``'s ``pandas`` block names the
  pandas version that wrote it. Neither is read back by LeRobot.
- Video bytes: both are h264 / yuv420p at 10 fps from libx264 (``-g 2 -crf 30``), but
  through different ffmpeg builds; the files differ in bytes, not in frame count or times.
"""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path
from types import ModuleType

import numpy as np
import pyarrow.parquet as pq
import pytest

from thirdhand.lerobot.episode import Episode
from thirdhand.lerobot.reader import read_dataset
from thirdhand.lerobot.video import probe
from thirdhand.lerobot.writer import write_dataset

HERE = Path(__file__).resolve().parent / "data" / "lerobot_reference"
REF = HERE / "dataset"
FILES = (
    "data/chunk-000/file-000.parquet",
    "meta/tasks.parquet",
    "meta/episodes/chunk-000/file-000.parquet",
)


def _make() -> ModuleType:
    spec = importlib.util.spec_from_file_location("lerobot_reference_make", HERE / "make.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def ours(tmp_path_factory: pytest.TempPathFactory) -> Path:
    ref = _make()
    episodes = [
        Episode(
            fps=ref.FPS,
            task=e["task"],
            features={"observation.state": e["state"], "action": e["action"]},
            names={"observation.state": ref.STATE_NAMES, "action": ref.ACTION_NAMES},
            videos={ref.CAMERA: e["video"]},
        )
        for e in ref.reference_episodes()
    ]
    root = tmp_path_factory.mktemp("ours") / "dataset"
    write_dataset(episodes, root, fps=ref.FPS, robot_type="panda")
    return root


def _json(root: Path, name: str) -> dict:  # type: ignore[type-arg]
    return json.loads((root / "meta" / name).read_text())


def test_info_json_is_lerobots(ours: Path) -> None:
    # Every key, feature (dtype, shape, names, video info), template and total.
    assert _json(ours, "info.json") == _json(REF, "info.json")


@pytest.mark.parametrize("name", FILES)
def test_parquet_columns_and_types_are_lerobots(ours: Path, name: str) -> None:
    a, b = pq.read_schema(ours / name), pq.read_schema(REF / name)
    assert a.remove_metadata().equals(b.remove_metadata()), f"{a}\n!=\n{b}"
    assert set(a.metadata or {}) == set(b.metadata or {})
    if b"huggingface" in (b.metadata or {}):
        ha = json.loads(a.metadata[b"huggingface"])["info"]["features"]
        hb = json.loads(b.metadata[b"huggingface"])["info"]["features"]
        assert ha == hb  # only the fingerprint differs
    if b"pandas" in (b.metadata or {}):
        pa_, pb = (json.loads(s.metadata[b"pandas"]) for s in (a, b))
        assert pa_["index_columns"] == pb["index_columns"]
        assert [c["field_name"] for c in pa_["columns"]] == [c["field_name"] for c in pb["columns"]]
    assert pq.ParquetFile(ours / name).metadata.row_group(0).column(0).compression == "SNAPPY"


def test_rows_are_lerobots(ours: Path) -> None:
    for name in FILES[:2]:
        assert pq.read_table(ours / name).to_pydict() == pq.read_table(REF / name).to_pydict()
    a = pq.read_table(ours / FILES[2]).to_pydict()
    b = pq.read_table(REF / FILES[2]).to_pydict()
    assert list(a) == list(b)
    for key in b:
        if not key.startswith("stats/"):
            assert a[key] == b[key], key
        else:
            _close(key, a[key], b[key], b.get(key.replace("/std", "/mean")))


EPS32 = float(np.finfo(np.float32).eps)


def _close(key: str, a: object, b: object, mean: object = None) -> None:
    x, y = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    assert x.shape == y.shape, key
    if key.startswith("stats/observation.images") and key.endswith("/std"):
        assert np.all(x > 0.1)  # the true spread of the test pattern's pixels
        assert np.all(y < x)  # LeRobot 0.4.4's wrapped uint8 square (see the module doc)
        return
    if key.endswith("/std"):
        # LeRobot's float32 variance, mean(x^2) - mean^2, is exact to a few float32 ulps of
        # mean(x^2) = mean^2 + std^2: compare variances to that bound.
        m = np.asarray(mean, dtype=float)
        bound = 8 * EPS32 * (m**2 + y**2)
        assert np.all(np.abs(x**2 - y**2) <= bound), (key, x, y)
        return
    np.testing.assert_allclose(x, y, rtol=2e-6, atol=1e-7, err_msg=key)


def test_stats_json_is_lerobots(ours: Path) -> None:
    a, b = _json(ours, "stats.json"), _json(REF, "stats.json")
    assert set(a) == set(b)
    for feature in b:
        assert list(a[feature]) == list(b[feature])
        for stat in b[feature]:
            key = f"stats/{feature}/{stat}"
            _close(key, a[feature][stat], b[feature][stat], b[feature]["mean"])
    pix = np.concatenate([e["video"] for e in _make().reference_episodes()]).reshape(-1, 3)
    np.testing.assert_allclose(
        np.ravel(a["observation.images.front"]["std"]), pix.std(axis=0) / 255, atol=1e-12
    )


def test_videos_have_lerobots_frames_and_times(ours: Path) -> None:
    key = "videos/observation.images.front/chunk-000/file-000.mp4"
    pa_, pb = probe(ours / key), probe(REF / key)
    assert (pa_.codec, pa_.pix_fmt, pa_.width, pa_.height) == (pb.codec, pb.pix_fmt, 64, 48)
    np.testing.assert_allclose(pa_.pts, pb.pts, atol=1e-9)


def test_reader_reads_lerobots_dataset_and_ours_alike(ours: Path) -> None:
    a, b = read_dataset(ours), read_dataset(REF)
    assert a.tasks == b.tasks
    ref = _make().reference_episodes()
    for ea, eb, frames in zip(a.episodes, b.episodes, ref, strict=True):
        for key in ("observation.state", "action"):
            np.testing.assert_array_equal(ea.features[key], eb.features[key])
        np.testing.assert_array_equal(ea.timestamps, eb.timestamps)
        va, vb = ea.videos["observation.images.front"], eb.videos["observation.images.front"]
        assert va.shape == vb.shape == frames["video"].shape
        for v in (va, vb):  # both decode to the frames given, up to h264 at crf 30
            assert np.abs(v.astype(float) - frames["video"]).mean() < 8
