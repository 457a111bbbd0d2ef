"""Read a LeRobot dataset (v3.0) back the way LeRobot reads it, checking it on the way.

``meta/info.json`` gives the path templates and features; ``meta/episodes/``
says where each episode's rows and video frames lie; the rows come from the
``data/`` parquet files and each video frame is decoded from its MP4 file at
``from_timestamp + timestamp`` (within LeRobot's tolerance of 1e-4 s). Every
total of ``info.json`` is checked against the files, and any disagreement is
one :class:`~thirdhand.errors.FormatError` line naming the file.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq
from numpy.typing import NDArray

from thirdhand.errors import FormatError
from thirdhand.lerobot import layout, video
from thirdhand.readlimits import check_regular, open_input, read_json

#: LeRobot's default tolerance between a frame's timestamp and its video frame, seconds.
TOLERANCE_S = 1e-4
#: Largest parquet or MP4 file read, bytes (LeRobot's own limits are 100 and 200 MB).
MAX_FILE_BYTES = 4 * 2**30


@dataclass(frozen=True)
class ReadEpisode:
    """One episode as read back.

    Attributes
    ----------
    index : int
        ``episode_index``.
    tasks : list of str
        Its tasks (``meta/episodes``).
    timestamps : ndarray of float32, shape (n_frames,), seconds
    features : dict str -> ndarray of float32, shape (n_frames, n)
    videos : dict str -> ndarray of uint8, shape (n_frames, height, width, 3)
        Each row's video frame (empty when read without ``decode_videos``).
    annotations : dict str -> list of str
    """

    index: int
    tasks: list[str]
    timestamps: NDArray[np.float32]
    features: dict[str, NDArray[np.float32]]
    videos: dict[str, NDArray[np.uint8]]
    annotations: dict[str, list[str]]


@dataclass(frozen=True)
class LeRobotDataset:
    """A whole dataset as read back: metadata and every episode."""

    root: Path
    info: dict[str, Any]
    stats: dict[str, dict[str, Any]]
    tasks: list[str]
    episodes: list[ReadEpisode]


def _parquet(path: Path) -> pa.Table:
    try:
        with open_input(path, what="parquet file", limit=MAX_FILE_BYTES) as fh:
            return pq.read_table(fh)
    except (pa.ArrowInvalid, OSError) as exc:
        raise FormatError(path, f"not a readable parquet file: {exc}") from None


def _folder_tables(root: Path, sub: str) -> pa.Table:
    files = sorted((root / sub).glob("chunk-*/file-*.parquet"))
    if not files:
        raise FormatError(root / sub, "holds no chunk-*/file-*.parquet file")
    return pa.concat_tables([_parquet(f) for f in files], promote_options="default")


def read_dataset(root: str | os.PathLike[str], *, decode_videos: bool = True) -> LeRobotDataset:
    """Every episode of the dataset at ``root``, checked against ``meta/info.json``.

    Parameters
    ----------
    root : path-like
        The dataset folder.
    decode_videos : bool
        Return every row's video frame. Without it, the videos are still
        decoded once to check that every row has a frame at its time, but no
        frame is kept (``ReadEpisode.videos`` is empty): the check of a large
        dataset in little memory.

    Raises
    ------
    FormatError
        A file is missing or unreadable, a total or an index disagrees, a
        timestamp is not ``frame_index / fps``, or a video has no frame at a
        row's time.
    """
    base = Path(root)
    info_path = base / layout.INFO_PATH
    info = read_json(info_path, what="LeRobot info.json")
    if not isinstance(info, dict) or info.get("codebase_version") != layout.CODEBASE_VERSION:
        got = info.get("codebase_version") if isinstance(info, dict) else type(info).__name__
        raise FormatError(info_path, f"expected codebase_version 'v3.0', got {got!r}")
    try:
        fps = int(info["fps"])
        features: dict[str, dict[str, Any]] = info["features"]
        data_path: str = info["data_path"]
        video_path: str | None = info.get("video_path")
        totals = {k: int(info[k]) for k in ("total_episodes", "total_frames", "total_tasks")}
    except (KeyError, TypeError, ValueError) as exc:
        raise FormatError(info_path, f"missing or bad entry {exc}") from None
    stats = read_json(base / layout.STATS_PATH, what="LeRobot stats.json")
    tasks_table = _parquet(base / layout.TASKS_PATH)
    tasks = _tasks(tasks_table, base / layout.TASKS_PATH)
    episodes_meta = _folder_tables(base, "meta/episodes").to_pylist()
    _agree(info_path, "total_tasks", totals["total_tasks"], len(tasks))
    _agree(info_path, "total_episodes", totals["total_episodes"], len(episodes_meta))
    cams = [k for k, v in features.items() if v.get("dtype") == "video"]
    if cams and not video_path:
        raise FormatError(info_path, f"video features {', '.join(cams)} but no video_path")
    numeric = [k for k, v in features.items() if v.get("dtype") == "float32" and k != "timestamp"]
    texts = [k for k, v in features.items() if v.get("dtype") == "string"]
    data_cache: dict[Path, pa.Table] = {}
    probes: dict[Path, video.VideoProbe] = {}
    decoded: dict[str, tuple[Path, NDArray[np.uint8]]] = {}
    out: list[ReadEpisode] = []
    n_rows = 0
    for i, ep in enumerate(sorted(episodes_meta, key=lambda r: r["episode_index"])):
        where = f"episode {i}"
        if ep["episode_index"] != i:
            raise FormatError(base / "meta/episodes", f"episode indices skip {i}")
        path = base / data_path.format(
            chunk_index=ep["data/chunk_index"], file_index=ep["data/file_index"]
        )
        if path not in data_cache:
            data_cache[path] = _parquet(path)
        table = data_cache[path]
        rows = table.filter(pc.equal(table["episode_index"], i))
        length = int(ep["length"])
        lo, hi = int(ep["dataset_from_index"]), int(ep["dataset_to_index"])
        index = rows["index"].to_numpy()
        if (
            rows.num_rows != length
            or hi - lo != length
            or not np.array_equal(index, np.arange(lo, hi))
        ):
            raise FormatError(
                path,
                f"{where}: {rows.num_rows} rows with index {index[:1]}..{index[-1:]}, "
                f"the episodes metadata says {length} rows {lo}..{hi - 1}",
                where=where,
            )
        frame = rows["frame_index"].to_numpy()
        ts = rows["timestamp"].to_numpy()
        if not np.array_equal(frame, np.arange(length)):
            raise FormatError(path, "frame_index is not 0, 1, 2, …", where=where)
        if not np.allclose(ts, (frame / fps).astype(np.float32), rtol=0, atol=1e-6):
            raise FormatError(path, f"timestamps are not frame_index / {fps}", where=where)
        feats = {k: _numeric(rows[k], length) for k in numeric}
        notes = {k: [str(s) for s in rows[k].to_pylist()] for k in texts}
        frames = {}
        for key in cams:
            assert video_path is not None
            vpath = base / video_path.format(
                video_key=key,
                chunk_index=ep[f"videos/{key}/chunk_index"],
                file_index=ep[f"videos/{key}/file_index"],
            )
            if vpath not in probes:
                check_regular(vpath, what="MP4 file")
                probes[vpath] = video.probe(vpath)
            found = probes[vpath]
            times = float(ep[f"videos/{key}/from_timestamp"]) + ts.astype(np.float64)
            picked = _frame_indices(vpath, found.pts, times, where)
            if decode_videos:
                if decoded.get(key, (None,))[0] != vpath:  # one file per camera in memory
                    decoded[key] = (vpath, _decode(vpath, found))
                frames[key] = decoded[key][1][picked]
        out.append(
            ReadEpisode(
                index=i,
                tasks=list(ep["tasks"]),
                timestamps=ts.astype(np.float32),
                features=feats,
                videos=frames,
                annotations=notes,
            )
        )
        n_rows += length
    all_rows = sum(t.num_rows for t in data_cache.values())
    _agree(info_path, "total_frames", totals["total_frames"], n_rows)
    _agree(info_path, "total_frames", totals["total_frames"], all_rows)
    return LeRobotDataset(root=base, info=info, stats=stats, tasks=tasks, episodes=out)


def _numeric(column: pa.ChunkedArray, length: int) -> NDArray[np.float32]:
    """A float32 column (one value per row) or list column as shape (n_rows, n)."""
    values = column.combine_chunks()
    if pa.types.is_list(values.type) or pa.types.is_fixed_size_list(values.type):
        values = values.flatten()
    return np.asarray(values, dtype=np.float32).reshape(length, -1)


def _decode(path: Path, found: video.VideoProbe) -> NDArray[np.uint8]:
    """Every frame of ``path`` in presentation order, as many as it has frame times."""
    frames = video.decode_frames(path, width=found.width, height=found.height)
    if frames.shape[0] != found.pts.size:
        raise FormatError(path, f"{found.pts.size} frame times for {frames.shape[0]} frames")
    return frames


def _frame_indices(
    path: Path, pts: NDArray[np.float64], times: NDArray[np.float64], where: str
) -> NDArray[np.intp]:
    """Index (in presentation order) of the frame nearest each time, as LeRobot picks it.

    Raises
    ------
    FormatError
        No frame lies within :data:`TOLERANCE_S` of one of the times.
    """
    shown = np.sort(pts)
    if shown.size == 0:
        raise FormatError(path, "the video has no frame", where=where)
    right = np.clip(np.searchsorted(shown, times), 0, shown.size - 1)
    left = np.clip(right - 1, 0, shown.size - 1)
    nearest = np.where(np.abs(shown[left] - times) <= np.abs(shown[right] - times), left, right)
    miss = np.flatnonzero(np.abs(shown[nearest] - times) >= TOLERANCE_S)
    if miss.size:
        k = int(miss[0])
        raise FormatError(
            path,
            f"no video frame within {TOLERANCE_S} s of {times[k]:.6f} s (row {k}); the file "
            f"has {shown.size} frames from {shown[0]:.6f} to {shown[-1]:.6f} s",
            where=where,
        )
    return nearest


def _tasks(table: pa.Table, path: Path) -> list[str]:
    names = table.column_names
    text = "task" if "task" in names else "__index_level_0__"
    if "task_index" not in names or text not in names:
        raise FormatError(path, f"expected columns task_index and the task text, got {names}")
    order = np.argsort(table["task_index"].to_numpy())
    if not np.array_equal(table["task_index"].to_numpy()[order], np.arange(table.num_rows)):
        raise FormatError(path, "task_index is not 0, 1, 2, …")
    values = table[text].to_pylist()
    return [str(values[k]) for k in order]


def _agree(path: Path, what: str, stated: int, found: int) -> None:
    if stated != found:
        raise FormatError(path, f"{what} is {stated} but the files hold {found}")
