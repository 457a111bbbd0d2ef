"""LeRobot's on-disk layout, codebase version v3.0 (``lerobot/datasets/utils.py``, 0.4.x).

Pure functions and constants: the path templates, the chunk and file indices,
the ``features`` block of ``meta/info.json`` and the arrow types of the columns.
"""

from __future__ import annotations

import json
from typing import Any

import pyarrow as pa

from thirdhand.lerobot.episode import RESERVED

CODEBASE_VERSION = "v3.0"
INFO_PATH = "meta/info.json"
STATS_PATH = "meta/stats.json"
TASKS_PATH = "meta/tasks.parquet"
CHUNK_FILE = "chunk-{chunk_index:03d}/file-{file_index:03d}"
EPISODES_PATH = "meta/episodes/" + CHUNK_FILE + ".parquet"
DATA_PATH = "data/" + CHUNK_FILE + ".parquet"
VIDEO_PATH = "videos/{video_key}/" + CHUNK_FILE + ".mp4"
#: LeRobot's defaults: files per chunk folder, and the size at which a new file starts.
CHUNKS_SIZE = 1000
DATA_FILES_SIZE_IN_MB = 100
VIDEO_FILES_SIZE_IN_MB = 200
#: The columns LeRobot adds to every dataset, with their ``info.json`` entries.
DEFAULT_FEATURES: dict[str, dict[str, Any]] = {
    "timestamp": {"dtype": "float32", "shape": [1], "names": None},
    **{k: {"dtype": "int64", "shape": [1], "names": None} for k in RESERVED[1:]},
}


def next_file(chunk_index: int, file_index: int, chunks_size: int) -> tuple[int, int]:
    """The (chunk, file) after a full file: the next file, or file 0 of the next chunk."""
    if file_index == chunks_size - 1:
        return chunk_index + 1, 0
    return chunk_index, file_index + 1


def feature_entries(
    names: dict[str, tuple[str, ...]],
    videos: dict[str, tuple[int, int, int]],
    annotations: tuple[str, ...],
    video_info: dict[str, dict[str, Any]],
) -> dict[str, dict[str, Any]]:
    """The ``features`` block of ``meta/info.json``, in column order.

    Parameters
    ----------
    names : dict
        Numeric feature -> its column names (float32, shape ``[n]``).
    videos : dict
        Camera -> (height, width, channels).
    annotations : tuple of str
        Per-frame text features (``string``, shape ``[1]``).
    video_info : dict
        Camera -> the ``info`` block of its video (codec, pixel format, fps…).
    """
    out: dict[str, dict[str, Any]] = {}
    for key, cols in names.items():
        out[key] = {"dtype": "float32", "shape": [len(cols)], "names": list(cols)}
    for key, shape in videos.items():
        out[key] = {
            "dtype": "video",
            "shape": list(shape),
            "names": ["height", "width", "channels"],
            "info": video_info[key],
        }
    for key in annotations:
        out[key] = {"dtype": "string", "shape": [1], "names": None}
    out.update({k: dict(v) for k, v in DEFAULT_FEATURES.items()})
    return out


def _hf_feature(entry: dict[str, Any]) -> dict[str, Any]:
    value = {"dtype": entry["dtype"], "_type": "Value"}
    if entry["shape"] == [1]:
        return value
    return {"feature": value, "length": entry["shape"][0], "_type": "List"}


def data_schema(features: dict[str, dict[str, Any]]) -> pa.Schema:
    """Arrow schema of ``data/`` files, with the ``huggingface`` metadata LeRobot writes.

    Numeric features are fixed-size lists of float32, text is ``string``,
    ``timestamp`` float32 and the indices int64; videos have no column.
    """
    fields = []
    hf: dict[str, Any] = {}
    for key, entry in features.items():
        if entry["dtype"] == "video":
            continue
        scalar = {"float32": pa.float32(), "int64": pa.int64(), "string": pa.string()}
        base = scalar[entry["dtype"]]
        typ = base if entry["shape"] == [1] else pa.list_(base, entry["shape"][0])
        fields.append(pa.field(key, typ))
        hf[key] = _hf_feature(entry)
    meta = {b"huggingface": json.dumps({"info": {"features": hf}}, allow_nan=False).encode()}
    return pa.schema(fields, metadata=meta)


def tasks_table(tasks: list[str]) -> pa.Table:
    """``meta/tasks.parquet``: ``task_index`` with the task text as the pandas index.

    LeRobot writes it from a pandas DataFrame indexed by the task text and reads
    it back with ``pandas.read_parquet``; the ``pandas`` schema metadata makes
    the text column that index again.
    """
    meta = {
        "index_columns": ["__index_level_0__"],
        "column_indexes": [
            {
                "name": None,
                "field_name": None,
                "pandas_type": "unicode",
                "numpy_type": "object",
                "metadata": {"encoding": "UTF-8"},
            }
        ],
        "columns": [
            {
                "name": "task_index",
                "field_name": "task_index",
                "pandas_type": "int64",
                "numpy_type": "int64",
                "metadata": None,
            },
            {
                "name": None,
                "field_name": "__index_level_0__",
                "pandas_type": "unicode",
                "numpy_type": "object",
                "metadata": None,
            },
        ],
        "attributes": {},
        "creator": {"library": "pyarrow", "version": pa.__version__},
    }
    schema = pa.schema(
        [pa.field("task_index", pa.int64()), pa.field("__index_level_0__", pa.large_string())],
        metadata={b"pandas": json.dumps(meta, allow_nan=False).encode()},
    )
    return pa.table(
        {"task_index": list(range(len(tasks))), "__index_level_0__": tasks}, schema=schema
    )
