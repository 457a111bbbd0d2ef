"""STL meshes: a reader for binary and ASCII files, and their bounds.

Used by the synthetic scenes (part sizes), the task file (mesh bounds), the
review GUI and the executor (collision meshes).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from thirdhand.arrays import FloatArray
from thirdhand.errors import FormatError
from thirdhand.readlimits import MAX_MESH_BYTES, read_input

_STL_DTYPE = np.dtype([("normal", "<f4", (3,)), ("vertices", "<f4", (3, 3)), ("attribute", "<u2")])


def read_stl(path: str | os.PathLike[str]) -> FloatArray:
    """Triangle vertices of a binary or ASCII STL file.

    Returns
    -------
    ndarray, shape (n_triangles, 3, 3)
        Vertex coordinates in the file's units (the 3rdHand meshes use millimetres).

    Raises
    ------
    FormatError
        If the path is not a regular file of at most
        :data:`~thirdhand.readlimits.MAX_MESH_BYTES`, the file is neither a
        consistent binary STL nor an ASCII one, or a vertex is not finite (NaN or
        infinite coordinates would reach the collision checker's solvers).
    """
    p = Path(path)
    data = read_input(p, what="mesh (STL) file", limit=MAX_MESH_BYTES)
    if len(data) >= 84:
        n = int(np.frombuffer(data[80:84], "<u4")[0])
        if 84 + 50 * n == len(data):
            tri = np.frombuffer(data, _STL_DTYPE, count=n, offset=84)["vertices"]
            return _finite(p, tri.astype(np.float64))
    text = data.decode("ascii", errors="replace")
    if not text.lstrip().lower().startswith("solid"):
        raise FormatError(
            p,
            f"expected a binary STL of 84 + 50·n bytes or an ASCII 'solid', got {len(data)} bytes",
        )
    rows = []
    for lineno, line in enumerate(text.splitlines(), start=1):
        parts = line.split()
        if parts and parts[0].lower() == "vertex":
            if len(parts) != 4:
                raise FormatError(p, f"expected 'vertex x y z', got {line.strip()!r}", line=lineno)
            try:
                rows.append([float(v) for v in parts[1:]])
            except ValueError:
                raise FormatError(p, f"non-numeric vertex {line.strip()!r}", line=lineno) from None
    if not rows or len(rows) % 3:
        raise FormatError(p, f"expected vertices in triples, found {len(rows)}")
    return _finite(p, np.asarray(rows, dtype=np.float64).reshape(-1, 3, 3))


def _finite(p: Path, tri: FloatArray) -> FloatArray:
    """``tri`` if every coordinate is finite; else one line naming the first bad triangle."""
    bad = ~np.isfinite(tri).all(axis=(1, 2))
    if bad.any():
        first = int(np.argmax(bad))
        raise FormatError(
            p,
            f"{int(bad.sum())} of {len(tri)} triangles have a vertex that is not a finite "
            f"number (NaN or infinite), the first is triangle {first}",
        )
    return tri


def stl_bounds(path: str | os.PathLike[str]) -> tuple[FloatArray, FloatArray]:
    """Axis-aligned bounding box of an STL mesh: ``(min (3,), max (3,))`` in file units."""
    v = read_stl(path).reshape(-1, 3)
    return v.min(axis=0), v.max(axis=0)
