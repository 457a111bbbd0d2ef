"""Write episodes as a LeRobot dataset (v3.0) with pyarrow and ffmpeg, never half-written.

:class:`DatasetWriter` builds the dataset in a temporary folder beside the
target (:func:`thirdhand.fileops.atomic_output`): every episode is first
written to files of its own (its rows, one video per camera), and counted as
finished only once they are complete. Closing the writer joins the finished
episodes into LeRobot's files (a new data or video file once the size limits
of ``meta/info.json`` would be passed, a new chunk folder every
``chunks_size`` files, as LeRobot does), writes the metadata and renames the
folder into place in one step. An exception leaves no target; Ctrl-C or
SIGTERM (:class:`~thirdhand.errors.Terminated`) with ``keep_finished`` leaves a
complete dataset of the episodes finished before it, then the interruption
goes on.
"""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
from pydantic import Field

from thirdhand.errors import OptionError, OutputError, Terminated
from thirdhand.fileops import atomic_output, check_output
from thirdhand.lerobot import layout, video
from thirdhand.lerobot.episode import Episode
from thirdhand.lerobot.stats import Stats, aggregate, column_stats, image_stats
from thirdhand.readlimits import open_input
from thirdhand.settings import Settings

_MB = 1024**2
#: Largest file of one episode's rows read back when joining them, bytes.
_PART_LIMIT = 4 * 2**30


class DatasetSettings(Settings):
    """How a dataset is split into files (LeRobot's defaults)."""

    chunks_size: int = Field(layout.CHUNKS_SIZE, ge=1, description="Files per chunk folder.")
    data_files_size_in_mb: float = Field(
        layout.DATA_FILES_SIZE_IN_MB, gt=0, description="A new data file starts past this size."
    )
    video_files_size_in_mb: float = Field(
        layout.VIDEO_FILES_SIZE_IN_MB, gt=0, description="A new video file starts past this size."
    )


@dataclass(frozen=True)
class DatasetSummary:
    """What :func:`write_dataset` wrote.

    Attributes
    ----------
    root : pathlib.Path
        The dataset folder.
    episodes, frames, tasks : int
        Totals, as in ``meta/info.json``.
    data_files, video_files : int
        Parquet files under ``data/`` and MP4 files under ``videos/``.
    interrupted : bool
        Ctrl-C or SIGTERM stopped the writing; the dataset holds the episodes
        finished before it.
    """

    root: Path
    episodes: int
    frames: int
    tasks: int
    data_files: int
    video_files: int
    interrupted: bool = False


@dataclass
class _Finished:
    """One finished episode: its own files and what the metadata needs."""

    length: int
    task: str
    data: Path
    data_bytes: int
    videos: dict[str, tuple[Path, int]]
    stats: dict[str, Stats]


@dataclass
class _Placement:
    """Where each finished episode lands: (chunk, file) per data and camera, video start times."""

    data: list[tuple[int, int]] = field(default_factory=list)
    videos: dict[str, list[tuple[int, int, float]]] = field(default_factory=dict)


def place_episodes(
    lengths: list[int],
    data_bytes: list[int],
    video_bytes: dict[str, list[int]],
    *,
    fps: int,
    settings: DatasetSettings,
) -> _Placement:
    """Assign every episode a data file and a video file per camera, as LeRobot does.

    A data file takes the next episode unless its size so far plus the
    episode's rows at the file's average size per row would reach
    ``data_files_size_in_mb``; a video file unless its size plus the
    episode's video would reach ``video_files_size_in_mb``. The episode's
    video starts where the previous one of its file ends (``from_timestamp``,
    seconds), 0 in a new file.
    """
    out = _Placement()
    chunk, file, size, rows = 0, 0, 0, 0
    for i, (n, b) in enumerate(zip(lengths, data_bytes, strict=True)):
        if i and size + (size / rows) * n >= settings.data_files_size_in_mb * _MB:
            chunk, file = layout.next_file(chunk, file, settings.chunks_size)
            size, rows = 0, 0
        out.data.append((chunk, file))
        size, rows = size + b, rows + n
    for key, sizes in video_bytes.items():
        chunk, file, size, start = 0, 0, 0, 0
        placed = []
        for i, (n, b) in enumerate(zip(lengths, sizes, strict=True)):
            if i and size + b >= settings.video_files_size_in_mb * _MB:
                chunk, file = layout.next_file(chunk, file, settings.chunks_size)
                size, start = 0, 0
            placed.append((chunk, file, start / fps))
            size, start = size + b, start + n
        out.videos[key] = placed
    return out


class DatasetWriter:
    """Write episodes one by one into a new LeRobot dataset folder.

    Use as a context manager::

        with DatasetWriter(root, fps=30, robot_type="panda") as w:
            for ep in episodes:
                w.add_episode(ep)
        summary = w.summary

    Parameters
    ----------
    root : path-like
        The dataset folder to create.
    fps : int
        Frames per second of every episode.
    robot_type : str or None
        ``robot_type`` of ``meta/info.json`` (``"panda"``; None for a person).
    force : bool
        Replace an existing dataset folder (kept as a numbered ``.bak`` folder).
    settings : DatasetSettings, optional
        File size limits and files per chunk.
    keep_finished : bool
        On Ctrl-C or SIGTERM, write the episodes finished so far (if any).
    """

    def __init__(
        self,
        root: str | os.PathLike[str],
        *,
        fps: int,
        robot_type: str | None,
        force: bool = False,
        settings: DatasetSettings | None = None,
        keep_finished: bool = True,
    ) -> None:
        if isinstance(fps, bool) or not isinstance(fps, int | np.integer) or fps <= 0:
            raise OptionError(f"fps must be a positive whole number, got {fps!r}")
        self.root = Path(root)
        self.fps = int(fps)
        self.robot_type = robot_type
        self.force = force
        self.settings = settings or DatasetSettings.model_validate({})
        self.keep_finished = keep_finished
        self.summary: DatasetSummary | None = None
        self._stack: contextlib.ExitStack | None = None
        self._built = Path()
        self._parts = Path()
        self._layout: dict[str, Any] | None = None
        self._done: list[_Finished] = []
        self._tasks: dict[str, int] = {}

    def __enter__(self) -> DatasetWriter:
        check_output(self.root, force=self.force)
        stack = contextlib.ExitStack()
        built = stack.enter_context(atomic_output(self.root))
        try:
            built.mkdir()
            self._parts = built.parent / ".episodes"
            self._parts.mkdir()
        except BaseException:
            stack.close()
            raise
        self._stack, self._built = stack, built
        return self

    def add_episode(self, episode: Episode) -> int:
        """Write one episode; returns its index. The episode counts only once complete.

        Raises
        ------
        OptionError
            Its frame rate, features, column names or camera sizes differ from
            the first episode's.
        """
        if self._stack is None:
            raise OptionError("DatasetWriter.add_episode: use the writer in a 'with' block")
        if episode.fps != self.fps:
            raise OptionError(
                f"episode {len(self._done)}: {episode.fps} frames per second, "
                f"the dataset {self.fps}"
            )
        shape = episode.layout()
        if self._layout is None:
            self._layout = shape
        elif shape != self._layout:
            raise OptionError(
                f"episode {len(self._done)}: its features, names or camera sizes differ from "
                f"episode 0's ({_difference(self._layout, shape)})"
            )
        index = len(self._done)
        first = sum(f.length for f in self._done)
        task_index = self._tasks.get(episode.task, len(self._tasks))
        n = episode.n_frames
        columns: dict[str, Any] = {}
        stats: dict[str, Stats] = {}
        for key, arr in episode.features.items():
            columns[key] = arr
            stats[key] = column_stats(arr)
        for key, frames in episode.videos.items():
            stats[key] = image_stats(frames)
        for key, texts in episode.annotations.items():
            columns[key] = list(texts)
        ts = episode.timestamps
        ints = {
            "frame_index": np.arange(n, dtype=np.int64),
            "episode_index": np.full(n, index, dtype=np.int64),
            "index": np.arange(first, first + n, dtype=np.int64),
            "task_index": np.full(n, task_index, dtype=np.int64),
        }
        columns["timestamp"] = ts.astype(np.float32)
        columns.update(ints)
        stats["timestamp"] = column_stats(ts[:, None])
        stats.update({k: column_stats(v[:, None]) for k, v in ints.items()})
        schema = layout.data_schema(self._features())
        table = pa.table([_arrow(columns[f.name], f.type) for f in schema], schema=schema)
        data = self._parts / f"data-{index:06d}.parquet"
        pq.write_table(table, data, compression="snappy", use_dictionary=True)
        videos: dict[str, tuple[Path, int]] = {}
        for key, frames in episode.videos.items():
            path = self._parts / f"video-{index:06d}-{len(videos)}.mp4"
            video.encode_frames(frames, path, fps=self.fps)
            videos[key] = (path, path.stat().st_size)
        done = _Finished(n, episode.task, data, data.stat().st_size, videos, stats)
        self._tasks.setdefault(episode.task, task_index)
        self._done.append(done)  # the one step that makes the episode count
        return index

    def _features(self) -> dict[str, dict[str, Any]]:
        assert self._layout is not None
        info = {
            key: {
                "video.height": h,
                "video.width": w,
                "video.codec": video.CODEC,
                "video.pix_fmt": video.PIX_FMT,
                "video.is_depth_map": False,
                "video.fps": self.fps,
                "video.channels": c,
                "has_audio": False,
            }
            for key, (h, w, c) in self._layout["videos"].items()
        }
        return layout.feature_entries(
            dict(self._layout["features"]),
            dict(self._layout["videos"]),
            tuple(self._layout["annotations"]),
            info,
        )

    def _finish(self) -> DatasetSummary:
        if not self._done:
            raise OptionError(f"{self.root}: no episode to write; nothing was written")
        root, done, s = self._built, self._done, self.settings
        cams = list(self._layout["videos"]) if self._layout else []
        placed = place_episodes(
            [d.length for d in done],
            [d.data_bytes for d in done],
            {k: [d.videos[k][1] for d in done] for k in cams},
            fps=self.fps,
            settings=s,
        )
        features = self._features()
        schema = layout.data_schema(features)
        for (c, f), group in _groups(placed.data).items():
            path = root / layout.DATA_PATH.format(chunk_index=c, file_index=f)
            path.parent.mkdir(parents=True, exist_ok=True)
            with pq.ParquetWriter(path, schema, compression="snappy", use_dictionary=True) as w:
                for i in group:
                    with open_input(done[i].data, what="episode rows", limit=_PART_LIMIT) as fh:
                        w.write_table(pq.read_table(fh, schema=schema))
        n_videos = 0
        for key in cams:
            spots = [(c, f) for c, f, _ in placed.videos[key]]
            for (c, f), group in _groups(spots).items():
                path = root / layout.VIDEO_PATH.format(video_key=key, chunk_index=c, file_index=f)
                path.parent.mkdir(parents=True, exist_ok=True)
                video.concatenate([done[i].videos[key][0] for i in group], path)
                n_videos += 1
        rows = []
        start = 0
        for i, d in enumerate(done):
            row: dict[str, Any] = {
                "episode_index": i,
                "tasks": [d.task],
                "length": d.length,
                "data/chunk_index": placed.data[i][0],
                "data/file_index": placed.data[i][1],
                "dataset_from_index": start,
                "dataset_to_index": start + d.length,
            }
            for key in cams:
                c, f, t0 = placed.videos[key][i]
                row[f"videos/{key}/chunk_index"] = c
                row[f"videos/{key}/file_index"] = f
                row[f"videos/{key}/from_timestamp"] = t0
                row[f"videos/{key}/to_timestamp"] = t0 + d.length / self.fps
            for key in features:
                if key in d.stats:
                    for stat, value in d.stats[key].items():
                        row[f"stats/{key}/{stat}"] = value.tolist()
            rows.append(row)
            start += d.length
        _write_episodes(root, rows, s)
        tasks = sorted(self._tasks, key=self._tasks.__getitem__)
        pq.write_table(layout.tasks_table(tasks), root / layout.TASKS_PATH, compression="snappy")
        total = sum(d.length for d in done)
        info = {
            "codebase_version": layout.CODEBASE_VERSION,
            "robot_type": self.robot_type,
            "total_episodes": len(done),
            "total_frames": total,
            "total_tasks": len(tasks),
            "chunks_size": s.chunks_size,
            "data_files_size_in_mb": _number(s.data_files_size_in_mb),
            "video_files_size_in_mb": _number(s.video_files_size_in_mb),
            "fps": self.fps,
            "splits": {"train": f"0:{len(done)}"},
            "data_path": layout.DATA_PATH,
            "video_path": layout.VIDEO_PATH if cams else None,
            "features": features,
        }
        stats = {
            key: {k: v.tolist() for k, v in aggregate([d.stats[key] for d in done]).items()}
            for key in features
            if key in done[0].stats
        }
        _write_json(root / layout.INFO_PATH, info)
        _write_json(root / layout.STATS_PATH, stats)
        return DatasetSummary(
            root=self.root,
            episodes=len(done),
            frames=total,
            tasks=len(tasks),
            data_files=len(_groups(placed.data)),
            video_files=n_videos,
        )

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        stack, self._stack = self._stack, None
        if stack is None:
            return
        interrupted = exc_type is not None and issubclass(exc_type, KeyboardInterrupt | Terminated)
        if exc_type is not None and not (interrupted and self.keep_finished and self._done):
            stack.__exit__(exc_type, exc, tb)
            return
        try:
            summary = self._finish()
        except BaseException as err:
            if not stack.__exit__(type(err), err, err.__traceback__):
                raise
            return
        stack.close()
        self.summary = summary if not interrupted else _interrupted(summary)


def _interrupted(s: DatasetSummary) -> DatasetSummary:
    return DatasetSummary(
        s.root, s.episodes, s.frames, s.tasks, s.data_files, s.video_files, interrupted=True
    )


def write_dataset(
    episodes: Iterable[Episode],
    root: str | os.PathLike[str],
    *,
    fps: int,
    robot_type: str | None,
    force: bool = False,
    settings: DatasetSettings | None = None,
    keep_finished: bool = True,
) -> DatasetSummary:
    """Write ``episodes`` as a new LeRobot dataset (v3.0) at ``root``.

    The episodes are drawn from the iterable one at a time (a generator that
    simulates each one is fine). See :class:`DatasetWriter` for the parameters.

    Returns
    -------
    DatasetSummary
        Totals and file counts.

    Raises
    ------
    OutputError
        ``root`` exists and ``force`` is not given, or it cannot be written.
    OptionError
        No episode, or episodes that do not agree; nothing is written.
    """
    writer = DatasetWriter(
        root,
        fps=fps,
        robot_type=robot_type,
        force=force,
        settings=settings,
        keep_finished=keep_finished,
    )
    with writer:
        for ep in episodes:
            writer.add_episode(ep)
    assert writer.summary is not None
    return writer.summary


def _arrow(values: Any, typ: pa.DataType) -> pa.Array:
    if pa.types.is_fixed_size_list(typ):
        arr = np.ascontiguousarray(values, dtype=np.float32)
        return pa.FixedSizeListArray.from_arrays(pa.array(arr.reshape(-1)), typ.list_size)
    if isinstance(values, np.ndarray):  # a feature of one column is a scalar column
        return pa.array(values.reshape(-1), type=typ)
    return pa.array(values, type=typ)


def _groups(spots: list[tuple[int, int]]) -> dict[tuple[int, int], list[int]]:
    out: dict[tuple[int, int], list[int]] = {}
    for i, spot in enumerate(spots):
        out.setdefault(spot, []).append(i)
    return out


def _write_episodes(root: Path, rows: list[dict[str, Any]], s: DatasetSettings) -> int:
    """``meta/episodes/``: one row per episode; a new file past ``data_files_size_in_mb``."""
    files: list[list[dict[str, Any]]] = [[]]
    spots = [(0, 0)]
    size = 0
    for row in rows:
        n = pa.Table.from_pylist([row]).nbytes
        if files[-1] and size + n >= s.data_files_size_in_mb * _MB:
            files.append([])
            spots.append(layout.next_file(*spots[-1], s.chunks_size))
            size = 0
        c, f = spots[-1]
        row["meta/episodes/chunk_index"] = c
        row["meta/episodes/file_index"] = f
        files[-1].append(row)
        size += n
    for (c, f), group in zip(spots, files, strict=True):
        path = root / layout.EPISODES_PATH.format(chunk_index=c, file_index=f)
        path.parent.mkdir(parents=True, exist_ok=True)
        table = pa.Table.from_pydict({k: [r[k] for r in group] for k in group[0]})
        pq.write_table(table, path, compression="snappy", use_dictionary=True)
    return len(files)


def _number(x: float) -> int | float:
    return int(x) if float(x).is_integer() else float(x)


def _write_json(path: Path, data: dict[str, Any]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps(data, indent=4, ensure_ascii=False, allow_nan=False)
    try:
        path.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise OutputError(f"{path}: cannot write: {exc.strerror or exc}") from None


def _difference(a: dict[str, Any], b: dict[str, Any]) -> str:
    for key in a:
        if a[key] != b[key]:
            return f"{key}: {a[key]} then {b[key]}"
    return "layout"
