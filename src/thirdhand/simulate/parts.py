"""Part geometry for physics: collision pieces, mass and inertia from a closed mesh.

A part's mesh (body frame, metres) collides in MuJoCo as the convex hull of each
mesh geom, so a part with a hole (the seat's leg sockets) needs a convex
decomposition: :func:`convex_pieces` runs CoACD once per mesh content and keeps
the pieces in a cache folder keyed by a hash of the triangles and the
decomposition's parameters, so a second run reads them back. Mass and inertia come
from the mesh's own volume (not the pieces', which overlap) times a density.
"""

from __future__ import annotations

import hashlib
import io
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from thirdhand.arrays import FloatArray
from thirdhand.errors import ThirdhandError
from thirdhand.readlimits import read_input

#: Version of the cache's file layout and of the call to CoACD (part of the key).
CACHE_VERSION = "coacd-1"

#: Largest cache entry read, bytes (a decomposition of a few hundred pieces).
MAX_CACHE_BYTES = 64 * 2**20


class SimulateError(ThirdhandError):
    """A task, run or setting that cannot be simulated."""


@dataclass(frozen=True)
class Piece:
    """One convex collision piece of a part.

    Attributes
    ----------
    vertices : ndarray, shape (n, 3)
        Metres, part body frame.
    """

    vertices: FloatArray


@dataclass(frozen=True)
class MassProperties:
    """Rigid-body inertia of a part.

    Attributes
    ----------
    mass : float
        kg.
    com : ndarray, shape (3,)
        Centre of mass, metres, body frame.
    inertia : ndarray, shape (3, 3)
        Inertia tensor about the centre of mass, kg·m², body axes.
    volume : float
        m³.
    """

    mass: float
    com: FloatArray
    inertia: FloatArray
    volume: float


def default_cache() -> Path:
    """``$XDG_CACHE_HOME/thirdhand/coacd`` (``~/.cache`` when the variable is unset)."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "thirdhand" / "coacd"


def _indexed(triangles: FloatArray) -> tuple[FloatArray, np.ndarray]:
    verts, inverse = np.unique(triangles.reshape(-1, 3), axis=0, return_inverse=True)
    return verts, inverse.reshape(-1, 3).astype(np.int64)


def mesh_key(triangles: FloatArray, threshold: float) -> str:
    """Hex digest of a mesh's triangles (float64) and the decomposition's parameters."""
    h = hashlib.sha256()
    h.update(CACHE_VERSION.encode())
    h.update(np.float64(threshold).tobytes())
    h.update(np.ascontiguousarray(triangles, dtype=np.float64).tobytes())
    return h.hexdigest()


def mass_properties(triangles: FloatArray, density: float) -> MassProperties:
    """Mass, centre of mass and inertia of a closed triangle mesh of uniform density.

    A mesh that does not enclose a volume (open, or inconsistently wound) is
    replaced by its convex hull.

    Parameters
    ----------
    triangles : ndarray, shape (n, 3, 3)
        Metres, body frame.
    density : float
        kg/m³.
    """
    import trimesh

    verts, faces = _indexed(np.asarray(triangles, dtype=np.float64))
    mesh = trimesh.Trimesh(verts, faces, process=True)
    if not mesh.is_volume:
        mesh.fix_normals()
    if not mesh.is_volume or mesh.volume <= 0.0:
        mesh = mesh.convex_hull
    mesh.density = density
    return MassProperties(
        mass=float(mesh.mass),
        com=np.asarray(mesh.center_mass, dtype=np.float64),
        inertia=np.asarray(mesh.moment_inertia, dtype=np.float64),
        volume=float(mesh.volume),
    )


def _volume(vertices: FloatArray) -> float:
    """Volume of the convex hull of points (n, 3), m³ (0 for a flat or degenerate set)."""
    from scipy.spatial import ConvexHull, QhullError

    try:
        return float(ConvexHull(vertices).volume)
    except (QhullError, ValueError):
        return 0.0


def convex_hull(triangles: FloatArray) -> list[Piece]:
    """The mesh's convex hull as one piece (holes filled)."""
    verts, _ = _indexed(np.asarray(triangles, dtype=np.float64))
    return [Piece(verts)]


def convex_pieces(
    triangles: FloatArray,
    *,
    name: str,
    threshold: float = 0.05,
    cache: Path | None = None,
) -> tuple[list[Piece], bool]:
    """Convex decomposition of a mesh by CoACD, read from ``cache`` when made before.

    Parameters
    ----------
    triangles : ndarray, shape (n, 3, 3)
        Metres, body frame.
    name : str
        The part, for error messages.
    threshold : float
        CoACD's concavity threshold.
    cache : pathlib.Path, optional
        Cache folder (:func:`default_cache` by default).

    Returns
    -------
    pieces : list of Piece
    cached : bool
        Whether the pieces came from the cache.

    Raises
    ------
    SimulateError
        When CoACD fails or returns no piece.
    """
    tri = np.asarray(triangles, dtype=np.float64)
    folder = default_cache() if cache is None else cache
    path = folder / f"{mesh_key(tri, threshold)}.npz"
    if path.is_file():
        try:
            data = read_input(path, what="cached decomposition", limit=MAX_CACHE_BYTES)
            with np.load(io.BytesIO(data)) as z:
                return [Piece(np.asarray(z[k], dtype=np.float64)) for k in sorted(z.files)], True
        except (OSError, ValueError, ThirdhandError):
            pass  # an unreadable cache entry is made again
    import coacd
    import pinocchio  # noqa: F401  (first: coacd's libraries break pinocchio's URDF parser)

    coacd.set_log_level("error")
    verts, faces = _indexed(tri)
    if len(faces) == 0 or _volume(verts) <= 0.0:
        raise SimulateError(
            f"{name}: convex decomposition failed: the mesh encloses no volume (flat or empty)"
        )
    try:
        parts = coacd.run_coacd(coacd.Mesh(verts, faces), threshold=threshold, seed=0)
    except Exception as exc:  # CoACD raises plain RuntimeErrors on bad meshes
        raise SimulateError(f"{name}: convex decomposition failed: {exc}") from None
    pieces = [Piece(np.asarray(v, dtype=np.float64)) for v, _ in parts if len(v) >= 4]
    if not pieces:
        raise SimulateError(f"{name}: convex decomposition failed: CoACD returned no piece")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        buf = io.BytesIO()
        arrays: dict[str, Any] = {f"p{i:04d}": p.vertices for i, p in enumerate(pieces)}
        np.savez(buf, **arrays)
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_bytes(buf.getvalue())
        os.replace(tmp, path)
    except OSError:
        pass  # no cache: the next run decomposes again
    return pieces, False
