"""Exact convex pieces of a part with pockets: its hull with its cavities cut out along their faces.

MuJoCo collides every mesh geom as its convex hull, so a part with a pocket needs
convex pieces whose union is the part. An approximate decomposition (CoACD) lets
its pieces bulge by about a millimetre into the pockets, which is what a tenon's
clearance is: a leg that fits its pocket in the real part jams on the pieces. The
assembly parts of the 3rdHand set are boards with machined pockets, grooves and
notches, whose cavities are convex or nearly so; for those this module cuts the
part exactly:

1. the cavities are the part's convex hull minus the part (``manifold3d``'s exact
   booleans), one connected component each;
2. a cavity thinner than :data:`MIN_THICKNESS_M` on average (a shell over slightly
   curved faces) or smaller than :data:`MIN_CAVITY_M3` is filled (nothing of an
   assembly goes in there);
3. starting from the hull, each cavity's convex hull is removed from every piece it
   meets by splitting the piece along the cavity's face planes (each piece outside
   one face and inside the ones before it is convex); a cavity that is itself far
   from convex is cut into its own exact pieces first (once).

:func:`exact_pieces` returns None for a mesh that is not a closed manifold (after
welding vertices closer than 0.1 µm), so the caller can fall back to CoACD.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from thirdhand.arrays import FloatArray

#: Cavities thinner than this on average (2 · volume / area) are filled, metres.
MIN_THICKNESS_M = 1.5e-3

#: Cavities smaller than this are filled, m³ (1 cm³).
MIN_CAVITY_M3 = 1e-6

#: Pieces smaller than this are dropped, m³ (1 mm³).
MIN_PIECE_M3 = 1e-9

#: A cavity whose hull exceeds it by more than this share is cut into pieces first.
CONVEX_SLACK = 0.02

#: Vertices closer than this are welded before the mesh is checked, metres.
WELD_M = 1e-7


@dataclass(frozen=True)
class Carved:
    """The exact pieces of a part and how far their union is from the mesh.

    Attributes
    ----------
    pieces : list of ndarray (n, 3)
        Vertices of each convex piece, metres, the mesh's frame.
    filled_m3 : float
        Volume of the cavities filled (too thin or too small to matter), m³.
    missing_m3 : float
        Volume of the part the pieces leave out (a non-convex cavity's hull), m³.
    cavities : int
        Cavities cut out.
    volume_m3 : float
        The mesh's volume, m³.
    """

    pieces: list[FloatArray]
    filled_m3: float
    missing_m3: float
    cavities: int
    volume_m3: float


def _manifold(triangles: FloatArray) -> Any | None:
    """The mesh as a ``manifold3d.Manifold``, or None when it is not a closed manifold."""
    import manifold3d as mf

    tri = np.round(np.asarray(triangles, dtype=np.float64) / WELD_M) * WELD_M
    verts, inverse = np.unique(tri.reshape(-1, 3), axis=0, return_inverse=True)
    faces = inverse.reshape(-1, 3)
    keep = (
        (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])
    )
    if not keep.any():
        return None
    mesh = mf.Mesh(
        vert_properties=np.asarray(verts, dtype=np.float32),
        tri_verts=np.asarray(faces[keep], dtype=np.uint32),
    )
    solid = mf.Manifold(mesh)
    if solid.status() != mf.Error.NoError or solid.volume() <= 0.0:
        return None
    return solid


def _vertices(solid: Any) -> FloatArray:
    return np.asarray(solid.to_mesh().vert_properties, dtype=np.float64)[:, :3]


def _face_planes(convex: Any) -> FloatArray:
    """Distinct face planes (k, 4) ``[n, d]`` of a convex solid, ``n·x + d ≤ 0`` inside."""
    from scipy.spatial import ConvexHull

    eq = ConvexHull(_vertices(convex)).equations
    _, first = np.unique(np.round(eq / 1e-7).astype(np.int64), axis=0, return_index=True)
    return np.asarray(eq[np.sort(first)], dtype=np.float64)


def _subtract(pieces: list[Any], convex: Any) -> list[Any]:
    """Convex ``pieces`` minus the convex solid ``convex``, as convex pieces."""
    planes = _face_planes(convex)
    out: list[Any] = []
    for piece in pieces:
        if (piece ^ convex).volume() <= MIN_PIECE_M3:
            out.append(piece)
            continue
        rest = piece
        for plane in planes:
            outside, rest = rest.split_by_plane(plane[:3].tolist(), float(-plane[3]))
            if outside.volume() > MIN_PIECE_M3:
                out.append(outside)
            if rest.volume() <= MIN_PIECE_M3:
                break
    return out


def _cavities(solid: Any, depth: int) -> tuple[list[Any], float]:
    """Disjoint convex solids covering the cavities that matter, and the volume filled."""
    filled = 0.0
    out: list[Any] = []
    for cavity in (solid.hull() - solid).decompose():
        vol = cavity.volume()
        if vol < MIN_CAVITY_M3 or 2.0 * vol / max(cavity.surface_area(), 1e-12) < MIN_THICKNESS_M:
            filled += vol
            continue
        hull = cavity.hull()
        if hull.volume() <= (1.0 + CONVEX_SLACK) * vol or depth >= 1:
            out.append(hull)
        else:
            out.extend(_pieces(cavity, depth + 1)[0])
    return out, filled


def _pieces(solid: Any, depth: int) -> tuple[list[Any], float, int]:
    cavities, filled = _cavities(solid, depth)
    pieces = [solid.hull()]
    for cavity in cavities:
        pieces = _subtract(pieces, cavity)
    return pieces, filled, len(cavities)


def exact_pieces(triangles: FloatArray) -> Carved | None:
    """Convex pieces of a closed mesh with its cavities cut out exactly, or None.

    Parameters
    ----------
    triangles : ndarray, shape (n, 3, 3)
        Metres.

    Returns
    -------
    Carved or None
        None when the mesh is not a closed manifold.
    """
    import manifold3d as mf

    solid = _manifold(triangles)
    if solid is None:
        return None
    pieces, filled, n = _pieces(solid, 0)
    union = mf.Manifold.batch_boolean(pieces, mf.OpType.Add) if pieces else mf.Manifold()
    missing = max(float((solid - union).volume()), 0.0)
    return Carved([_vertices(p) for p in pieces], float(filled), missing, n, float(solid.volume()))
