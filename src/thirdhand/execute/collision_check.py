"""Checking configurations and paths of a collision world: batched checks over a pair table.

:class:`SceneChecks` checks the bodies of one
:class:`~thirdhand.execute.scene_bodies.SceneBodies` snapshot,
which :class:`~thirdhand.execute.scene.CollisionScene` (table, boxes, parts,
attach and detach) hands it on every change. Which pairs are checked and with
which margins is decided by the pure functions of
:mod:`~thirdhand.execute.pair_table`; the checker keeps the coal requests, the
sphere covers and the caches. A configuration is checked in two phases, batched
over many configurations at once: world-frame bounding boxes of every body
(robot links from :class:`~thirdhand.execute.kinematics.Chain`, numpy) or the
sphere covers over the pair table, then coal's exact narrow phase on the pairs
they cannot clear, stopping at the first contact. Paths are interpolated so that
no point of the robot or the grasped part moves more than a given distance
between two checks, and checked coarse to fine. Poses are homogeneous (4, 4)
matrices in the world frame, metres; configurations are radians.
"""

from __future__ import annotations

import hashlib
from functools import lru_cache
from typing import NamedTuple

import coal
import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from thirdhand.arrays import BoolArray, FloatArray, IndexArray
from thirdhand.execute import pair_table as pt
from thirdhand.execute import sphere_check as sc
from thirdhand.execute.kinematics import Chain
from thirdhand.execute.pair_table import GRIPPER, PATH_REACH, ROBOT
from thirdhand.execute.robot import Robot
from thirdhand.execute.scene_bodies import (
    Body,
    SceneBodies,
    coal_transform,
    fixed_link_frame,
    touching_links,
)
from thirdhand.execute.spheres import SphereCover, cover_geometry, transform_cover

__all__ = [
    "GRIPPER",
    "PATH_REACH",
    "ROBOT",
    "Body",
    "SceneBodies",
    "SceneChecks",
    "SpherePairs",
    "coal_transform",
    "fixed_link_frame",
    "geometry_cover",
    "touching_links",
    "warm_up",
    "world_aabb",
]


class SpherePairs(NamedTuple):
    """The pair table split for the sphere kernels.

    Attributes
    ----------
    moving : ndarray of intp, shape (M,)
        Pairs (indices into the table) whose bodies move relative to each other.
    blocks : sphere_check.PairBlocks
        Those pairs arranged for the kernels.
    fixed : ndarray of intp, shape (F,)
        Pairs of two bodies that keep their distance at every configuration.
    fixed_dist : ndarray, shape (F,)
        coal's exact distance of each fixed pair, metres.
    """

    moving: IndexArray
    blocks: sc.PairBlocks
    fixed: IndexArray
    fixed_dist: FloatArray


class PairState(NamedTuple):
    """What the checker keeps per allowed set: the pair table, its split for the kernels,
    the margins by clearance and the path kernel's margin levels by step."""

    table: pt.PairTable
    spheres: SpherePairs | None
    margins: dict[float, FloatArray]
    path_levels: dict[float, tuple[FloatArray, FloatArray, IndexArray] | None]


_COVERS: dict[int, tuple[coal.CollisionGeometry, SphereCover]] = {}


_MESH_COVERS: dict[tuple[int, int, bytes], SphereCover] = {}


def geometry_cover(geometry: coal.CollisionGeometry) -> SphereCover:
    """The sphere cover of a geometry in its frame, computed once per geometry object (per mesh)."""
    hit = _COVERS.get(id(geometry))
    if hit is not None and hit[0] is geometry:
        return hit[1]
    if isinstance(geometry, coal.BVHModelBase):  # the same mesh loaded again (another Robot)
        verts = np.asarray(geometry.vertices(), dtype=np.float64)
        key = (geometry.num_vertices, geometry.num_tris, hashlib.sha1(verts.tobytes()).digest())
        cover = _MESH_COVERS.get(key)
        if cover is None:
            cover = _MESH_COVERS[key] = cover_geometry(geometry)
    else:
        cover = cover_geometry(geometry)
    _COVERS[id(geometry)] = (geometry, cover)
    return cover


@lru_cache(maxsize=512)
def _coarse_to_fine(n: int) -> NDArray[np.intp]:
    """A permutation of ``range(n)`` by bit-reversed index: 0, n/2, n/4, 3n/4, ... (read-only)."""
    bits = max(int(n - 1).bit_length(), 1)
    idx = np.arange(n)
    rev = np.zeros(n, dtype=np.int64)
    for b in range(bits):
        rev |= ((idx >> b) & 1) << (bits - 1 - b)
    out = np.argsort(rev, kind="stable").astype(np.intp)
    out.flags.writeable = False
    return out


@numba.njit(cache=True, nogil=True)
def _dense_path(
    qa: FloatArray, lever: FloatArray, max_step_m: float, max_step_rad: float
) -> FloatArray:  # pragma: no cover - compiled
    """:meth:`SceneChecks.interpolate`'s configurations (m, dof), compiled (same arithmetic)."""
    n, dof = qa.shape
    counts = np.empty(n - 1, dtype=np.int64)
    total = 1
    for k in range(n - 1):
        lin = 0.0
        big = 0.0
        for j in range(dof):
            d = abs(qa[k + 1, j] - qa[k, j])
            lin += d * lever[j]
            big = max(big, d)
        steps = max(lin / max_step_m, big / max_step_rad)
        c = max(int(np.ceil(steps)), 1)
        counts[k] = c
        total += c
    out = np.empty((total, dof))
    out[0] = qa[0]
    row = 1
    for k in range(n - 1):
        c = counts[k]
        for i in range(1, c + 1):
            s = i / c
            for j in range(dof):
                out[row, j] = (1.0 - s) * qa[k, j] + s * qa[k + 1, j]
            row += 1
    return out


def warm_up() -> None:
    """Compile (or load from the cache) every collision and IK kernel before a deadline runs:
    the sphere layer's (:func:`.sphere_check.warm_up`) and the dense path's."""
    sc.warm_up()
    _dense_path(np.zeros((2, 1)), np.ones(1), 0.01, 0.02)


def world_aabb(
    t: FloatArray, center: FloatArray, half: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """World AABB centres and half extents of boxes under transforms ``t`` (..., 4, 4)."""
    rot = t[..., :3, :3]
    c = np.einsum("...ij,...j->...i", rot, center) + t[..., :3, 3]
    h = np.einsum("...ij,...j->...i", np.abs(rot), half)
    return c, h


class SceneChecks:
    """The batched checks of a collision world (see the module notes).

    Checks the bodies of one :class:`SceneBodies` snapshot at a time, replaced by
    :meth:`update`; keeps coal's requests, the sphere covers and the caches of the
    pair table and its margins.

    Parameters
    ----------
    robot : Robot
    bodies : SceneBodies
        The world to check.
    tolerance : float
        Penetration depth, metres, below which two primitive shapes only touch.
    spheres : bool
        Use the sphere layer as the broad phase and for path checks (see
        :class:`~thirdhand.execute.scene.CollisionScene`).

    Attributes
    ----------
    n_checks : int
        Configurations checked so far; reset with :meth:`reset_counter`.
    n_narrow : int
        Exact (coal) pair tests so far.
    """

    def __init__(
        self, robot: Robot, bodies: SceneBodies, *, tolerance: float = 1e-3, spheres: bool = True
    ) -> None:
        self.robot = robot
        self.tolerance = float(tolerance)
        self.use_spheres = bool(spheres)
        self.n_checks = 0
        self.n_narrow = 0
        self._bodies = bodies
        self._requests: dict[float, coal.CollisionRequest] = {}
        self._result = coal.CollisionResult()
        self._chain_cache: tuple[Chain, sc.ChainArrays] | None = None
        self._lever: FloatArray | None = None
        self._sworld: sc.SphereWorld | None = None
        self._fixed: list[FloatArray | None] = []
        self._fixed_dist: dict[tuple[int, int], float] = {}
        self._table: pt.PairTable | None = None
        self._table_key: frozenset[frozenset[str]] = frozenset()
        self._spairs: SpherePairs | None = None
        self._margins: dict[float, FloatArray] = {}
        self._levels: dict[float, tuple[FloatArray, FloatArray, IndexArray] | None] = {}
        self._pair_states: dict[frozenset[frozenset[str]], PairState] = {}

    @property
    def bodies(self) -> SceneBodies:
        """The world being checked."""
        return self._bodies

    def update(self, bodies: SceneBodies, *, moved: bool = True, posed: bool = True) -> None:
        """Check ``bodies`` from now on, forgetting what the change made stale.

        Parameters
        ----------
        bodies : SceneBodies
            The world after the change.
        moved : bool
            A body was added, removed, grasped or released: everything is recomputed
            (the lever arms and sphere covers too).
        posed : bool
            A free object moved: the pair tables and sphere covers are recomputed
            (the fixed pairs' distances changed).

        Without either (a pair allowed or disallowed), the pair table, margins and
        kernel split of the allowed set left are kept, and those of the set now in
        force come back if it was seen before: step search allows and disallows a
        gripper at its part hundreds of times per step.
        """
        self._bodies = bodies
        kept = None
        if moved or posed:
            self._pair_states = {}
            self._sworld = None
        else:
            if self._table is not None:
                self._pair_states[self._table_key] = PairState(
                    self._table, self._spairs, self._margins, self._levels
                )
            kept = self._pair_states.get(bodies.allowed)
        if kept is not None:
            self._table, self._spairs, self._margins, self._levels = kept
            self._table_key = bodies.allowed
        else:
            self._table = None
            self._spairs = None
            self._margins = {}
            self._levels = {}
        if moved:
            self._lever = None

    # -- pairs ------------------------------------------------------------------------

    def pair_table(self) -> pt.PairTable:
        """The checked pairs and their contact margins (:func:`.pair_table.pair_table`),
        cached till the world changes."""
        if self._table is None:
            self._table_key = self._bodies.allowed
            self._table = pt.pair_table(self._bodies.pair_world(), self.tolerance)
        return self._table

    def pair_margins(self, clearance: float = 0.0) -> FloatArray:
        """Security margin of every checked pair, metres, shape (P,) (cached till the world
        changes): :func:`.pair_table.pair_margins` of the table."""
        key = float(max(clearance, 0.0))
        cached = self._margins.get(key)
        if cached is None:
            cached = self._margins[key] = pt.pair_margins(self.pair_table(), key)
        return cached

    def _request(self, margin: float) -> coal.CollisionRequest:
        req = self._requests.get(margin)
        if req is None:
            req = coal.CollisionRequest()
            req.security_margin = margin
            self._requests[margin] = req
        return req

    def _requests_of(self, margins: FloatArray) -> list[coal.CollisionRequest]:
        """coal requests of per-pair margins (P,), one per distinct margin."""
        values, inverse = np.unique(margins, return_inverse=True)
        reqs = [self._request(float(v)) for v in values]
        return [reqs[k] for k in inverse.reshape(-1)]

    # -- spheres ----------------------------------------------------------------------

    def sphere_world(self) -> sc.SphereWorld:
        """Sphere covers of every body, each in the frame that moves it (cached till a body
        is added, removed or moved)."""
        if self._sworld is not None:
            return self._sworld
        state = self._bodies
        n_links = len(state.links)
        covers: list[SphereCover | None] = []
        frames: list[int] = []
        boxes: dict[int, tuple[FloatArray, FloatArray]] = {}
        fixed: list[FloatArray | None] = []
        for k, body in enumerate(state.bodies):
            if k < n_links:
                joint = int(state.link_joint[k])
                t_fixed = fixed_link_frame(body, joint, self.robot.chain)
                frame, t = (-1, t_fixed) if t_fixed is not None else (joint, body.transform)
            elif state.attached is body:
                frame = self.robot.tool_joint
                t = self.robot.t_joint_tool @ body.transform
            else:
                frame, t = -1, body.transform
            frames.append(frame)
            fixed.append(t if frame < 0 else None)
            if frame < 0 and isinstance(body.geometry, coal.Box):
                boxes[k] = (t, np.asarray(body.geometry.halfSide, dtype=np.float64))
                covers.append(None)
            else:
                covers.append(transform_cover(geometry_cover(body.geometry), t))
        self._sworld = sc.pack(covers, frames, boxes)
        self._fixed = fixed
        self._fixed_dist = {}
        return self._sworld

    def chain_arrays(self) -> sc.ChainArrays:
        """The robot's chain as the sphere kernels take it."""
        cached = self._chain_cache
        if cached is None or cached[0] is not self.robot.chain:
            chain = self.robot.chain
            arrays = sc.ChainArrays(chain.placements, chain.axes, chain.parents.astype(np.int64))
            cached = self._chain_cache = (chain, arrays)
        return cached[1]

    def sphere_pairs(self) -> SpherePairs:
        """The pair table split for the kernels: moving pairs, and fixed ones (distance known).

        Two bodies no joint moves, or moved by the same joint (a grasped part and its
        hand's links), keep their distance at every configuration: coal's exact distance
        is computed once. Cached till the world changes.
        """
        if self._spairs is not None:
            return self._spairs
        world = self.sphere_world()
        table = self.pair_table()
        first, second = table.first, table.second
        moving = world.frame[first] != world.frame[second]
        fixed_idx = np.flatnonzero(~moving)
        bodies = self._bodies.bodies
        dists = np.empty(len(fixed_idx))
        req = coal.DistanceRequest()
        t_home: FloatArray | None = None
        for n, p in enumerate(fixed_idx):
            a, b = int(first[p]), int(second[p])
            d = self._fixed_dist.get((a, b))
            if d is None:
                if world.frame[a] < 0:
                    ta, tb = self._fixed[a], self._fixed[b]
                else:
                    if t_home is None:
                        t_home = self.transforms(self.robot.home[None])[0]
                    ta, tb = t_home[a], t_home[b]
                assert ta is not None and tb is not None
                res = coal.DistanceResult()
                ga, gb = bodies[a].geometry, bodies[b].geometry
                d = float(coal.distance(ga, coal_transform(ta), gb, coal_transform(tb), req, res))
                self._fixed_dist[(a, b)] = d
            dists[n] = d
        idx = np.flatnonzero(moving)
        blocks = sc.pair_blocks(world, np.column_stack([first[idx], second[idx]]))
        self._spairs = SpherePairs(idx, blocks, fixed_idx, dists)
        return self._spairs

    def _path_levels(
        self, max_step_m: float, margins: FloatArray | None = None
    ) -> tuple[FloatArray, FloatArray, IndexArray] | None:
        """The path kernel's margin levels (see :func:`.sphere_check.path_flagged`) for a path
        interpolated at ``max_step_m``, or None when two fixed bodies are within their contact
        margin.

        Level 0 is ``margins`` (P,), by default the path clearance (half a step per moving
        body, cached till the world changes); the others are
        :func:`.pair_table.path_margin_levels`.
        """
        key = float(max_step_m)
        if margins is None and key in self._levels:
            return self._levels[key]
        base = self.pair_margins(max_step_m / 2.0) if margins is None else margins
        table = self.pair_table()
        split = self.sphere_pairs()
        levels = None
        # fixed pairs do not move relative to each other: their distance is known, and
        # only their contact margin applies (no clearance)
        if not pt.fixed_pairs_touch(split.fixed_dist, table.contact[split.fixed]):
            m = pt.path_margin_levels(
                base[split.moving], table.n_moving[split.moving], max_step_m, PATH_REACH
            )
            levels = (*sc.sorted_margins(split.blocks, m), PATH_REACH)
        if margins is None:
            self._levels[key] = levels
        return levels

    def _path_first_flagged(
        self, dense: FloatArray, max_step_m: float, margins: FloatArray | None = None
    ) -> int:
        """A configuration of ``dense`` (interpolated at ``max_step_m``) the spheres flag at
        ``margins`` (default: the path clearance), or -1 if they clear all; -2 when two
        fixed bodies touch (nothing is cleared). Counts the tests in :attr:`n_checks`."""
        levels = self._path_levels(max_step_m, margins)
        if levels is None:
            return -2
        first, tests = sc.path_flagged(
            self.sphere_world(), self.chain_arrays(), dense, self.sphere_pairs().blocks, levels
        )
        self.n_checks += tests
        return first

    def sphere_flags(self, qs: ArrayLike, margins: FloatArray | None = None) -> BoolArray:
        """Checked pairs the sphere covers cannot clear, per configuration, shape (n, P).

        Unflagged pairs are certainly free in coal's exact check (the covers are
        conservative, :mod:`~thirdhand.execute.spheres`); ``margins`` (P,) default
        to the contact margins. Pairs of two bodies no joint moves are flagged from
        their exact distance, computed once.
        """
        qa = np.asarray(qs, dtype=np.float64).reshape(-1, self.robot.dof)
        m = self.pair_margins() if margins is None else margins
        world = self.sphere_world()
        split = self.sphere_pairs()
        out = np.zeros((qa.shape[0], len(m)), dtype=bool)
        out[:, split.moving] = sc.flags(
            world, self.chain_arrays(), qa, split.blocks, m[split.moving]
        )
        out[:, split.fixed] = pt.fixed_pair_flags(split.fixed_dist, m[split.fixed])[None]
        return out

    def sphere_free_mask(self, qs: ArrayLike, margins: FloatArray | None = None) -> BoolArray:
        """True where the sphere covers alone prove a configuration collision-free, shape (n,).

        Conservative: may say "not free" where coal finds no contact, never "free"
        where it finds one. Joint limits are not checked.
        """
        qa = np.asarray(qs, dtype=np.float64).reshape(-1, self.robot.dof)
        m = self.pair_margins() if margins is None else margins
        world = self.sphere_world()
        split = self.sphere_pairs()
        if pt.fixed_pairs_touch(split.fixed_dist, m[split.fixed]):
            return np.zeros(qa.shape[0], dtype=bool)
        return sc.free(world, self.chain_arrays(), qa, split.blocks, m[split.moving])

    def path_free_spheres(
        self, qs: ArrayLike, *, max_step_m: float = 0.01, max_step_rad: float = 0.02
    ) -> bool:
        """True if the sphere covers alone prove a path free with :meth:`check_path`'s clearance.

        Conservative: True implies that :meth:`check_path` (with clearance) is True;
        False may be a path coal would accept (a part close to a surface). One
        compiled call over the densely interpolated path: stretches cleared at their middle
        with widened margins, coarse to fine, stopping at the first flagged configuration.
        """
        if not self.use_spheres:
            return False
        qa = np.asarray(qs, dtype=np.float64).reshape(-1, self.robot.dof)
        dense = self.interpolate(qa, max_step_m=max_step_m, max_step_rad=max_step_rad)
        # a segment between two configurations within the limits stays within them
        if not np.all((qa >= self.robot.lower - 1e-9) & (qa <= self.robot.upper + 1e-9)):
            return False
        return self._path_first_flagged(dense, max_step_m) == -1

    # -- checking ---------------------------------------------------------------------

    def transforms(self, qs: ArrayLike) -> FloatArray:
        """World transforms of every body (links, objects, grasped part) at ``qs`` (n, dof),
        shape (n, B, 4, 4)."""
        qa = np.asarray(qs, dtype=np.float64).reshape(-1, self.robot.dof)
        n = qa.shape[0]
        state = self._bodies
        out = np.empty((n, len(state.bodies), 4, 4))
        tj = self.robot.chain.joint_transforms(qa)
        n_links = len(state.links)
        local = state.link_local
        static = state.link_joint < 0
        out[:, :n_links] = local[None]
        mv = ~static
        out[:, :n_links][:, mv] = tj[:, state.link_joint[mv]] @ local[mv]
        k = n_links
        for obj in state.objects:
            out[:, k] = obj.transform
            k += 1
        if state.attached is not None:
            out[:, k] = self.robot.tool_transforms(qa) @ state.attached.transform
        return out

    def valid_mask(
        self,
        qs: ArrayLike,
        *,
        stop_at_first: bool = False,
        exact: bool = False,
        margins: FloatArray | None = None,
    ) -> BoolArray:
        """Collision-free and within-limits flag of many configurations.

        Parameters
        ----------
        qs : array_like, shape (n, dof)
            Configurations, radians.
        stop_at_first : bool
            Stop at the first invalid configuration (in order); the ones after it
            are reported invalid without being checked.
        exact : bool
            Leave the sphere covers out: every pair whose bounding boxes overlap goes
            to coal (the independent check of executed paths). The verdicts are the
            same either way; only the time differs.
        margins : ndarray, shape (P,), optional
            Security margin per checked pair, metres (:meth:`pair_margins`); by
            default the contact margins.

        Returns
        -------
        ndarray of bool, shape (n,)
        """
        qa = np.asarray(qs, dtype=np.float64).reshape(-1, self.robot.dof)
        m = self.pair_margins() if margins is None else margins
        n = qa.shape[0]
        ok = np.all((qa >= self.robot.lower - 1e-9) & (qa <= self.robot.upper + 1e-9), axis=1)
        overlap = self._candidates(qa, m, exact)
        flagged = np.any(overlap, axis=1)
        if not np.any(flagged & ok):  # no pair for coal: limits decide
            if stop_at_first and not np.all(ok):
                bad = int(np.argmin(ok))
                self.n_checks += bad + 1
                ok[bad:] = False
            else:
                self.n_checks += n
            return ok
        table = self.pair_table()
        first, second = table.first, table.second
        bodies = self._bodies.bodies
        rows = np.flatnonzero(flagged)
        t_rows = self.transforms(qa[rows])
        row_of = np.full(n, -1, dtype=np.intp)
        row_of[rows] = np.arange(len(rows))
        requests = self._requests_of(m)
        for i in range(n):
            if not ok[i]:
                self.n_checks += 1
                if stop_at_first:
                    ok[i:] = False
                    break
                continue
            self.n_checks += 1
            if not flagged[i]:
                continue
            t = t_rows[row_of[i]]
            tfs: dict[int, coal.Transform3s] = {}  # one coal transform per body and config
            for p in np.flatnonzero(overlap[i]):
                a, b = int(first[p]), int(second[p])
                self.n_narrow += 1
                self._result.clear()
                ta = tfs.get(a)
                if ta is None:
                    ta = tfs[a] = coal_transform(t[a])
                tb = tfs.get(b)
                if tb is None:
                    tb = tfs[b] = coal_transform(t[b])
                if coal.collide(
                    bodies[a].geometry, ta, bodies[b].geometry, tb, requests[p], self._result
                ):
                    ok[i] = False
                    break
            if stop_at_first and not ok[i]:
                ok[i:] = False
                break
        return ok

    def _candidates(self, qa: FloatArray, margins: FloatArray, exact: bool) -> BoolArray:
        """Pairs coal must decide per configuration (n, P): sphere flags, or overlapping boxes."""
        if not exact and self.use_spheres:
            return self.sphere_flags(qa, margins)
        table = self.pair_table()
        first, second = table.first, table.second
        bodies = self._bodies.bodies
        centers = np.array([b.center for b in bodies])
        halves = np.array([b.half for b in bodies])
        c, h = world_aabb(self.transforms(qa), centers[None], halves[None])
        reach = h[:, first] + h[:, second] + np.maximum(margins, 0.0)[None, :, None] + 1e-9
        return np.all(np.abs(c[:, first] - c[:, second]) <= reach, axis=2)

    def collisions(self, q: ArrayLike) -> list[tuple[str, str]]:
        """Every colliding pair of body (link or object) names at ``q`` (dof,), for diagnostics."""
        table = self.pair_table()
        bodies = self._bodies.bodies
        hits = self.pair_hits(self.robot.check_q(q), self.pair_margins())
        out: list[tuple[str, str]] = []
        for p in np.flatnonzero(hits):
            pair = (bodies[table.first[p]].name, bodies[table.second[p]].name)
            if pair not in out:
                out.append(pair)
        return out

    def pair_hits(self, q: FloatArray, margins: FloatArray) -> BoolArray:
        """Which checked pairs collide at ``q`` (dof,) under ``margins`` (P,), shape (P,)."""
        table = self.pair_table()
        first, second = table.first, table.second
        bodies = self._bodies.bodies
        if self.use_spheres:
            candidates = self.sphere_flags(q[None], margins)[0]
        else:
            candidates = self._candidates(q[None], margins, True)[0]
        hits = np.zeros(len(first), dtype=bool)
        if not np.any(candidates):
            return hits
        t = self.transforms(q[None])[0]
        for p in np.flatnonzero(candidates):
            a, b = int(first[p]), int(second[p])
            self._result.clear()
            hits[p] = bool(
                coal.collide(
                    bodies[a].geometry,
                    coal_transform(t[a]),
                    bodies[b].geometry,
                    coal_transform(t[b]),
                    self._request(float(margins[p])),
                    self._result,
                )
            )
        return hits

    def motion_bound(self) -> FloatArray:
        """Per-joint lever arm, metres: no robot or grasped point moves more than ``Σ |Δq_j| r_j``.

        ``r_j`` bounds the distance of any body moved by joint ``j`` from that
        joint's axis (the distance from the joint origin to the far corner of
        each body's bounding box, at the home configuration — the chain is rigid
        between joints, so this distance does not depend on ``q``).

        Returns
        -------
        ndarray, shape (dof,)
        """
        if self._lever is not None:
            return self._lever
        q = self.robot.home[None]
        chain = self.robot.chain
        tj = chain.joint_transforms(q)[0]
        state = self._bodies
        t = self.transforms(q)[0]
        radius = np.zeros(self.robot.dof)
        n_links = len(state.links)
        for k, body in enumerate(state.bodies):
            if k < n_links:
                j = int(state.link_joint[k])
                if j < 0:
                    continue
                moved = chain.ancestors(j)
            elif state.attached is body:
                moved = chain.ancestors(self.robot.tool_joint)
            else:
                continue
            c, h = world_aabb(t[k], body.center, body.half)
            far = np.linalg.norm(c[None] - tj[:, :3, 3], axis=1) + np.linalg.norm(h)
            radius = np.where(moved, np.maximum(radius, far), radius)
        self._lever = radius
        return radius

    def interpolate(
        self, qs: ArrayLike, *, max_step_m: float = 0.01, max_step_rad: float = 0.02
    ) -> FloatArray:
        """Densely interpolate a joint path so that no point moves more than ``max_step_m``.

        Parameters
        ----------
        qs : array_like, shape (n, dof)
            Waypoints, radians.
        max_step_m : float
            Largest displacement of any robot or grasped-part point between
            consecutive configurations, metres (bounded by :meth:`motion_bound`).
        max_step_rad : float
            Largest change of any joint between consecutive configurations, radians.

        Returns
        -------
        ndarray, shape (m, dof)
            The waypoints and the configurations between them, in order.
        """
        qa = np.asarray(qs, dtype=np.float64).reshape(-1, self.robot.dof)
        if qa.shape[0] < 2:
            return qa.copy()
        return np.asarray(
            _dense_path(np.ascontiguousarray(qa), self.motion_bound(), max_step_m, max_step_rad),
            dtype=np.float64,
        )

    def check_path(
        self,
        qs: ArrayLike,
        *,
        max_step_m: float = 0.01,
        max_step_rad: float = 0.02,
        clearance: bool = True,
        chunk: int = 64,
    ) -> bool:
        """True if a piecewise-linear joint path is collision-free, checked densely.

        Every segment is interpolated by :meth:`interpolate` (no point moves more
        than ``max_step_m`` between checks) and each configuration checked, stopping
        at the first collision; the configurations are visited coarse to fine
        (every 2^k-th first), so a path that collides is usually rejected after a
        few checks.

        With ``clearance`` (the default) the check is conservative for the
        continuous motion: between two checks no point is farther than
        ``max_step_m / 2`` from where it was checked, so each checked configuration
        must keep that distance to the world (twice it between two moving bodies).
        Pairs that are closer than that at the first or the last waypoint — a
        grasped part leaving the table, a hand at its grasp — are checked at
        their contact tolerance instead (:func:`.pair_table.near_end_margins`).

        Parameters
        ----------
        qs : array_like, shape (n, dof)
            Waypoints, radians.
        max_step_m, max_step_rad : float
            Density of the check (see :meth:`interpolate`).
        clearance : bool
            Require the clearance above; without it only the checked
            configurations are guaranteed collision-free.
        chunk : int
            Configurations checked per batch.
        """
        qa = np.asarray(qs, dtype=np.float64).reshape(-1, self.robot.dof)
        margins = self.pair_margins()
        if clearance and len(qa) > 1:
            wide = self.pair_margins(max_step_m / 2.0)
            if not self.use_spheres or np.any(self.sphere_flags(qa[[0, -1]], wide)):
                if not np.all(self.valid_mask(qa[[0, -1]], margins=margins)):
                    return False
                near = self.pair_hits(qa[0], wide) | self.pair_hits(qa[-1], wide)
                margins = pt.near_end_margins(margins, wide, near)
            else:  # the spheres clear both ends with room to spare: no pair is near
                margins = wide
        dense = self.interpolate(qa, max_step_m=max_step_m, max_step_rad=max_step_rad)
        # the common case in one compiled call: the spheres clear every configuration
        # a segment between two configurations within the limits stays within them
        within = np.all((qa >= self.robot.lower - 1e-9) & (qa <= self.robot.upper + 1e-9))
        if within and self.use_spheres:
            first = self._path_first_flagged(dense, max_step_m, margins)
            if first == -1:
                return True
            # coal decides first where the spheres flagged: a colliding path is rejected there
            if (
                first >= 0
                and not self.valid_mask(
                    dense[first : first + 1], stop_at_first=True, margins=margins
                )[0]
            ):
                return False
        # coarse to fine (bit-reversed order): a colliding stretch is hit after few checks
        dense = dense[_coarse_to_fine(dense.shape[0])]
        for k in range(0, dense.shape[0], chunk):
            if not np.all(
                self.valid_mask(dense[k : k + chunk], stop_at_first=True, margins=margins)
            ):
                return False
        return True

    def reset_counter(self) -> None:
        """Set :attr:`n_checks` and :attr:`n_narrow` to zero."""
        self.n_checks = 0
        self.n_narrow = 0
