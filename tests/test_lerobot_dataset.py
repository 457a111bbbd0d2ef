"""The LeRobot dataset writer and reader: round trips, statistics, file layout, refusals."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from thirdhand.errors import FormatError, OptionError, OutputError, Terminated
from thirdhand.lerobot import layout
from thirdhand.lerobot.episode import Episode
from thirdhand.lerobot.reader import read_dataset
from thirdhand.lerobot.stats import column_stats, image_stats, sample_indices
from thirdhand.lerobot.writer import DatasetSettings, place_episodes, write_dataset

FPS = 15
CAM = "observation.images.wrist"


def _video(n: int, seed: int, h: int = 32, w: int = 48) -> np.ndarray:
    yy, xx = np.mgrid[0:h, 0:w]
    frames = np.empty((n, h, w, 3), dtype=np.uint8)
    for i in range(n):
        frames[i, ..., 0] = (3 * xx + 7 * i + 11 * seed) % 200 + 20
        frames[i, ..., 1] = (4 * yy + 5 * seed) % 200 + 20
        frames[i, ..., 2] = 128 + 50 * np.sin((xx - yy + 2 * i) / 8.0)
    return frames


def _episode(n: int, seed: int, *, video: bool = True, task: str = "stack") -> Episode:
    rng = np.random.default_rng(seed)
    return Episode(
        fps=FPS,
        task=task,
        features={
            "observation.state": rng.normal(size=(n, 3)),
            "action": rng.uniform(-1, 1, size=(n, 2)),
        },
        names={"observation.state": ("j1", "j2", "gripper_width"), "action": ("j1", "g")},
        videos={CAM: _video(n, seed)} if video else {},
        annotations={"annotation.phase": tuple(f"p{i // 3}" for i in range(n))},
    )


def test_round_trip(tmp_path: Path) -> None:
    eps = [_episode(5, 1), _episode(7, 2, task="insert"), _episode(4, 3)]
    summary = write_dataset(eps, tmp_path / "ds", fps=FPS, robot_type="panda")
    assert (summary.episodes, summary.frames, summary.tasks) == (3, 16, 2)
    back = read_dataset(tmp_path / "ds")
    assert back.tasks == ["stack", "insert"]
    assert back.info["total_frames"] == 16 and back.info["splits"] == {"train": "0:3"}
    for ep, got in zip(eps, back.episodes, strict=True):
        for key, arr in ep.features.items():
            np.testing.assert_array_equal(got.features[key], arr)  # float32, exact
        n = ep.n_frames
        np.testing.assert_array_equal(got.timestamps, (np.arange(n) / FPS).astype(np.float32))
        assert got.annotations["annotation.phase"] == list(ep.annotations["annotation.phase"])
        frames = got.videos[CAM]
        assert frames.shape == ep.videos[CAM].shape  # one decoded frame per row
        err = np.abs(frames.astype(float) - ep.videos[CAM]).mean()
        assert err < 6, err  # h264 at crf 30 on smooth frames: a few grey levels
        assert got.tasks == [ep.task]
    light = read_dataset(tmp_path / "ds", decode_videos=False)
    assert all(e.videos == {} for e in light.episodes)
    np.testing.assert_array_equal(light.episodes[2].features["action"], eps[2].features["action"])
    meta = pq.read_table(tmp_path / "ds/meta/episodes/chunk-000/file-000.parquet").to_pydict()
    assert meta["dataset_from_index"] == [0, 5, 12]
    assert meta["dataset_to_index"] == [5, 12, 16]
    np.testing.assert_allclose(meta[f"videos/{CAM}/from_timestamp"], [0, 5 / FPS, 12 / FPS])
    np.testing.assert_allclose(meta[f"videos/{CAM}/to_timestamp"], [5 / FPS, 12 / FPS, 16 / FPS])
    data = pq.read_table(tmp_path / "ds/data/chunk-000/file-000.parquet").to_pydict()
    assert data["index"] == list(range(16))
    assert data["episode_index"] == [0] * 5 + [1] * 7 + [2] * 4
    assert data["task_index"] == [0] * 5 + [1] * 7 + [0] * 4


def test_a_one_column_feature_is_a_scalar_column(tmp_path: Path) -> None:
    ep = Episode(
        fps=10,
        task="t",
        features={"gripper": np.arange(4.0)[:, None]},
        names={"gripper": ("width",)},
    )
    write_dataset([ep], tmp_path / "ds", fps=10, robot_type=None)
    info = json.loads((tmp_path / "ds/meta/info.json").read_text())
    assert info["features"]["gripper"] == {"dtype": "float32", "shape": [1], "names": ["width"]}
    schema = pq.read_schema(tmp_path / "ds/data/chunk-000/file-000.parquet")
    assert str(schema.field("gripper").type) == "float"  # as LeRobot's datasets.Value("float32")
    got = read_dataset(tmp_path / "ds").episodes[0].features["gripper"]
    np.testing.assert_array_equal(got, ep.features["gripper"])


def test_the_same_episodes_give_the_same_bytes(tmp_path: Path) -> None:
    """Parallel runs that hand the writer the same episodes get byte-identical datasets."""
    eps = [_episode(12, 1), _episode(9, 2, task="insert")]
    for name in ("a", "b"):
        write_dataset(eps, tmp_path / name, fps=FPS, robot_type="panda")
    files = sorted(
        p.relative_to(tmp_path / "a") for p in (tmp_path / "a").rglob("*") if p.is_file()
    )
    assert len(files) == 6
    for f in files:
        assert (tmp_path / "a" / f).read_bytes() == (tmp_path / "b" / f).read_bytes(), f


def test_statistics_are_numpys(tmp_path: Path) -> None:
    eps = [_episode(9, 4), _episode(6, 5)]
    write_dataset(eps, tmp_path / "ds", fps=FPS, robot_type=None)
    stats = json.loads((tmp_path / "ds/meta/stats.json").read_text())
    for key in ("observation.state", "action"):
        x = np.concatenate([e.features[key] for e in eps]).astype(np.float64)
        np.testing.assert_array_equal(stats[key]["min"], x.min(axis=0))
        np.testing.assert_array_equal(stats[key]["max"], x.max(axis=0))
        np.testing.assert_allclose(stats[key]["mean"], x.mean(axis=0), rtol=0, atol=1e-12)
        np.testing.assert_allclose(stats[key]["std"], x.std(axis=0), rtol=0, atol=1e-12)
        assert stats[key]["count"] == [15]
        per = [column_stats(e.features[key]) for e in eps]
        for q in ("q01", "q10", "q50", "q90", "q99"):  # count-weighted, as LeRobot aggregates
            want = (9 * per[0][q] + 6 * per[1][q]) / 15
            np.testing.assert_allclose(stats[key][q], want, rtol=0, atol=1e-12)
    pix = np.concatenate([e.videos[CAM] for e in eps]).reshape(-1, 3).astype(np.float64)
    np.testing.assert_allclose(np.ravel(stats[CAM]["mean"]), pix.mean(axis=0) / 255, atol=1e-12)
    np.testing.assert_allclose(np.ravel(stats[CAM]["std"]), pix.std(axis=0) / 255, atol=1e-12)
    assert np.shape(stats[CAM]["mean"]) == (3, 1, 1) and stats[CAM]["count"] == [15]
    ts = np.concatenate([np.arange(9), np.arange(6)]) / FPS
    np.testing.assert_allclose(stats["timestamp"]["mean"], [ts.mean()], atol=1e-12)
    assert stats["index"]["max"] == [14] and stats["episode_index"]["min"] == [0]
    assert "annotation.phase" not in stats  # text has no statistics, as in LeRobot


def test_quantiles_recover_a_known_distribution() -> None:
    # 2001 evenly spaced values on [0, 1]: the q-quantile is q, within one value's spacing
    # and one of the 5000 histogram bins.
    x = np.linspace(0.0, 1.0, 2001)[:, None]
    s = column_stats(x)
    for key, q in (("q01", 0.01), ("q10", 0.1), ("q50", 0.5), ("q90", 0.9), ("q99", 0.99)):
        assert abs(s[key][0] - q) <= 1 / 2000 + 1 / 5000, (key, s[key])
    one = column_stats(np.array([[2.0, 3.0]]))  # one frame: every quantile is the mean
    np.testing.assert_array_equal(one["q50"], [2.0, 3.0])


def test_image_sampling_and_downsampling() -> None:
    assert sample_indices(10).tolist() == list(range(10))
    idx = sample_indices(1000)
    assert idx.size == 177 and idx[0] == 0 and idx[-1] == 999  # LeRobot's documented count
    big = np.zeros((2, 320, 480, 3), dtype=np.uint8)
    big[:, ::3, ::3, 0] = 255  # every third pixel: the only ones kept when subsampling by 3
    s = image_stats(big)
    assert s["mean"][0, 0, 0] == 1.0 and s["mean"][1, 0, 0] == 0.0


def test_files_roll_over_by_size_and_chunk(tmp_path: Path) -> None:
    tiny = DatasetSettings(chunks_size=2, data_files_size_in_mb=1e-6, video_files_size_in_mb=1e-6)
    eps = [_episode(3 + i, 10 + i) for i in range(5)]
    s = write_dataset(eps, tmp_path / "ds", fps=FPS, robot_type="panda", settings=tiny)
    assert (s.data_files, s.video_files) == (5, 5)
    files = sorted(
        p.relative_to(tmp_path / "ds").as_posix() for p in (tmp_path / "ds").rglob("*.*")
    )
    for c, f in ((0, 0), (0, 1), (1, 0), (1, 1), (2, 0)):
        assert layout.DATA_PATH.format(chunk_index=c, file_index=f) in files
        assert layout.VIDEO_PATH.format(video_key=CAM, chunk_index=c, file_index=f) in files
    parts = sorted((tmp_path / "ds/meta/episodes").rglob("*.parquet"))
    assert len(parts) == 5  # the episodes metadata rolls over by the data size limit too
    rows = [r for part in parts for r in pq.read_table(part).to_pylist()]
    meta = {k: [r[k] for r in rows] for k in rows[0]}
    assert meta["meta/episodes/chunk_index"] == [0, 0, 1, 1, 2]
    assert meta["data/chunk_index"] == [0, 0, 1, 1, 2]
    assert meta["data/file_index"] == [0, 1, 0, 1, 0]
    assert meta[f"videos/{CAM}/from_timestamp"] == [0.0] * 5  # each video file starts anew
    back = read_dataset(tmp_path / "ds")
    for ep, got in zip(eps, back.episodes, strict=True):
        np.testing.assert_array_equal(got.features["action"], ep.features["action"])
        assert got.videos[CAM].shape[0] == ep.n_frames


def test_placement_is_lerobots_rule() -> None:
    mb = 1024**2
    s = DatasetSettings(chunks_size=1000, data_files_size_in_mb=10, video_files_size_in_mb=10)
    # data: 4 MB per 10 rows; the third episode would bring the file to 12 MB >= 10.
    p = place_episodes(
        [10, 10, 10], [4 * mb] * 3, {"cam": [3 * mb, 6 * mb, 2 * mb]}, fps=10, settings=s
    )
    assert p.data == [(0, 0), (0, 0), (0, 1)]
    # video: 3 + 6 < 10 stays; 9 + 2 >= 10 starts file 1 at time 0.
    assert p.videos["cam"] == [(0, 0, 0.0), (0, 0, 1.0), (0, 1, 0.0)]
    assert layout.next_file(0, 998, 1000) == (0, 999)
    assert layout.next_file(0, 999, 1000) == (1, 0)


def test_existing_folder_refused_then_replaced_with_force(tmp_path: Path) -> None:
    target = tmp_path / "ds"
    write_dataset([_episode(4, 1, video=False)], target, fps=FPS, robot_type=None)
    with pytest.raises(OutputError, match="exists; pass --force") as err:
        write_dataset([_episode(6, 2, video=False)], target, fps=FPS, robot_type=None)
    assert "\n" not in str(err.value)
    assert read_dataset(target).info["total_frames"] == 4
    write_dataset([_episode(6, 2, video=False)], target, fps=FPS, robot_type=None, force=True)
    assert read_dataset(target).info["total_frames"] == 6
    assert read_dataset(tmp_path / "ds.bak").info["total_frames"] == 4
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep")
    with pytest.raises(OutputError, match="holds no recording"):
        write_dataset([_episode(3, 1)], tmp_path / "mine", fps=FPS, robot_type=None, force=True)


def _stopped(exc: BaseException, n_done: int):  # type: ignore[no-untyped-def]
    for i in range(n_done):
        yield _episode(4 + i, i)
    raise exc


@pytest.mark.parametrize("exc", [RuntimeError("simulation failed"), KeyboardInterrupt()])
def test_interrupted_writer_leaves_nothing_without_keep_finished(
    tmp_path: Path, exc: BaseException
) -> None:
    with pytest.raises(type(exc)):
        write_dataset(
            _stopped(exc, 2), tmp_path / "ds", fps=FPS, robot_type=None, keep_finished=False
        )
    assert os.listdir(tmp_path) == []  # no target, no temporary folder


def test_error_mid_run_leaves_nothing_even_with_keep_finished(tmp_path: Path) -> None:
    with pytest.raises(RuntimeError):
        write_dataset(_stopped(RuntimeError("x"), 2), tmp_path / "ds", fps=FPS, robot_type=None)
    assert os.listdir(tmp_path) == []


def test_ctrl_c_keeps_the_finished_episodes(tmp_path: Path) -> None:
    with pytest.raises(KeyboardInterrupt):
        write_dataset(_stopped(KeyboardInterrupt(), 2), tmp_path / "ds", fps=FPS, robot_type=None)
    back = read_dataset(tmp_path / "ds")
    assert [e.features["action"].shape[0] for e in back.episodes] == [4, 5]
    assert os.listdir(tmp_path) == ["ds"]
    with pytest.raises(KeyboardInterrupt):  # interrupted before any episode: nothing
        write_dataset(_stopped(KeyboardInterrupt(), 0), tmp_path / "d2", fps=FPS, robot_type=None)
    assert os.listdir(tmp_path) == ["ds"]


def test_sigterm_keeps_the_finished_episodes(tmp_path: Path) -> None:
    with pytest.raises(Terminated):
        write_dataset(_stopped(Terminated(), 3), tmp_path / "ds", fps=FPS, robot_type=None)
    assert read_dataset(tmp_path / "ds").info["total_episodes"] == 3


def test_an_episode_cut_short_is_not_counted(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Ctrl-C while the third episode's video is encoded: its rows are already on disk."""
    from thirdhand.lerobot import video

    encode = video.encode_frames
    calls = []

    def stop_on_third(frames: np.ndarray, path: Path, *, fps: int) -> None:
        calls.append(path)
        if len(calls) == 3:
            path.write_bytes(b"half a video")
            raise KeyboardInterrupt
        encode(frames, path, fps=fps)

    monkeypatch.setattr(video, "encode_frames", stop_on_third)
    eps = [_episode(4, 1), _episode(5, 2), _episode(6, 3)]
    with pytest.raises(KeyboardInterrupt):
        write_dataset(eps, tmp_path / "ds", fps=FPS, robot_type=None)
    monkeypatch.setattr(video, "encode_frames", encode)
    back = read_dataset(tmp_path / "ds")
    assert back.info["total_frames"] == 9 and len(back.episodes) == 2
    for ep, got in zip(eps, back.episodes, strict=False):
        np.testing.assert_array_equal(
            got.features["observation.state"], ep.features["observation.state"]
        )
        assert got.videos[CAM].shape[0] == ep.n_frames
    assert os.listdir(tmp_path) == ["ds"]


def test_zero_episodes_is_one_line(tmp_path: Path) -> None:
    with pytest.raises(OptionError, match="no episode to write") as err:
        write_dataset([], tmp_path / "ds", fps=FPS, robot_type=None)
    assert "\n" not in str(err.value) and os.listdir(tmp_path) == []


def _kw(**change: object) -> dict[str, object]:
    kw: dict[str, object] = {
        "fps": 10,
        "task": "t",
        "features": {"s": np.zeros((4, 2))},
        "names": {"s": ("a", "b")},
    }
    kw.update(change)
    return kw


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"fps": 0}, "fps must be positive"),
        ({"fps": 2.5}, "whole number"),
        ({"task": " "}, "task text is empty"),
        ({"features": {}}, "no feature"),
        ({"features": {"s": np.zeros(4)}}, "shape \\(n_frames, n\\)"),
        ({"features": {"s": np.array([[0, 1], [np.nan, 1]])}}, "frame 1 column 0 is not finite"),
        ({"names": {"s": ("a",)}}, "2 columns but 1 names"),
        ({"names": {"s": ("a", "a")}}, "unique"),
        ({"features": {"a/b": np.zeros((4, 2))}, "names": {"a/b": ("a", "b")}}, "contains '/'"),
        (
            {"features": {"index": np.zeros((4, 2))}, "names": {"index": ("a", "b")}},
            "LeRobot's own",
        ),
        ({"videos": {"cam": np.zeros((4, 5, 6, 3), np.uint8)}}, "must be even"),
        ({"videos": {"cam": np.zeros((3, 4, 6, 3), np.uint8)}}, "3 frames, the other features 4"),
        ({"videos": {"cam": np.zeros((4, 4, 6, 3))}}, "must be uint8"),
        ({"annotations": {"p": ("x",) * 3}}, "3 frames"),
    ],
)
def test_bad_episode_is_one_line(change: dict[str, object], message: str) -> None:
    with pytest.raises(OptionError, match=message) as err:
        Episode(**_kw(**change))  # type: ignore[arg-type]
    assert "\n" not in str(err.value)


def test_episodes_that_disagree_are_refused(tmp_path: Path) -> None:
    other = Episode(**_kw(names={"s": ("a", "c")}))  # type: ignore[arg-type]
    with pytest.raises(OptionError, match=r"episode 1: .*differ") as err:
        write_dataset([Episode(**_kw()), other], tmp_path / "ds", fps=10, robot_type=None)  # type: ignore[arg-type]
    assert "\n" not in str(err.value) and os.listdir(tmp_path) == []
    with pytest.raises(OptionError, match="12 frames per second, the dataset 10"):
        write_dataset([Episode(**_kw(fps=12))], tmp_path / "ds", fps=10, robot_type=None)  # type: ignore[arg-type]


def _tamper(root: Path, **changes: object) -> None:
    info = json.loads((root / layout.INFO_PATH).read_text())
    info.update(changes)
    (root / layout.INFO_PATH).write_text(json.dumps(info))


def test_reader_refuses_inconsistent_datasets(tmp_path: Path) -> None:
    root = tmp_path / "ds"
    write_dataset([_episode(5, 1), _episode(3, 2)], root, fps=FPS, robot_type=None)
    _tamper(root, total_frames=9)
    with pytest.raises(FormatError, match="total_frames is 9 but the files hold 8") as err:
        read_dataset(root)
    assert "\n" not in str(err.value)
    _tamper(root, total_frames=8, total_episodes=3)
    with pytest.raises(FormatError, match="total_episodes is 3 but the files hold 2"):
        read_dataset(root)
    _tamper(root, total_episodes=2, fps=FPS * 2)
    with pytest.raises(FormatError, match="timestamps are not frame_index"):
        read_dataset(root)
    _tamper(root, fps=FPS, codebase_version="v2.1")
    with pytest.raises(FormatError, match=r"expected codebase_version 'v3\.0'"):
        read_dataset(root)
    _tamper(root, codebase_version="v3.0")
    read_dataset(root)
    video = root / layout.VIDEO_PATH.format(video_key=CAM, chunk_index=0, file_index=0)
    short = tmp_path / "short.mp4"
    from thirdhand.lerobot.video import encode_frames

    encode_frames(_video(6, 1), short, fps=FPS)  # two frames fewer than the 8 rows
    os.replace(short, video)
    for decode in (True, False):  # the times are checked even when no frame is kept
        with pytest.raises(FormatError, match="no video frame within") as err:
            read_dataset(root, decode_videos=decode)
        assert "\n" not in str(err.value) and "(episode 1): no video frame" in str(err.value)
