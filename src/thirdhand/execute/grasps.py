"""Grasps of a part: from the demonstration and from its shape, ranked.

A grasp is the pose of the robot's tool frame in the part's body frame,
``T_part_tool`` (4, 4): the tool's ``z`` is the approach direction (out of the
hand, into the part), its ``y`` the direction the fingers close along, its
origin the point between the fingertips. Picking the part lying at
``T_world_part`` puts the tool at ``T_world_part · T_part_tool``, placing it at
its goal puts it at ``T_world_goal · T_part_tool``; the same grasp serves both.

Shape-based candidates come from the part's bounding box (or mesh vertices):

- a rod (one extent ≥ 1.8 × the others): side grasps across the axis at five
  points along it and twelve directions around it, and end grasps along the
  axis at either end;
- a plate (one extent < 0.35 × the next): grasps on either face at nine points,
  the hand along the face normal (the report's simplification that finger–part
  contacts are ignored makes these valid), and edge grasps pinching its thickness;
- anything else: one grasp at the centre of each face.

Demonstrated grasps (:func:`demo_grasps`) are where a person's fingers held the
part just before the constraint appeared: the fingertips' centroid in the part
frame, the fingers closing from the thumb to the others, the hand approaching
towards the nearest point of the part's core (its axis for a rod).
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from thirdhand.arrays import FloatArray
from thirdhand.demonstration import Demonstration
from thirdhand.execute.goals import invert

#: How far inside a face the tool frame sits for a face or end grasp, metres.
GRASP_DEPTH_M = 0.015
#: How far a gripper's fingers reach past the tool point toward the hand before its casing,
#: metres, less a margin (Panda: tool point 45 mm from the fingers' base).
FINGER_DEPTH_M = 0.035
#: Widest a part's box may be across a parallel gripper's fingers to be held, metres
#: (the Franka Hand opens 80 mm).
MAX_GRIP_M = 0.08
#: A fingertip centroid this close to a part's core (the box shrunk by its smallest half
#: extent) pinches the core: the approach comes from the fingers' layout, metres.
CORE_TOL_M = 0.005
#: Least spread of the non-thumb fingertips that gives their line, metres.
FINGER_SPREAD_M = 0.01
#: A part is a rod when its longest extent is at least this many times the next.
ROD_RATIO = 1.8
#: A part (or a rod's cross-section) is flat when its thinnest extent is under this
#: fraction of the next.
FLAT_RATIO = 0.35


#: Half extents of a fingertip pad across the closing direction, metres: along the tool's
#: x and along its approach (the Franka Hand's pads, 18 × 22 mm).
PAD_HALF_M = (0.009, 0.011)
#: Directions of the rays that tell inside a closed mesh from outside (not along an axis,
#: so that they miss the edges of axis-aligned faces); a point is inside on a majority.
_RAYS = np.array([[0.5773, 0.5774, 0.5774], [-0.3010, 0.8165, 0.4924], [0.8018, -0.2673, 0.5345]])


@dataclass(frozen=True)
class Grasp:
    """One grasp candidate.

    Attributes
    ----------
    pose : ndarray, shape (4, 4)
        ``T_part_tool``, metres, part's body frame.
    source : str
        ``"demo"`` or ``"shape"``.
    label : str
        What kind of grasp (``"side"``, ``"end"``, ``"face"``, ``"edge"``, ``"demo:rh"``...).
    """

    pose: FloatArray
    source: str
    label: str


def tool_frame(origin: ArrayLike, approach: ArrayLike, closing: ArrayLike) -> FloatArray:
    """``T_part_tool`` (4, 4) from a point and two directions (part frame).

    ``approach`` becomes the tool's z; ``closing`` is orthogonalised against it
    and becomes y; x completes a right-handed frame.
    """
    z = np.asarray(approach, dtype=np.float64)
    z = z / np.linalg.norm(z)
    y = np.asarray(closing, dtype=np.float64)
    y = y - (y @ z) * z
    y = y / np.linalg.norm(y)
    t = np.eye(4)
    t[:3, 0] = np.cross(y, z)
    t[:3, 1] = y
    t[:3, 2] = z
    t[:3, 3] = np.asarray(origin, dtype=np.float64)
    return t


def _rolls(t: FloatArray, n: int) -> list[FloatArray]:
    """``t`` turned about its own z by ``2π k / n``, k = 0..n-1."""
    out = []
    for k in range(n):
        a = 2.0 * np.pi * k / n
        r = np.eye(4)
        r[:2, :2] = [[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]]
        out.append(t @ r)
    return out


def shape_grasps(bbox_min: ArrayLike, bbox_max: ArrayLike, *, n_around: int = 12) -> list[Grasp]:
    """Grasp candidates from a part's bounding box (body frame, metres).

    Parameters
    ----------
    bbox_min, bbox_max : array_like, shape (3,)
    n_around : int
        Directions around a rod's axis.

    Returns
    -------
    list of Grasp
        Unranked (see :func:`rank_grasps`).
    """
    lo = np.asarray(bbox_min, dtype=np.float64)
    hi = np.asarray(bbox_max, dtype=np.float64)
    ext = hi - lo
    centre = (lo + hi) / 2.0
    order = np.argsort(-ext, kind="stable")
    e = np.eye(3)
    out: list[Grasp] = []
    if ext[order[0]] >= ROD_RATIO * ext[order[1]]:
        a, b, c = (int(i) for i in order)
        for f in (0.85, 0.7, 0.5, 0.3, 0.15):
            p = centre.copy()
            p[a] = lo[a] + f * ext[a]
            for k in range(n_around):
                phi = 2.0 * np.pi * k / n_around
                d = -(np.cos(phi) * e[b] + np.sin(phi) * e[c])
                t = tool_frame(p, d, np.cross(e[a], d))
                out += [Grasp(r, "shape", "side") for r in _rolls(t, 2)]
        for sign, end in ((1.0, hi[a]), (-1.0, lo[a])):
            p = centre.copy()
            p[a] = end - sign * GRASP_DEPTH_M
            t = tool_frame(p, -sign * e[a], e[b])
            out += [Grasp(r, "shape", "end") for r in _rolls(t, 4)]
        return out
    if ext[order[2]] < FLAT_RATIO * ext[order[1]]:
        n_ax, u, v = int(order[2]), int(order[0]), int(order[1])
        for sign in (1.0, -1.0):
            for fu in (-0.3, 0.0, 0.3):
                for fv in (-0.3, 0.0, 0.3):
                    p = centre + fu * ext[u] * e[u] + fv * ext[v] * e[v]
                    p[n_ax] = (hi if sign > 0 else lo)[n_ax] - sign * GRASP_DEPTH_M
                    t = tool_frame(p, -sign * e[n_ax], e[u])
                    out += [Grasp(r, "shape", "face") for r in _rolls(t, 4)]
        for axis in (u, v):
            for sign in (1.0, -1.0):
                p = centre.copy()
                p[axis] = (hi if sign > 0 else lo)[axis] - sign * 2 * GRASP_DEPTH_M
                t = tool_frame(p, -sign * e[axis], e[n_ax])
                out += [Grasp(r, "shape", "edge") for r in _rolls(t, 2)]
        return out
    for axis in range(3):
        for sign in (1.0, -1.0):
            p = centre.copy()
            p[axis] = (hi if sign > 0 else lo)[axis] - sign * GRASP_DEPTH_M
            t = tool_frame(p, -sign * e[axis], e[(axis + 1) % 3])
            out += [Grasp(r, "shape", "face") for r in _rolls(t, 4)]
    return out


def rank_grasps(grasps: Sequence[Grasp], avoid: ArrayLike | None = None) -> list[Grasp]:
    """Order grasps: demonstrated ones first, then the farthest from ``avoid``.

    Parameters
    ----------
    grasps : sequence of Grasp
    avoid : array_like, shape (3,), optional
        A point of the part frame to keep the hand away from (where the part meets
        its parent at the goal), metres.
    """
    if avoid is None:
        return sorted(grasps, key=lambda g: g.source != "demo")
    p = np.asarray(avoid, dtype=np.float64)
    return sorted(
        grasps,
        key=lambda g: (g.source != "demo", -round(float(np.linalg.norm(g.pose[:3, 3] - p)), 3)),
    )


def demo_grasps(
    demo: Demonstration,
    part: str,
    before: float,
    *,
    window: float = 3.0,
    max_distance: float = 0.03,
    bbox: tuple[ArrayLike, ArrayLike] | None = None,
) -> list[Grasp]:
    """Where each hand held ``part`` in the ``window`` seconds before time ``before``.

    For every hand (fingers sharing ``BodyInfo.hand_body``), the last frame of the
    window whose fingertip centroid lies within ``max_distance`` of the part's
    bounding box (of its origin without one) gives one grasp.

    Parameters
    ----------
    demo : Demonstration
        With finger bodies (``kind == "finger"``) and the part's track.
    part : str
    before : float
        Seconds, demonstration time (the constraint's appearance).
    window : float
        Seconds searched before ``before``.
    max_distance : float
        Metres between the fingertip centroid and the part's box.
    bbox : (array_like (3,), array_like (3,)), optional
        The part's bounding box, body frame, metres.

    Returns
    -------
    list of Grasp
        Possibly empty (no fingers, or none near the part).
    """
    if part not in demo:
        return []
    fingers = [b for b in demo.bodies if b.kind == "finger"]
    hands: dict[str, list[str]] = {}
    for b in fingers:
        key = b.hand_body or b.hand or b.name
        hands.setdefault(key, []).append(b.name)
    mask = (demo.t >= before - window) & (demo.t <= before)
    frames = np.flatnonzero(mask & demo.valid(part))
    out: list[Grasp] = []
    if frames.size == 0:
        return out
    p_part = demo.pos(part)[frames]
    q_part = demo.quat(part)[frames]
    from thirdhand import se3

    t_wp = se3.matrix_from_pose(p_part, q_part)
    t_pw = invert(t_wp)
    for hand, names in sorted(hands.items()):
        pts = np.stack([demo.pos(n)[frames] for n in names], axis=1)  # (k, f, 3)
        ok = np.all(np.isfinite(pts), axis=(1, 2))
        local = np.einsum("kij,kfj->kfi", t_pw[:, :3, :3], pts) + t_pw[:, None, :3, 3]
        cen = local.mean(axis=1)
        near = ok & (_box_distance(cen, bbox) < max_distance)
        idx = np.flatnonzero(near)
        if idx.size == 0:
            continue
        k = int(idx[-1])
        thumb = [i for i, n in enumerate(names) if "thumb" in n]
        others = [i for i in range(len(names)) if i not in thumb]
        if not thumb or not others:
            continue
        closing = local[k, others].mean(axis=0) - local[k, thumb].mean(axis=0)
        if np.linalg.norm(closing) < 1e-6:
            continue
        approach = _core_point(cen[k], bbox) - cen[k]
        approach = approach - (approach @ closing) / (closing @ closing) * closing
        if np.linalg.norm(approach) < CORE_TOL_M:
            # The fingertips pinch the part's core (a board held across its thickness):
            # the hand came in along the fingers, across the line of the fingertips.
            approach = _finger_approach(local[k], thumb, others, closing, bbox)
        if np.linalg.norm(approach) < 1e-6:
            continue
        out.append(Grasp(tool_frame(cen[k], approach, closing), "demo", f"demo:{hand}"))
    return out


def square_to_box(grasps: Sequence[Grasp]) -> list[Grasp]:
    """Demonstrated grasps, each followed by its copy closing square to the part's faces.

    A hand's thumb and fingers meet a board at a slant a parallel gripper cannot hold:
    its jaws must close along the normal of the faces they press, and come in square to
    the edge they reach over. Where a grasp closes within 45° of one of the box's axes,
    the copy closes along that axis and keeps the demonstration's tool centre (where
    along the part the person held it) and its approach made perpendicular to the new
    closing direction — along the nearest box axis when within 45° of one (the side the
    person reached from). It is labelled ``"<label>/square"`` and comes right after the
    exact grasp.
    Shape grasps and grasps already square (within 1°) are returned as given.

    Parameters
    ----------
    grasps : sequence of Grasp
        ``T_part_tool``, part's body frame (a part's box is axis-aligned there: the
        frame's axes are its faces' normals).

    Returns
    -------
    list of Grasp
    """
    out: list[Grasp] = []
    for g in grasps:
        out.append(g)
        if g.source != "demo":
            continue
        y = g.pose[:3, 1]
        a = int(np.argmax(np.abs(y)))
        cos = abs(float(y[a]))
        if cos < np.cos(np.pi / 4) or cos > np.cos(np.deg2rad(1.0)):
            continue
        closing = np.sign(y[a]) * np.eye(3)[a]
        approach = g.pose[:3, 2] - (g.pose[:3, 2] @ closing) * closing
        if np.linalg.norm(approach) < 1e-6:
            continue
        approach = approach / np.linalg.norm(approach)
        b = int(np.argmax(np.abs(approach)))
        if abs(approach[b]) >= np.cos(np.pi / 4):  # square to the edge it reaches over
            approach = np.sign(approach[b]) * np.eye(3)[b]
        t = tool_frame(g.pose[:3, 3], approach, closing)
        out.append(Grasp(t, g.source, f"{g.label}/square"))
    return out


def within_fingers(
    grasps: Sequence[Grasp], bbox_min: ArrayLike, bbox_max: ArrayLike, *,
    depth: float = FINGER_DEPTH_M,
) -> list[Grasp]:  # fmt: skip
    """Demonstrated grasps moved to where a parallel gripper's fingers can hold them.

    A person's fingertips may hold a board deep inside its edge or off its middle; the
    gripper's fingers reach ``depth`` past the tool point toward the hand before its
    casing, and they close symmetrically about the tool point. Each demonstrated grasp
    whose part reaches farther than ``depth`` behind the tool point (along the approach,
    toward the hand) is slid back along its approach until it reaches ``depth``; one held
    by its edge is slid deeper toward the box's middle, as far as ``depth`` allows (flat
    pads on a round leg's shoulder, above its axis, squeeze it out of the hand as the
    arm accelerates: a rod's grasp goes onto its axis, backed off only as far as
    ``depth`` needs); and its tool point is centred between the box's faces along the
    closing direction (held off centre, the part is pushed across in the hand as the
    fingers close and placed off its goal by as much). A grasp whose fingers would close
    along a side of the box wider than the gripper opens (:data:`MAX_GRIP_M`; a hand
    holding a leg from its end, the thumb along it) is first turned a quarter about its
    approach, so that they close across it. Shape grasps are returned as given
    (:func:`between_fingers` fits them).

    Parameters
    ----------
    grasps : sequence of Grasp
        ``T_part_tool``, part's body frame.
    bbox_min, bbox_max : array_like, shape (3,)
        The part's bounding box, body frame, metres.
    depth : float
        Metres of the fingers past the tool point, toward the hand.
    """
    lo = np.asarray(bbox_min, dtype=np.float64)
    hi = np.asarray(bbox_max, dtype=np.float64)
    ext = hi - lo
    out: list[Grasp] = []
    for g in grasps:
        if g.source != "demo":
            out.append(g)
            continue
        t = g.pose.copy()
        if _width_across(t[:3, 1], lo, hi) > MAX_GRIP_M:
            # the fingers would close along the part's long side: a quarter turn about
            # the approach closes them across it
            t[:3, :2] = np.column_stack([t[:3, 1], -t[:3, 0]])
        p, closing, approach = t[:3, 3].copy(), t[:3, 1], t[:3, 2]
        long_axis = int(np.argmax(ext))
        across = [k for k in range(3) if k != long_axis]
        if ext[long_axis] >= ROD_RATIO * ext[across].max():
            # a rod: the tool point onto its axis (where it is along it), backed off
            # along the approach as far as the fingers' depth needs
            p[across] = ((lo + hi) / 2.0)[across]
            p = p - max(0.0, float(ext[across].max()) / 2.0 - depth) * approach
        else:
            p = p + _depth_shift(p, approach, lo, hi, depth) * approach
        if bool(np.all(p >= lo - 1e-9) and np.all(p <= hi + 1e-9)):
            p = _centred_along(p, closing, lo, hi)
        t[:3, 3] = p
        out.append(Grasp(t, g.source, g.label))
    return out


def _depth_shift(
    p: FloatArray, approach: FloatArray, lo: FloatArray, hi: FloatArray, depth: float
) -> float:
    """How far to move a tool point along its approach: the box's middle onto it, or near.

    Along the approach the box spans ``[u_lo, u_hi]`` from ``p``; moved by ``s`` its
    middle is ``(u_lo + u_hi) / 2 - s`` ahead of the tool point and ``s - u_lo``
    of it lies behind (toward the hand), at most ``depth``.
    """
    corners = np.array([[(hi if (i >> k) & 1 else lo)[k] for k in range(3)] for i in range(8)])
    u = (corners - p) @ approach
    u_lo, u_hi = float(u.min()), float(u.max())
    return min((u_lo + u_hi) / 2.0, depth + u_lo)


def between_fingers(
    grasps: Sequence[Grasp], bbox_min: ArrayLike, bbox_max: ArrayLike, *,
    width: float = MAX_GRIP_M,
) -> list[Grasp]:  # fmt: skip
    """Shape grasps a parallel gripper can close on: the part fits between the fingers.

    A shape grasp of a board may close across its length (a face grasp rolled about
    its approach): the fingers cannot open that wide, and one finger ends on an edge.
    Each shape grasp whose box is wider than ``width`` along the box axis nearest to
    the closing direction is dropped (a rod's box is as wide as its thickest end, so
    a tapered leg is kept); the others are centred between
    the box's faces along it, so that the fingers meet the part together. Grasps
    from a demonstration are returned as given (:func:`within_fingers` fits them).

    Parameters
    ----------
    grasps : sequence of Grasp
        ``T_part_tool``, part's body frame.
    bbox_min, bbox_max : array_like, shape (3,)
        The part's bounding box, body frame, metres.
    width : float
        Widest part the fingers close on, metres.
    """
    lo = np.asarray(bbox_min, dtype=np.float64)
    hi = np.asarray(bbox_max, dtype=np.float64)
    out: list[Grasp] = []
    for g in grasps:
        if g.source != "shape":
            out.append(g)
            continue
        t = g.pose.copy()
        p, closing = t[:3, 3], t[:3, 1]
        if _width_across(closing, lo, hi) > width:
            continue
        t[:3, 3] = _centred_along(p, closing, lo, hi)
        out.append(Grasp(t, g.source, g.label))
    return out


def _ray_t(tri: FloatArray, origins: FloatArray, d: FloatArray) -> FloatArray:
    """Distances (n, t) along ``d`` from each origin to each triangle (inf: missed or behind)."""
    a, e1, e2 = tri[:, 0], tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    h = np.cross(d, e2)  # (t, 3)
    det = np.einsum("ij,ij->i", e1, h)
    ok = np.abs(det) > 1e-15
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = origins[:, None, :] - a[None]  # (n, t, 3)
    u = np.einsum("ntj,tj->nt", s, h) * inv
    qv = np.cross(s, e1[None])
    v = (qv @ d) * inv
    t = np.einsum("ntj,tj->nt", qv, e2) * inv
    hit = ok & (u >= 0.0) & (v >= 0.0) & (u + v <= 1.0) & (t > 0.0)
    return np.where(hit, t, np.inf)


def _chunks(n: int, tri: FloatArray) -> list[slice]:
    """Slices of ``n`` points small enough that a (points, triangles) array stays ~4 MB."""
    size = max(1, 500_000 // max(len(tri), 1))
    return [slice(k, min(k + size, n)) for k in range(0, n, size)]


def first_hit(triangles: ArrayLike, origins: ArrayLike, direction: ArrayLike) -> FloatArray:
    """Distance (n,) from each origin along ``direction`` (unit) to the mesh; inf on a miss."""
    tri = np.asarray(triangles, dtype=np.float64)
    pts = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
    d = np.asarray(direction, dtype=np.float64)
    out = np.full(len(pts), np.inf)
    for sl in _chunks(len(pts), tri):
        out[sl] = _ray_t(tri, pts[sl], d).min(axis=1)
    return out


def inside_mesh(triangles: ArrayLike, points: ArrayLike) -> NDArray[np.bool_]:
    """Whether each point lies inside a closed triangle mesh (ray parity, three rays voting).

    Parameters
    ----------
    triangles : array_like, shape (t, 3, 3)
        The mesh, any frame, metres.
    points : array_like, shape (n, 3)
        Same frame.

    Returns
    -------
    ndarray of bool, shape (n,)
    """
    tri = np.asarray(triangles, dtype=np.float64)
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    votes = np.zeros(len(pts), dtype=np.int64)
    for d in _RAYS:
        for sl in _chunks(len(pts), tri):
            hits = np.isfinite(_ray_t(tri, pts[sl], d))
            votes[sl] += np.count_nonzero(hits, axis=1) % 2
    return np.asarray(votes >= 2)


#: :func:`pinch_grasps` of the meshes seen in this process, by their triangles' digest and
#: the parameters: a part's scan costs seconds, and every episode of ``generate`` plans
#: the same parts again.
_PINCH_CACHE: dict[tuple[bytes, tuple[Any, ...]], tuple[Grasp, ...]] = {}


def pinch_grasps(
    triangles: ArrayLike,
    *,
    step: float = 0.01,
    depth: float = GRASP_DEPTH_M,
    width: float = MAX_GRIP_M - 0.01,
    clearance: float = 0.008,
    pad: tuple[float, float] = PAD_HALF_M,
    axes: Sequence[int] = (0, 1, 2),
) -> list[Grasp]:
    """Grasps on the narrow features of a part's mesh that its bounding box hides.

    A board with slats is too wide for the fingers as a box, but a slat is not. From
    each of the six body axes, tool points on a grid (``step`` apart) a ``depth`` under
    the surface the fingers come through are kept where, along either other axis, the
    material there is at most ``width`` across (the point is centred in it), the pad's
    corners lie in it, and a finger (``clearance`` beside the material, from the
    surface down past the pad, across the pad's width) meets nothing: the fingers go
    down the gaps beside it. Each mesh is scanned once per process (by its triangles'
    digest and the parameters).

    Parameters
    ----------
    triangles : array_like, shape (t, 3, 3)
        The part's closed mesh, body frame, metres.
    axes : sequence of int
        The body axes the fingers come along (both ways).

    Returns
    -------
    list of Grasp
        ``T_part_tool`` with source ``"shape"`` and label ``"pinch"``, unranked.
    """
    tri = np.ascontiguousarray(triangles, dtype=np.float64)
    key = (
        hashlib.sha1(tri.tobytes()).digest(),
        (step, depth, width, clearance, tuple(pad), tuple(axes)),
    )
    if key not in _PINCH_CACHE:
        if len(_PINCH_CACHE) >= 64:
            _PINCH_CACHE.clear()
        _PINCH_CACHE[key] = tuple(
            _pinch_scan(tri, step=step, depth=depth, width=width, clearance=clearance,
                        pad=pad, axes=axes)
        )  # fmt: skip
    return list(_PINCH_CACHE[key])


def _pinch_scan(
    tri: FloatArray,
    *,
    step: float,
    depth: float,
    width: float,
    clearance: float,
    pad: tuple[float, float],
    axes: Sequence[int],
) -> list[Grasp]:
    """The scan of :func:`pinch_grasps` (same parameters), uncached."""
    v = tri.reshape(-1, 3)
    lo, hi = v.min(axis=0) - 1e-3, v.max(axis=0) + 1e-3
    e = np.eye(3)
    hx, hz = pad
    out: list[Grasp] = []
    for ai in axes:
        for sign in (1.0, -1.0):
            a = -sign * e[ai]  # the approach, into the part from its ``sign`` side
            for ci in (k for k in range(3) if k != ai):
                bi = 3 - ai - ci
                c, b = e[ci], np.cross(a, e[ci])
                us = np.arange(lo[ci] + step / 2, hi[ci], step)
                vs = np.arange(lo[bi] + step / 2, hi[bi], step)
                uu, vv = (g.ravel() for g in np.meshgrid(us, vs, indexing="ij"))
                start = np.zeros((len(uu), 3))
                start[:, ci], start[:, bi] = uu, vv
                start[:, ai] = hi[ai] if sign > 0 else lo[ai]
                t0 = first_hit(tri, start, a)
                ok = np.isfinite(t0)
                top = start[ok] + t0[ok, None] * a
                p = top + depth * a
                plus = first_hit(tri, p, c)
                minus = first_hit(tri, p, -c)
                w = plus + minus
                keep = (w <= width) & (w >= 2.0 * hx)
                p, top, plus, minus, w = p[keep], top[keep], plus[keep], minus[keep], w[keep]
                p = p + ((plus - minus) / 2.0)[:, None] * c
                if len(p) == 0:
                    continue
                corners = np.array([[hx, hz], [hx, -hz], [-hx, hz], [-hx, -hz]])
                solid = np.concatenate([p + cb[0] * b + cb[1] * a for cb in corners])
                fingers = []
                for side in (1.0, -1.0):
                    for f in np.linspace(-0.005, depth + hz, 4):
                        for across in (-hx, 0.0, hx):
                            fingers.append(
                                top
                                + ((w / 2.0 + clearance) * side)[:, None] * c
                                + (f * a + across * b)[None]
                            )
                free = np.concatenate(fingers)
                n = len(p)
                good = inside_mesh(tri, np.concatenate([p, solid]))
                good_p, good_c = good[:n], good[n:].reshape(len(corners), n).all(axis=0)
                clear = ~inside_mesh(tri, free).reshape(-1, n).any(axis=0)
                for q in p[good_p & good_c & clear]:
                    out.append(Grasp(tool_frame(q, a, c), "shape", "pinch"))
    return out


def mesh_centroid(triangles: ArrayLike) -> FloatArray:
    """Centre of mass (3,) of the solid a closed mesh (t, 3, 3) bounds, uniform density;
    its vertices' mean when it encloses no volume."""
    tri = np.asarray(triangles, dtype=np.float64)
    vol = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2]))
    total = float(vol.sum())
    if abs(total) < 1e-12:
        return np.asarray(tri.reshape(-1, 3).mean(axis=0), dtype=np.float64)
    return np.asarray((vol[:, None] * tri.sum(axis=1)).sum(axis=0) / (4.0 * total))


def is_wide_plate(bbox_min: ArrayLike, bbox_max: ArrayLike) -> bool:
    """Whether a part is a plate no parallel gripper closes on whole: flat (its thinnest
    extent under :data:`FLAT_RATIO` times the next) and wider than :data:`MAX_GRIP_M`
    both ways in its plane."""
    ext = np.sort(np.asarray(bbox_max, dtype=np.float64) - np.asarray(bbox_min))
    return bool(ext[0] < FLAT_RATIO * ext[1] and ext[1] > MAX_GRIP_M)


def nearest_com(grasps: Sequence[Grasp], com: ArrayLike, n: int) -> list[Grasp]:
    """The ``n`` grasps whose tool points lie nearest the centre of mass ``com`` (body
    frame): a part held by friction far from it turns out of the fingers under its own
    weight (the chair's 2.2 kg back held by its top rail, 15 cm off: 3.2 N·m)."""
    c = np.asarray(com, dtype=np.float64)
    d = [float(np.linalg.norm(g.pose[:3, 3] - c)) for g in grasps]
    order = np.argsort(d, kind="stable")[:n]
    return [grasps[int(i)] for i in order]


def on_material(
    grasps: Sequence[Grasp], triangles: ArrayLike, *, pad: tuple[float, float] = PAD_HALF_M
) -> list[Grasp]:
    """The grasps whose fingertip pads close on the part, not on a gap in it.

    A shape grasp comes from the part's bounding box: on a chair's back with slats it
    may close where the box is and the board is not. A grasp is kept when the tool
    point and at least three of the pad's four corners (``pad``: half extents along
    the tool's x and its approach, metres; in the plane between the fingers) lie
    inside the part's closed mesh (:func:`inside_mesh`).

    Parameters
    ----------
    grasps : sequence of Grasp
        ``T_part_tool``, part's body frame.
    triangles : array_like, shape (t, 3, 3)
        The part's closed mesh, body frame, metres.
    """
    if not grasps:
        return []
    hx, hz = pad
    local = np.array([[0.0, 0.0, 0.0], [hx, 0, hz], [hx, 0, -hz], [-hx, 0, hz], [-hx, 0, -hz]])
    pts = np.concatenate([local @ g.pose[:3, :3].T + g.pose[:3, 3] for g in grasps])
    inside = inside_mesh(triangles, pts).reshape(len(grasps), len(local))
    return [g for g, row in zip(grasps, inside, strict=True) if row[0] and row[1:].sum() >= 3]


def rod_turns(
    grasps: Sequence[Grasp], bbox_min: ArrayLike, bbox_max: ArrayLike, *, n: int = 12
) -> list[Grasp]:
    """Demonstrated grasps of a rod turned about its long axis, ``n`` turns each.

    A rod lying on the table rests at any spin about its axis, and a hand that
    came from above when the person picked it may have to come from below where
    it lies now. Turning the grasp about the rod's axis (through the middle of
    its cross-section) keeps what the demonstration says about a rod: where
    along it the hand held it and at what angle to the axis. The copies keep the
    source ``"demo"``, labelled with their turn (``"demo:rh@90"``); the exact
    grasp comes first. Non-rods (no extent ≥ 1.8 × the others) are returned as given.

    Parameters
    ----------
    grasps : sequence of Grasp
        Grasps of the part, ``T_part_tool``.
    bbox_min, bbox_max : array_like, shape (3,)
        The part's bounding box, body frame, metres.
    n : int
        Turns (the identity included), ``2π k / n``.

    Returns
    -------
    list of Grasp
        For each grasp, the exact one then its ``n - 1`` turned copies.
    """
    lo = np.asarray(bbox_min, dtype=np.float64)
    hi = np.asarray(bbox_max, dtype=np.float64)
    ext = hi - lo
    order = np.argsort(-ext, kind="stable")
    if ext[order[0]] < ROD_RATIO * ext[order[1]]:
        return list(grasps)
    a = int(order[0])
    centre = (lo + hi) / 2.0
    out: list[Grasp] = []
    for g in grasps:
        out.append(g)
        for k in range(1, n):
            ang = 2.0 * np.pi * k / n
            c, s_ = np.cos(ang), np.sin(ang)
            b, d = (a + 1) % 3, (a + 2) % 3
            r = np.eye(4)
            r[b, b], r[b, d], r[d, b], r[d, d] = c, -s_, s_, c
            shift = np.eye(4)
            shift[:3, 3] = centre
            shift[a, 3] = 0.0
            turn = shift @ r @ invert(shift)
            out.append(Grasp(turn @ g.pose, g.source, f"{g.label}@{round(np.degrees(ang))}"))
    return out


def _finger_approach(
    tips: FloatArray,
    thumb: Sequence[int],
    others: Sequence[int],
    closing: FloatArray,
    bbox: tuple[ArrayLike, ArrayLike] | None,
) -> FloatArray:
    """The hand's approach (3,) from its fingertips (k, 3), part frame, for a pinch of the core.

    The fingers lie side by side across the direction they point in: the approach is
    perpendicular to the closing direction and to the line through the non-thumb tips
    (the farthest pair), or, with a single such tip, to the closing direction and the
    part's nearest face. Its sign puts the hand outside: the approach points away from
    the nearer of the part's two faces along it (the edge the hand reached over).
    Zero when neither rule gives a direction.
    """
    unit = closing / np.linalg.norm(closing)
    lo, hi = (None, None) if bbox is None else (np.asarray(bbox[0]), np.asarray(bbox[1]))
    cen = tips.mean(axis=0)
    axis = np.zeros(3)
    if len(others) >= 2:
        pts = tips[list(others)]
        gaps = pts[:, None, :] - pts[None, :, :]
        i, j = np.unravel_index(np.argmax(np.linalg.norm(gaps, axis=2)), gaps.shape[:2])
        axis = np.cross(unit, gaps[i, j])
    if np.linalg.norm(axis) < FINGER_SPREAD_M * 0.5:
        if lo is None or hi is None:
            return np.zeros(3)
        # the box axis across the closing direction whose face is nearest
        best = np.inf
        for a in range(3):
            e = np.eye(3)[a]
            e = e - (e @ unit) * unit
            if np.linalg.norm(e) < np.sin(np.pi / 4):  # within 45° of the closing direction
                continue
            d = min(cen[a] - lo[a], hi[a] - cen[a])
            if d < best:
                best, axis = d, e
    axis = axis / np.linalg.norm(axis)
    if lo is None or hi is None:
        return np.asarray(axis, dtype=np.float64)
    # the distance to the box's boundary going back along -axis and along +axis
    back = _exit_distance(cen, -axis, lo, hi)
    ahead = _exit_distance(cen, axis, lo, hi)
    return np.asarray(axis if back <= ahead else -axis, dtype=np.float64)


def _width_across(closing: FloatArray, lo: FloatArray, hi: FloatArray) -> float:
    """How wide the box ``[lo, hi]`` is along the box axis nearest to ``closing``, metres."""
    return float((hi - lo)[int(np.argmax(np.abs(closing)))])


def _centred_along(p: FloatArray, d: FloatArray, lo: FloatArray, hi: FloatArray) -> FloatArray:
    """``p`` (3,) inside the box ``[lo, hi]`` moved along ``d`` to midway between its faces."""
    ahead, back = _exit_distance(p, d, lo, hi), _exit_distance(p, -d, lo, hi)
    return np.asarray(p + (ahead - back) / 2.0 * d, dtype=np.float64)


def _exit_distance(p: FloatArray, d: FloatArray, lo: FloatArray, hi: FloatArray) -> float:
    """How far the ray ``p + s d`` (s ≥ 0) runs inside the box ``[lo, hi]``, metres."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(d > 0, (hi - p) / d, np.where(d < 0, (lo - p) / d, np.inf))
    return float(max(np.min(t), 0.0))


def _core_point(p: FloatArray, bbox: tuple[ArrayLike, ArrayLike] | None) -> FloatArray:
    """The point of a box's core nearest ``p`` (3,): its axis for a rod, mid-plane for a plate.

    The core is the box shrunk by its smallest half extent on every side.
    """
    if bbox is None:
        return np.zeros(3)
    lo = np.asarray(bbox[0], dtype=np.float64)
    hi = np.asarray(bbox[1], dtype=np.float64)
    half = (hi - lo) / 2.0
    c = (hi + lo) / 2.0
    keep = half - half.min()
    return np.asarray(np.clip(p, c - keep, c + keep), dtype=np.float64)


def _box_distance(p: FloatArray, bbox: tuple[ArrayLike, ArrayLike] | None) -> FloatArray:
    """Distance of points ``p`` (k, 3) from a box (from the origin without one), metres."""
    if bbox is None:
        return np.asarray(np.linalg.norm(p, axis=1), dtype=np.float64)
    lo = np.asarray(bbox[0], dtype=np.float64)
    hi = np.asarray(bbox[1], dtype=np.float64)
    return np.asarray(np.linalg.norm(p - np.clip(p, lo, hi), axis=1), dtype=np.float64)
