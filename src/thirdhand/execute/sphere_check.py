"""Batched, conservative collision tests of a world of sphere covers, compiled with numba.

The fast layer under :class:`~thirdhand.execute.collision_check.SceneChecks`.
Every body of the world is a :class:`~thirdhand.execute.spheres.SphereCover`
fixed to a frame — the world (tables, placed parts, the robot's base) or one of
the arm's joints (links, and the grasped part through the tool) — except static
boxes, kept as exact boxes. For each configuration of a batch the kernels
compute the joint frames (forward kinematics from the pinocchio model's joint
placements, :func:`~thirdhand.execute.kinematics.joint_transforms_nb`) and test every active
pair of bodies
through a three-level hierarchy: the two bodies' bounding spheres, their groups,
their spheres. A pair is *flagged* when some sphere of one comes within the
pair's margin of some sphere (or the box) of the other. The covers hold every
point coal counts as part of a body, so an unflagged pair is certainly free in
coal's exact check; a flagged pair may still be free (the caller asks coal).

Arrays (built by :func:`pack`): spheres ``(S, 4)`` (centre in the body's frame,
metres; radius); groups ``(G, 4)`` with ``group_range (G, 2)``; per body
``frame`` (joint index, -1 for the world), ``kind`` (0 spheres, 1 box), ``bound
(B, 4)``, ``body_groups (B, 2)``, and for boxes ``box_inv (B, 4, 4)``
(``T_box_world``) and ``box_half (B, 3)``; pairs ``(P, 2)`` with ``margin (P,)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from thirdhand.arrays import BoolArray, FloatArray, IntArray
from thirdhand.execute.kinematics import _fk, joint_local, joint_transforms_nb, sincos
from thirdhand.execute.spheres import SphereCover

__all__ = ["ChainArrays", "PairBlocks", "SphereWorld", "flags", "free", "joint_transforms_nb",
           "pack", "pair_blocks", "path_flagged", "sorted_margins", "warm_up"]  # fmt: skip


SPHERES = 0
BOX = 1
_NO_LANES = np.zeros((0, 1), dtype=np.bool_)


@dataclass(frozen=True)
class ChainArrays:
    """The arm's kinematic chain as arrays for the kernels (:class:`.kinematics.Chain`)."""

    placements: FloatArray  # (dof, 4, 4) T_parent_joint at zero angle
    axes: FloatArray  # (dof, 3) unit axis in the joint frame
    parents: IntArray  # (dof,) parent joint, -1 for the world


@dataclass(frozen=True)
class SphereWorld:
    """Sphere covers of every body of a world and its active pairs, packed for the kernels."""

    spheres: FloatArray
    groups: FloatArray
    group_range: IntArray
    frame: IntArray
    kind: IntArray
    bound: FloatArray
    body_groups: IntArray
    box_inv: FloatArray
    box_half: FloatArray


def pack(
    covers: list[SphereCover | None],
    frames: list[int],
    boxes: dict[int, tuple[FloatArray, FloatArray]],
) -> SphereWorld:
    """Pack the bodies of a world for the kernels.

    Parameters
    ----------
    covers : list of SphereCover or None
        Per body, its cover in its frame (None for a box, see ``boxes``).
    frames : list of int
        Per body, the joint it is fixed to, -1 for the world.
    boxes : dict
        Body index → (``T_world_box`` (4, 4), half extents (3,)) of static boxes.
    """
    n = len(covers)
    spheres, groups, ranges = [], [], []
    body_groups = np.zeros((n, 2), dtype=np.int64)
    bound = np.zeros((n, 4))
    box_inv = np.tile(np.eye(4), (n, 1, 1))
    box_half = np.zeros((n, 3))
    kind = np.zeros(n, dtype=np.int64)
    n_s = n_g = 0
    for b, cover in enumerate(covers):
        if cover is None:
            t, half = boxes[b]
            kind[b] = BOX
            box_inv[b] = np.linalg.inv(t)
            box_half[b] = half
            bound[b, :3] = t[:3, 3]
            bound[b, 3] = float(np.linalg.norm(half)) + 1e-6
            body_groups[b] = (n_g, n_g)
            continue
        spheres.append(cover.spheres)
        groups.append(cover.groups)
        ranges.append(cover.group_range + n_s)
        body_groups[b] = (n_g, n_g + len(cover.groups))
        bound[b] = cover.bound
        n_s += len(cover.spheres)
        n_g += len(cover.groups)
    return SphereWorld(
        spheres=np.vstack(spheres) if spheres else np.zeros((0, 4)),
        groups=np.vstack(groups) if groups else np.zeros((0, 4)),
        group_range=(np.vstack(ranges) if ranges else np.zeros((0, 2))).astype(np.int64),
        frame=np.asarray(frames, dtype=np.int64),
        kind=kind,
        bound=bound,
        body_groups=body_groups,
        box_inv=box_inv,
        box_half=box_half,
    )


@numba.njit(cache=True, inline="always")
def _move(m: FloatArray, src: FloatArray, k: int, dst: FloatArray) -> None:
    """``dst[k] = m · src[k]`` (centre moved by the rigid transform m (4, 4), radius kept)."""
    x, y, z = src[k, 0], src[k, 1], src[k, 2]
    dst[k, 0] = m[0, 0] * x + m[0, 1] * y + m[0, 2] * z + m[0, 3]
    dst[k, 1] = m[1, 0] * x + m[1, 1] * y + m[1, 2] * z + m[1, 3]
    dst[k, 2] = m[2, 0] * x + m[2, 1] * y + m[2, 2] * z + m[2, 3]
    dst[k, 3] = src[k, 3]


@numba.njit(cache=True, inline="always")
def _near(a: FloatArray, i: int, b: FloatArray, j: int, margin: float) -> bool:
    """Spheres ``a[i]`` and ``b[j]`` closer than ``margin`` (or overlapping)."""
    dx, dy, dz = a[i, 0] - b[j, 0], a[i, 1] - b[j, 1], a[i, 2] - b[j, 2]
    r = a[i, 3] + b[j, 3] + margin
    return dx * dx + dy * dy + dz * dz <= r * r


@numba.njit(cache=True, inline="always")
def _near_box(a: FloatArray, i: int, inv: FloatArray, half: FloatArray, b: int,
              margin: float) -> bool:  # fmt: skip
    """Sphere ``a[i]`` closer than ``margin`` to box ``b`` (or inside it)."""
    acc = 0.0
    x, y, z = a[i, 0], a[i, 1], a[i, 2]
    for k in range(3):
        v = inv[b, k, 0] * x + inv[b, k, 1] * y + inv[b, k, 2] * z + inv[b, k, 3]
        e = abs(v) - half[b, k]
        if e > 0.0:
            acc += e * e
    r = a[i, 3] + margin
    return acc <= r * r


@numba.njit(cache=True, inline="always")
def _sides_near(t: FloatArray, sides: FloatArray, blk: int, fa: int, fb: int,
                margin: float) -> bool:  # fmt: skip
    """The spheres around the bodies of each side of block ``blk`` (``sides`` (K, 2, 4), in
    the sides' frames ``fa`` and ``fb``, -1 the world) closer than ``margin``."""
    ax, ay, az = sides[blk, 0, 0], sides[blk, 0, 1], sides[blk, 0, 2]
    bx, by, bz = sides[blk, 1, 0], sides[blk, 1, 1], sides[blk, 1, 2]
    if fa >= 0:
        m = t[fa]
        ax, ay, az = (m[0, 0] * ax + m[0, 1] * ay + m[0, 2] * az + m[0, 3],
                      m[1, 0] * ax + m[1, 1] * ay + m[1, 2] * az + m[1, 3],
                      m[2, 0] * ax + m[2, 1] * ay + m[2, 2] * az + m[2, 3])  # fmt: skip
    if fb >= 0:
        m = t[fb]
        bx, by, bz = (m[0, 0] * bx + m[0, 1] * by + m[0, 2] * bz + m[0, 3],
                      m[1, 0] * bx + m[1, 1] * by + m[1, 2] * bz + m[1, 3],
                      m[2, 0] * bx + m[2, 1] * by + m[2, 2] * bz + m[2, 3])  # fmt: skip
    dx, dy, dz = ax - bx, ay - by, az - bz
    r = sides[blk, 0, 3] + sides[blk, 1, 3] + margin
    return dx * dx + dy * dy + dz * dz <= r * r


@numba.njit(cache=True, inline="always")
def _flag_config(t: FloatArray, key: int, spheres: FloatArray, groups: FloatArray,
                 group_range: IntArray, frame: IntArray, kind: IntArray, bound: FloatArray,
                 body_groups: IntArray, box_inv: FloatArray, box_half: FloatArray,
                 clusters: FloatArray, cluster_frame: IntArray, sides: FloatArray,
                 pairs: IntArray, margins: FloatArray, blocks: IntArray,
                 block_margin: FloatArray, every: bool,
                 wc: FloatArray, wb: FloatArray, wg: FloatArray, ws: FloatArray,
                 stamps: IntArray, out: BoolArray, row: int, near: BoolArray,
                 lane: int) -> bool:  # fmt: skip
    """Flag the pairs of one configuration (joint frames ``t``) in ``out[row]``; True if any.

    ``every``: flag every pair, else stop at the first. ``key`` identifies the
    configuration in ``stamps`` (3, max(B, G)): the configuration a body's bound, a
    group's centre and a group's spheres were last moved for (moving bodies are moved
    only when a test needs them). ``wc``, ``wb``, ``wg``, ``ws``: see :func:`_run`.
    ``lane`` ≥ 0: the blocks' cluster tests are already made, ``near[:, lane]`` (K, lanes)
    (:func:`_lanes_near`); -1: made here.
    """
    bstamp, gstamp, sstamp = stamps[0], stamps[1], stamps[2]
    if lane < 0:
        for c in range(clusters.shape[0]):
            if cluster_frame[c] >= 0:
                _move(t[cluster_frame[c]], clusters, c, wc)
    flagged = False
    for blk in range(blocks.shape[0]):
        ca, cb = blocks[blk, 2], blocks[blk, 3]
        fa, fb = cluster_frame[ca], cluster_frame[cb]
        if lane >= 0:
            if not near[blk, lane]:
                continue
        # A fixed box is its own cluster (frame -2 - body): the cluster sphere against the
        # box itself, not the box's bounding sphere (a table's is a metre wide).
        elif fb <= -2:
            if fa > -2 and not _near_box(wc, ca, box_inv, box_half, -2 - fb, block_margin[blk]):
                continue
        elif fa <= -2:
            if not _near_box(wc, cb, box_inv, box_half, -2 - fa, block_margin[blk]):
                continue
        elif not _near(wc, ca, wc, cb, block_margin[blk]):
            continue
        elif blocks[blk, 4] and not _sides_near(t, sides, blk, fa, fb, block_margin[blk]):
            continue
        for p in range(blocks[blk, 0], blocks[blk, 1]):
            a, b = pairs[p, 0], pairs[p, 1]
            m = margins[p]
            if kind[a] == BOX:
                a, b = b, a
            hit = False
            for e in (a, b):
                if frame[e] >= 0 and bstamp[e] != key:
                    bstamp[e] = key
                    _move(t[frame[e]], bound, e, wb)
            if kind[a] == BOX:
                hit = True  # two boxes: left to coal
            elif kind[b] == BOX:
                if not _near_box(wb, a, box_inv, box_half, b, m):
                    continue
                for g in range(body_groups[a, 0], body_groups[a, 1]):
                    if frame[a] >= 0 and gstamp[g] != key:
                        gstamp[g] = key
                        _move(t[frame[a]], groups, g, wg)
                    if not _near_box(wg, g, box_inv, box_half, b, m):
                        continue
                    if frame[a] >= 0 and sstamp[g] != key:
                        sstamp[g] = key
                        for k in range(group_range[g, 0], group_range[g, 1]):
                            _move(t[frame[a]], spheres, k, ws)
                    for k in range(group_range[g, 0], group_range[g, 1]):
                        if _near_box(ws, k, box_inv, box_half, b, m):
                            hit = True
                            break
                    if hit:
                        break
            elif _near(wb, a, wb, b, m):
                for e in (a, b):
                    if frame[e] >= 0:
                        for g in range(body_groups[e, 0], body_groups[e, 1]):
                            if gstamp[g] != key:
                                gstamp[g] = key
                                _move(t[frame[e]], groups, g, wg)
                for ga in range(body_groups[a, 0], body_groups[a, 1]):
                    if not _near(wg, ga, wb, b, m):
                        continue
                    for gb in range(body_groups[b, 0], body_groups[b, 1]):
                        if not _near(wg, ga, wg, gb, m):
                            continue
                        for g, f in ((ga, frame[a]), (gb, frame[b])):
                            if f >= 0 and sstamp[g] != key:
                                sstamp[g] = key
                                for k in range(group_range[g, 0], group_range[g, 1]):
                                    _move(t[f], spheres, k, ws)
                        for sa in range(group_range[ga, 0], group_range[ga, 1]):
                            if not _near(ws, sa, wg, gb, m):
                                continue
                            for sb in range(group_range[gb, 0], group_range[gb, 1]):
                                if _near(ws, sa, ws, sb, m):
                                    hit = True
                                    break
                            if hit:
                                break
                        if hit:
                            break
                    if hit:
                        break
            if hit:
                out[row, p] = True
                flagged = True
                if not every:
                    return True
    return flagged


@numba.njit(cache=True, nogil=True)
def _run(qs: FloatArray, placements: FloatArray, axes: FloatArray, parents: IntArray,
         spheres: FloatArray, groups: FloatArray, group_range: IntArray, frame: IntArray,
         kind: IntArray, bound: FloatArray, body_groups: IntArray, box_inv: FloatArray,
         box_half: FloatArray, clusters: FloatArray, cluster_frame: IntArray,
         sides: FloatArray, pairs: IntArray, margins: FloatArray, blocks: IntArray,
         block_margin: FloatArray, stop: int, wc: FloatArray, wb: FloatArray, wg: FloatArray,
         ws: FloatArray, stamps: IntArray, out: BoolArray, hits: BoolArray) -> int:  # fmt: skip
    """Fill ``hits`` (n,) with whether a configuration has a flagged pair, and ``out`` with
    the pair flags; returns the first flagged config or -1.

    ``stop``: 0 flags every pair of every configuration in ``out`` (n, P); 1 stops each
    configuration at its first flagged pair, ``out`` (1, P) then only scratch. ``wc``,
    ``wb``, ``wg``, ``ws`` are scratch copies of ``clusters``, ``bound``, ``groups``,
    ``spheres`` (the fixed entries already in world coordinates); ``stamps`` (3, max(B, G))
    scratch too (see :func:`_flag_config`).

    Configurations go :data:`LANES` at a time through forward kinematics (:func:`_fk_lanes`)
    and the blocks' cluster and side tests (:func:`_lanes_near`); one that some block leaves
    near goes on alone to those blocks' pairs (:func:`_flag_config`).
    """
    n, dof = qs.shape
    t = np.empty((dof, 4, 4))
    t[:, 3, :3] = 0.0
    t[:, 3, 3] = 1.0
    tl = np.empty((dof + 1, 12, LANES))
    near = np.empty((blocks.shape[0], LANES), dtype=np.bool_)
    cl = np.empty((clusters.shape[0], 3, LANES))
    for c in range(clusters.shape[0]):
        for k in range(3):
            cl[c, k, :] = clusters[c, k]
    stamps[:] = -1
    first = -1
    for i0 in range(0, n, LANES):
        _fk_lanes(qs, i0, placements, axes, parents, tl)
        _lanes_near(tl, clusters, cluster_frame, cl, box_inv, box_half, sides, blocks,
                    block_margin, near)  # fmt: skip
        for lane in range(min(LANES, n - i0)):
            i = i0 + lane
            some = False
            for blk in range(blocks.shape[0]):
                if near[blk, lane]:
                    some = True
                    break
            hit = False
            if some:
                for j in range(dof):
                    for r in range(3):
                        for col in range(4):
                            t[j, r, col] = tl[j, 4 * r + col, lane]
                hit = _flag_config(t, i, spheres, groups, group_range, frame, kind, bound,
                                   body_groups, box_inv, box_half, clusters, cluster_frame,
                                   sides, pairs, margins, blocks, block_margin, stop == 0, wc,
                                   wb, wg, ws, stamps, out, i if stop == 0 else 0, near,
                                   lane)  # fmt: skip
            hits[i] = hit
            if hit and first < 0:
                first = i
    return first


#: Configurations the batch kernel carries together through forward kinematics and the
#: blocks' cluster tests (loops over them: each array read once per block, part of the
#: tests vectorised by LLVM); only those some block leaves near go on to the pairs, one by one.
LANES = 8


@numba.njit(cache=True, nogil=True)
def _fk_lanes(qs: FloatArray, i0: int, placements: FloatArray, axes: FloatArray,
              parents: IntArray, tl: FloatArray) -> None:  # fmt: skip
    """Joint frames of configurations ``qs[i0 : i0 + LANES]`` (:func:`.kinematics._fk`'s
    arithmetic, lane by lane): ``tl`` (dof + 1, 12, LANES), the top three rows of each
    ``T_world_joint``, row-major, the configuration last; ``tl[dof]`` is the identity (the
    world, parent of a root joint). Lanes past the end of ``qs`` repeat its last row."""
    n, dof = qs.shape
    nl = tl.shape[2]  # LANES, as a run-time trip count: LLVM unrolls a constant one instead
    cs = np.empty(nl)
    sn = np.empty(nl)
    for e in range(12):
        tl[dof, e, :] = 1.0 if e in (0, 5, 10) else 0.0
    for j in range(dof):
        for lane in range(nl):
            sn[lane], cs[lane] = sincos(qs[min(i0 + lane, n - 1), j])
        x, y, z = axes[j, 0], axes[j, 1], axes[j, 2]
        pl = placements[j]
        par = tl[parents[j] if parents[j] >= 0 else dof]
        o = tl[j]
        for lane in range(nl):
            loc = joint_local(pl, x, y, z, sn[lane], cs[lane])
            for a in range(3):
                p0, p1, p2 = par[4 * a, lane], par[4 * a + 1, lane], par[4 * a + 2, lane]
                for k in range(4):
                    o[4 * a + k, lane] = p0 * loc[k] + p1 * loc[4 + k] + p2 * loc[8 + k]
                o[4 * a + 3, lane] += par[4 * a + 3, lane]


@numba.njit(cache=True, inline="always")
def _lanes_sides(tl: FloatArray, sides: FloatArray, blk: int, fa: int, fb: int, margin: float,
                 near: BoolArray) -> None:  # fmt: skip
    """:func:`_sides_near` of block ``blk`` for every lane of ``tl``, and-ed into ``near``."""
    ax, ay, az = sides[blk, 0, 0], sides[blk, 0, 1], sides[blk, 0, 2]
    bx, by, bz = sides[blk, 1, 0], sides[blk, 1, 1], sides[blk, 1, 2]
    r = sides[blk, 0, 3] + sides[blk, 1, 3] + margin
    ma, mb = tl[fa if fa >= 0 else tl.shape[0] - 1], tl[fb if fb >= 0 else tl.shape[0] - 1]
    nl = tl.shape[2]
    for lane in range(nl):
        d2 = 0.0
        for k in range(0, 12, 4):
            pa = ma[k, lane] * ax + ma[k + 1, lane] * ay + ma[k + 2, lane] * az + ma[k + 3, lane]
            pb = mb[k, lane] * bx + mb[k + 1, lane] * by + mb[k + 2, lane] * bz + mb[k + 3, lane]
            d2 += (pa - pb) * (pa - pb)
        near[blk, lane] &= d2 <= r * r


@numba.njit(cache=True, nogil=True)
def _lanes_near(tl: FloatArray, clusters: FloatArray, cluster_frame: IntArray, cl: FloatArray,
                box_inv: FloatArray, box_half: FloatArray, sides: FloatArray, blocks: IntArray,
                block_margin: FloatArray, near: BoolArray) -> None:  # fmt: skip
    """The blocks' cluster and side tests of :func:`_flag_config` for
    the configurations of ``tl`` (:func:`_fk_lanes`): ``near`` (K, LANES). ``cl`` (C, 3,
    LANES): the clusters' centres in the world, the fixed ones already there."""
    nl = tl.shape[2]
    for c in range(clusters.shape[0]):
        f = cluster_frame[c]
        if f < 0:
            continue
        x, y, z = clusters[c, 0], clusters[c, 1], clusters[c, 2]
        m = tl[f]
        for k in range(3):
            for lane in range(nl):
                cl[c, k, lane] = (m[4 * k, lane] * x + m[4 * k + 1, lane] * y
                                  + m[4 * k + 2, lane] * z + m[4 * k + 3, lane])  # fmt: skip
    for blk in range(blocks.shape[0]):
        ca, cb = blocks[blk, 2], blocks[blk, 3]
        fa, fb = cluster_frame[ca], cluster_frame[cb]
        if fa <= -2 and fb <= -2:
            near[blk, :] = True  # two boxes: left to the pairs
            continue
        if fa <= -2 or fb <= -2:
            # a fixed box (its own cluster, frame -2 - body) against the other cluster
            box, c = (-2 - fb, ca) if fb <= -2 else (-2 - fa, cb)
            r = clusters[c, 3] + block_margin[blk]
            inv = box_inv[box]
            h0, h1, h2 = box_half[box, 0], box_half[box, 1], box_half[box, 2]
            for lane in range(nl):
                x, y, z = cl[c, 0, lane], cl[c, 1, lane], cl[c, 2, lane]
                e0 = abs(inv[0, 0] * x + inv[0, 1] * y + inv[0, 2] * z + inv[0, 3]) - h0
                e1 = abs(inv[1, 0] * x + inv[1, 1] * y + inv[1, 2] * z + inv[1, 3]) - h1
                e2 = abs(inv[2, 0] * x + inv[2, 1] * y + inv[2, 2] * z + inv[2, 3]) - h2
                e0, e1, e2 = max(e0, 0.0), max(e1, 0.0), max(e2, 0.0)
                near[blk, lane] = e0 * e0 + e1 * e1 + e2 * e2 <= r * r
            continue
        r = clusters[ca, 3] + clusters[cb, 3] + block_margin[blk]
        for lane in range(nl):
            dx = cl[ca, 0, lane] - cl[cb, 0, lane]
            dy = cl[ca, 1, lane] - cl[cb, 1, lane]
            dz = cl[ca, 2, lane] - cl[cb, 2, lane]
            near[blk, lane] = dx * dx + dy * dy + dz * dz <= r * r
        if blocks[blk, 4]:
            # and the spheres around the bodies each side of the block names
            _lanes_sides(tl, sides, blk, fa, fb, block_margin[blk], near)


@numba.njit(cache=True, nogil=True)
def _run_path(qs: FloatArray, placements: FloatArray, axes: FloatArray, parents: IntArray,
              spheres: FloatArray, groups: FloatArray, group_range: IntArray, frame: IntArray,
              kind: IntArray, bound: FloatArray, body_groups: IntArray, box_inv: FloatArray,
              box_half: FloatArray, clusters: FloatArray, cluster_frame: IntArray,
              sides: FloatArray, pairs: IntArray, margins: FloatArray, blocks: IntArray,
              block_margin: FloatArray, reach: IntArray, wc: FloatArray, wb: FloatArray,
              wg: FloatArray, ws: FloatArray, stamps: IntArray,
              out: BoolArray) -> tuple[int, int]:  # fmt: skip
    """A flagged configuration of a dense path ``qs`` (n, dof), or -1; and the tests made.

    ``margins`` (L, P) and ``block_margin`` (L, K): level 0 is the path check's own
    margins; level l > 0 holds for the ``reach[l]`` configurations on either side of the
    one tested (no point moves more than a step between neighbours, and each level's
    margins add that many steps). Intervals of the path are tested at their middle
    configuration, breadth first (coarse to fine), with the smallest level covering
    the interval; an interval that fails is tested at level 0 there and split in two.
    ``out`` (1, P): scratch for the pair flags of the tests.
    """
    n, dof = qs.shape
    t = np.empty((dof, 4, 4))
    stamps[:] = -1
    lo_q = np.empty(2 * n + 1, dtype=np.int64)
    hi_q = np.empty(2 * n + 1, dtype=np.int64)
    lo_q[0], hi_q[0] = 0, n - 1
    head, tail, tests = 0, 1, 0
    top = reach.shape[0] - 1
    while head < tail:
        lo, hi = lo_q[head], hi_q[head]
        head += 1
        mid = (lo + hi) // 2
        k = max(mid - lo, hi - mid)
        level = 0
        while level < top and reach[level] < k:
            level += 1
        _fk(qs[mid], placements, axes, parents, t)
        hit = True
        if reach[level] >= k:
            tests += 1
            hit = _flag_config(t, mid, spheres, groups, group_range, frame, kind, bound,
                               body_groups, box_inv, box_half, clusters, cluster_frame, sides,
                               pairs, margins[level], blocks, block_margin[level], False, wc, wb,
                               wg, ws, stamps, out, 0, _NO_LANES, -1)  # fmt: skip
        if not hit:
            continue
        if level > 0 or reach[level] < k:
            tests += 1
            hit = _flag_config(t, mid, spheres, groups, group_range, frame, kind, bound,
                               body_groups, box_inv, box_half, clusters, cluster_frame, sides,
                               pairs, margins[0], blocks, block_margin[0], False, wc, wb, wg,
                               ws, stamps, out, 0, _NO_LANES, -1)  # fmt: skip
        if hit:
            return mid, tests
        if lo < mid:
            lo_q[tail], hi_q[tail] = lo, mid - 1
            tail += 1
        if mid < hi:
            lo_q[tail], hi_q[tail] = mid + 1, hi
            tail += 1
    return -1, tests


@dataclass
class PairBlocks:
    """Active pairs sorted into blocks of one cluster pair, for the kernels.

    A cluster is the set of bodies one joint moves (links and the grasped part),
    or one fixed body; its bounding sphere is tested before any pair of the block
    (against the box itself when the other cluster is a fixed box), then, where that
    prunes more, the spheres around the bodies each side of the block names.
    """

    order: IntArray  # (P,) the caller's pair index of each sorted pair
    pairs: IntArray  # (P, 2) body pairs, sorted
    blocks: IntArray  # (K, 5) start, stop, cluster a, cluster b, test the sides (0/1)
    clusters: FloatArray  # (C, 4) bounding spheres, in each cluster's frame
    cluster_frame: IntArray  # (C,) joint; -1 a fixed body of spheres, -2 - b the fixed box b
    sides: FloatArray  # (K, 2, 4) per block, the sphere around each side's bodies in its pairs
    scratch: tuple[FloatArray, FloatArray, FloatArray, FloatArray, IntArray]


def pair_blocks(world: SphereWorld, pairs: IntArray) -> PairBlocks:
    """Sort ``pairs`` (P, 2) of ``world`` into cluster blocks (see :class:`PairBlocks`)."""
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    n_bodies = len(world.frame)
    dof_off = int(world.frame.max(initial=-1)) + 1
    cid = np.where(world.frame >= 0, world.frame, dof_off + np.arange(n_bodies))
    used, inverse = np.unique(cid, return_inverse=True)
    body_cluster = inverse.reshape(-1).astype(np.int64)
    clusters = np.zeros((len(used), 4))
    cluster_frame = np.full(len(used), -1, dtype=np.int64)
    for c in range(len(used)):
        members = np.flatnonzero(body_cluster == c)
        clusters[c] = _enclose(world.bound[members])
        cluster_frame[c] = world.frame[members[0]]
        if cluster_frame[c] < 0 and len(members) == 1 and world.kind[members[0]] == BOX:
            cluster_frame[c] = -2 - members[0]
    ca, cb = body_cluster[pairs[:, 0]], body_cluster[pairs[:, 1]]
    lo, hi = np.minimum(ca, cb), np.maximum(ca, cb)
    order = np.lexsort((hi, lo)).astype(np.int64)
    key = lo[order] * len(used) + hi[order]
    starts = np.concatenate([[0], np.flatnonzero(np.diff(key)) + 1, [len(order)]]).astype(np.int64)
    blocks = np.column_stack(
        [starts[:-1], starts[1:], lo[order][starts[:-1]], hi[order][starts[:-1]]]
    ).astype(np.int64)
    blocks = blocks.reshape(-1, 4)
    sorted_pairs = pairs[order].copy()
    sides, use = _block_sides(world, sorted_pairs, blocks, body_cluster, clusters)
    scratch = (clusters.copy(), world.bound.copy(), world.groups.copy(), world.spheres.copy(),
               np.full((3, max(n_bodies, len(world.groups))), -1, dtype=np.int64))  # fmt: skip
    return PairBlocks(order, sorted_pairs, np.column_stack([blocks, use]).astype(np.int64),
                      clusters, cluster_frame, sides, scratch)  # fmt: skip


#: A block's side spheres are tested when one is this much smaller than its cluster's.
SIDE_SHRINK = 0.8


def _block_sides(world: SphereWorld, pairs: IntArray, blocks: IntArray, body_cluster: IntArray,
                 clusters: FloatArray) -> tuple[FloatArray, IntArray]:  # fmt: skip
    """Per block, the sphere around the bodies of each side that its pairs name (K, 2, 4),
    in the side's frame, and whether testing them can prune more than the clusters (K,):
    a link's few bodies facing the fingers sit in a much smaller sphere than the link's
    whole cluster, which holds the hand too. Vectorised over the sorted pairs (a body
    named twice changes no enclosing sphere)."""
    k = len(blocks)
    sides = np.zeros((k, 2, 4))
    if not k:
        return sides, np.zeros(0, dtype=np.int64)
    starts = blocks[:, 0]
    block_of = np.repeat(np.arange(k), blocks[:, 1] - blocks[:, 0])
    first_is_a = body_cluster[pairs[:, 0]] == blocks[block_of, 2]
    use = np.zeros(k, dtype=bool)
    for j, body in enumerate(
        (
            np.where(first_is_a, pairs[:, 0], pairs[:, 1]),
            np.where(first_is_a, pairs[:, 1], pairs[:, 0]),
        )
    ):
        b = world.bound[body]
        lo = np.minimum.reduceat(b[:, :3] - b[:, 3:], starts, axis=0)
        hi = np.maximum.reduceat(b[:, :3] + b[:, 3:], starts, axis=0)
        centre = (lo + hi) / 2.0
        reach = np.linalg.norm(b[:, :3] - centre[block_of], axis=1) + b[:, 3]
        sides[:, j, :3] = centre
        sides[:, j, 3] = np.maximum.reduceat(reach, starts)
        use |= sides[:, j, 3] < SIDE_SHRINK * clusters[blocks[:, 2 + j], 3]
    boxed = np.maximum.reduceat(world.kind[pairs].max(axis=1), starts) == BOX
    return sides, (use & ~boxed & (blocks[:, 2] != blocks[:, 3])).astype(np.int64)


def _enclose(spheres: FloatArray) -> FloatArray:
    lo = np.min(spheres[:, :3] - spheres[:, 3:], axis=0)
    hi = np.max(spheres[:, :3] + spheres[:, 3:], axis=0)
    c = (lo + hi) / 2.0
    return np.append(c, float(np.max(np.linalg.norm(spheres[:, :3] - c, axis=1) + spheres[:, 3])))


def flags(
    world: SphereWorld, chain: ChainArrays, qs: FloatArray, blocks: PairBlocks, margins: FloatArray
) -> BoolArray:
    """Pair flags (n, P) of a packed world: True where coal must decide.

    ``margins`` (P,) are the pairs' security margins, metres (negative ones count as
    0), in the caller's pair order, as is the output.
    """
    sorted_flags, _, _ = _call(world, chain, qs, blocks, margins, 0)
    out = np.empty_like(sorted_flags)
    out[:, blocks.order] = sorted_flags
    return out


def free(
    world: SphereWorld, chain: ChainArrays, qs: FloatArray, blocks: PairBlocks, margins: FloatArray
) -> BoolArray:
    """True where no pair is flagged (certainly collision-free), shape (n,); stops per config."""
    return ~_call(world, chain, qs, blocks, margins, 1)[1]


def path_flagged(
    world: SphereWorld,
    chain: ChainArrays,
    qs: FloatArray,
    blocks: PairBlocks,
    levels: tuple[FloatArray, FloatArray, IntArray],
) -> tuple[int, int]:
    """A flagged configuration of a dense path (-1 if none) and the number of tests made.

    ``qs`` (n, dof): a path interpolated so that no point moves more than a step ``s``
    between neighbours. ``levels``: :func:`sorted_margins` of the margins (L, P) a
    configuration needs to stand for the ``reach`` (L,) configurations on either side
    (level 0: the path check's own margins, reach 0; level l: those plus ``reach[l] s``
    per moving body) and ``reach``. A free stretch is cleared by one test at its middle;
    where that fails, the stretch is split (coarse to fine), down to single configurations
    at level 0, so the verdict is the dense check's at a fraction of its cost.
    """
    qa = np.ascontiguousarray(qs, dtype=np.float64)
    if not len(blocks.pairs) or not qa.shape[0]:
        return -1, 0
    m, bm, reach = levels
    wc, wb, wg, ws, stamps = blocks.scratch
    out = np.zeros((1, len(blocks.pairs)), dtype=np.bool_)
    first, tests = _run_path(qa, chain.placements, chain.axes, chain.parents, world.spheres,
                             world.groups, world.group_range, world.frame, world.kind,
                             world.bound, world.body_groups, world.box_inv, world.box_half,
                             blocks.clusters, blocks.cluster_frame, blocks.sides, blocks.pairs, m,
                             blocks.blocks, bm, reach, wc, wb, wg, ws, stamps, out)  # fmt: skip
    return int(first), int(tests)


def sorted_margins(blocks: PairBlocks, margins: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The kernels' margins: per sorted pair (..., P) and per block (..., K), metres.

    ``margins`` (..., P) in the caller's pair order; negative ones count as 0. Computed once
    per world and margin set by callers that check many paths (:func:`path_flagged`).
    Both in C order whatever the input's: indexing the last axis of (L, P) margins gives
    Fortran order, a layout the kernels would be compiled for anew mid-run.
    """
    m = np.maximum(np.asarray(margins, dtype=np.float64)[..., blocks.order], 0.0) + 1e-9
    m = np.ascontiguousarray(m)
    if not len(blocks.blocks):
        return m, m[..., :0]
    return m, np.ascontiguousarray(np.maximum.reduceat(m, blocks.blocks[:, 0], axis=-1))


def _call(world: SphereWorld, chain: ChainArrays, qs: FloatArray, blocks: PairBlocks,
          margins: FloatArray, stop: int) -> tuple[BoolArray, BoolArray, int]:  # fmt: skip
    """Pair flags (n, P) (``stop`` 0; else a (1, P) scratch row), per-configuration hits (n,)
    and the first configuration flagged (-1 if none)."""
    qa = np.ascontiguousarray(qs, dtype=np.float64)
    n_pairs = len(blocks.pairs)
    out = np.zeros((qa.shape[0] if stop == 0 else 1, n_pairs), dtype=np.bool_)
    hits = np.zeros(qa.shape[0], dtype=np.bool_)
    if not n_pairs or not qa.shape[0]:
        return out, hits, -1
    m, bm = sorted_margins(blocks, margins)
    wc, wb, wg, ws, stamp = blocks.scratch
    first = _run(qa, chain.placements, chain.axes, chain.parents, world.spheres, world.groups,
                 world.group_range, world.frame, world.kind, world.bound, world.body_groups,
                 world.box_inv, world.box_half, blocks.clusters, blocks.cluster_frame,
                 blocks.sides, blocks.pairs, m, blocks.blocks, bm, stop, wc, wb, wg, ws, stamp, out,
                 hits)  # fmt: skip
    return out, hits, int(first)


def warm_up() -> None:
    """Compile (or load from the cache) every kernel on a tiny world, before any deadline runs.

    The first call in a process on a fresh checkout compiles for seconds to a minute (2-core
    machine); later processes load the compiled code from ``__pycache__``.
    """
    from thirdhand.execute.kinematics import Chain, solve_ik
    from thirdhand.execute.spheres import group_cover

    chain = Chain(np.eye(4)[None], np.array([[0.0, 0.0, 1.0]]), np.array([-1], dtype=np.intp))
    arrays = ChainArrays(chain.placements, chain.axes, chain.parents.astype(np.int64))
    cover = group_cover(np.array([[0.1, 0.0, 0.0, 0.05]]), 0.06)
    world = pack([cover, None], [0, -1], {1: (np.eye(4), np.array([0.1, 0.1, 0.1]))})
    blocks = pair_blocks(world, np.array([[0, 1]]))
    qs = np.zeros((2, 1))
    margins = np.zeros(1)
    flags(world, arrays, qs, blocks, margins)
    free(world, arrays, qs, blocks, margins)
    levels = (*sorted_margins(blocks, np.zeros((2, 1))), np.array([0, 1], dtype=np.int64))
    path_flagged(world, arrays, qs, blocks, levels)
    joint_transforms_nb(qs, arrays.placements, arrays.axes, arrays.parents)
    solve_ik(chain, 0, np.eye(4), np.eye(4), qs, np.array([-1.0]), np.array([1.0]))
