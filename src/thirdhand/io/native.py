"""Native format: one Parquet file, lossless float64, all metadata and labels.

Layout: column ``t`` (seconds), then per body the columns ``<name>:x y z qx qy qz
qw`` (float64; NaN where not tracked) and ``<name>:valid`` (bool). The schema
metadata key ``thirdhand`` holds JSON with the format version, body metadata,
labels and the demonstration's ``meta``.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from thirdhand import jsontext
from thirdhand.demonstration import (
    Demonstration,
    body_info_from_dict,
    body_info_to_dict,
    labels_from_dict,
    labels_to_dict,
)
from thirdhand.errors import FormatError, ThirdhandError
from thirdhand.fileops import atomic_output
from thirdhand.readlimits import check_regular, loads_json

FORMAT_VERSION = "thirdhand.demonstration/1"
_META_KEY = b"thirdhand"
_COLS = ("x", "y", "z", "qx", "qy", "qz", "qw")
_MAGIC = b"PAR1"


def sniff(path: Path) -> bool:
    """A file ending in ``.parquet`` or starting with Parquet's magic bytes."""
    if not path.is_file():
        return False
    if path.suffix.lower() == ".parquet":
        return True
    from thirdhand.readlimits import sniff_bytes

    return sniff_bytes(path, 4) == _MAGIC


def write(demo: Demonstration, path: str | os.PathLike[str]) -> None:
    """Write ``demo`` to a Parquet file (atomically: temp file then rename)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    p = Path(path)
    arrays: dict[str, Any] = {"t": pa.array(demo.t, pa.float64())}
    for name in demo.body_names:
        tr = demo.track(name)
        for j, c in enumerate(_COLS):
            src = tr.pos[:, j] if j < 3 else tr.quat[:, j - 3]
            arrays[f"{name}:{c}"] = pa.array(np.ascontiguousarray(src), pa.float64())
        arrays[f"{name}:valid"] = pa.array(tr.valid, pa.bool_())
    header = {
        "format": FORMAT_VERSION,
        "bodies": [body_info_to_dict(b) for b in demo.bodies],
        "labels": labels_to_dict(demo.labels),
        "meta": demo.meta,
    }
    table = pa.table(arrays)
    table = table.replace_schema_metadata(
        {_META_KEY: jsontext.dumps(header, what="the recording's header").encode()}
    )
    with atomic_output(p) as tmp:
        pq.write_table(table, tmp, compression="zstd")


def read(path: str | os.PathLike[str]) -> Demonstration:
    """Read a demonstration written by :func:`write`."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    p = check_regular(path, what="Parquet file")
    try:
        table = pq.read_table(p)
    except (pa.ArrowInvalid, OSError) as exc:
        raise FormatError(p, f"not a readable Parquet file: {exc}") from None
    raw = (table.schema.metadata or {}).get(_META_KEY)
    if raw is None:
        raise FormatError(p, "Parquet file has no thirdhand metadata (not written by thirdhand)")
    header = loads_json(raw, error=lambda m: FormatError(p, f"thirdhand metadata: {m}"))
    if not isinstance(header, dict):
        raise FormatError(p, "thirdhand metadata is not a JSON object")
    if header.get("format") != FORMAT_VERSION:
        raise FormatError(
            p, f"unsupported format {header.get('format')!r}, expected {FORMAT_VERSION!r}"
        )
    names = set(table.column_names)

    def column(name: str) -> np.ndarray:
        if name not in names:
            raise FormatError(p, f"missing column {name!r}")
        return table.column(name).to_numpy(zero_copy_only=False)

    try:
        bodies = [body_info_from_dict(b) for b in header["bodies"]]
        labels = labels_from_dict(header.get("labels", {}))
        pos, quat, valid = {}, {}, {}
        for b in bodies:
            cols = np.column_stack([column(f"{b.name}:{c}") for c in _COLS])
            pos[b.name], quat[b.name] = cols[:, :3], cols[:, 3:]
            valid[b.name] = column(f"{b.name}:valid").astype(bool)
        return Demonstration(
            column("t"), bodies, pos, quat, valid, labels=labels, meta=header.get("meta", {})
        )
    except FormatError:
        raise
    except (ThirdhandError, KeyError, TypeError) as exc:
        raise FormatError(p, str(exc)) from None
