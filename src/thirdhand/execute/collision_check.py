"""Checking configurations and paths of a collision world: pairs, margins, batched checks.

The checking half of :class:`~thirdhand.execute.scene.CollisionScene` (which
builds the world: table, boxes, parts, attach and detach). A configuration is
checked in two phases, batched over many configurations at once: world-frame
bounding boxes of every body (robot links from
:class:`~thirdhand.execute.kinematics.Chain`, numpy) over a fixed list of active
pairs, then coal's exact narrow phase on the pairs whose boxes overlap,
stopping at the first contact. Paths are interpolated so that no point of the
robot or the grasped part moves more than a given distance between two checks,
and checked coarse to fine. Poses are homogeneous (4, 4) matrices in the
world frame, metres; configurations are radians.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from functools import lru_cache

import coal
import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from thirdhand.arrays import BoolArray, FloatArray, IndexArray
from thirdhand.execute import sphere_check as sc
from thirdhand.execute.robot import Robot
from thirdhand.execute.spheres import SphereCover, cover_geometry, transform_cover

GRIPPER = "gripper"
ROBOT = "robot"

#: Reach of the path kernel's margin levels, configurations on either side (see
#: :meth:`SceneChecks._path_levels`); a longer stretch is split before it is tested.
PATH_REACH = np.concatenate([[0], 2 ** np.arange(13)]).astype(np.int64)

#: What :meth:`SceneChecks._invalidate` keeps per allowed set: the active pairs, their
#: split for the kernels, the margins and the path kernel's margin levels.
PairState = tuple[
    tuple[IndexArray, IndexArray],
    tuple[IndexArray, sc.PairBlocks, IndexArray, FloatArray] | None,
    dict[float, FloatArray],
    dict[float, tuple[FloatArray, FloatArray, IndexArray] | None],
]


@dataclass
class Body:
    """A body of the world: a coal geometry, where it is, and its local bounding box."""

    name: str
    geometry: coal.CollisionGeometry
    transform: FloatArray  # T_world_body (objects) or T_joint_geom (robot links), (4, 4)
    center: FloatArray  # local AABB centre (3,)
    half: FloatArray  # local AABB half extents (3,)
    offset: FloatArray = field(default_factory=lambda: np.eye(4))  # T_part_geometry


def coal_transform(t: FloatArray) -> coal.Transform3s:
    """coal transform of a homogeneous matrix (4, 4)."""
    return coal.Transform3s(np.ascontiguousarray(t[:3, :3]), np.ascontiguousarray(t[:3, 3]))


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
    """Pairs, margins and the batched checks of a collision world (see the module notes).

    The attributes are set by :class:`~thirdhand.execute.scene.CollisionScene`.
    """

    robot: Robot
    tolerance: float
    use_spheres: bool
    n_checks: int
    n_narrow: int
    _requests: dict[float, coal.CollisionRequest]
    _result: coal.CollisionResult
    _links: list[Body]
    _link_joint: IndexArray
    _link_names: list[str]
    _self_pairs: list[tuple[int, int]]
    _objects: dict[str, Body]
    _attached: Body | None
    _t_tool_attached: FloatArray
    _touch_links: set[str]
    _allowed: set[frozenset[str]]
    _pairs: tuple[IndexArray, IndexArray] | None
    _lever: FloatArray | None
    _moving: IndexArray
    _sworld: sc.SphereWorld | None
    _spairs: tuple[IndexArray, sc.PairBlocks, IndexArray, FloatArray] | None
    _fixed: list[FloatArray | None]
    _fixed_dist: dict[tuple[int, int], float]
    _margin_cache: dict[float, FloatArray]
    _path_margin_cache: dict[float, tuple[FloatArray, FloatArray, IndexArray] | None]
    _chain_cache: tuple[object, sc.ChainArrays] | None
    _pairs_key: frozenset[frozenset[str]]
    _pair_states: dict[frozenset[frozenset[str]], PairState]

    # -- pairs ------------------------------------------------------------------------

    def _invalidate(self, *, bodies: bool = True, poses: bool = True) -> None:
        """Forget the cached pairs and margins (and, with ``bodies``, lever arms and spheres).

        Without ``bodies`` and ``poses`` (a pair allowed or disallowed: ``_allowed`` already
        changed) the pairs, margins and kernel split of the allowed set left are kept, and
        those of the set now in force come back if it was seen before: step search allows
        and disallows a gripper at its part hundreds of times per step. ``poses`` (an object
        moved) drops them all (their fixed distances changed).
        """
        kept = None
        if bodies or poses:
            self._pair_states = {}
        else:
            if self._pairs is not None:
                self._pair_states[self._pairs_key] = (
                    self._pairs, self._spairs, self._margin_cache, self._path_margin_cache
                )  # fmt: skip
            kept = self._pair_states.get(frozenset(self._allowed))
        if kept is not None:
            self._pairs, self._spairs, self._margin_cache, self._path_margin_cache = kept
            self._pairs_key = frozenset(self._allowed)
        else:
            self._pairs = None
            self._spairs = None
            self._margin_cache = {}
            self._path_margin_cache = {}
        if bodies:
            self._lever = None
            self._sworld = None

    def _is_allowed(self, a: str, b: str, a_is_link: bool) -> bool:
        al = self._allowed
        if frozenset((a, b)) in al:
            return True
        if a_is_link:
            if frozenset((ROBOT, b)) in al:
                return True
            if a in self.robot.gripper_links and frozenset((GRIPPER, b)) in al:
                return True
        return False

    def _active_pairs(self) -> tuple[IndexArray, IndexArray]:
        """Body index pairs: links 0..G-1, objects G..G+E-1, grasped part G+E."""
        if self._pairs is not None:
            return self._pairs
        self._pairs_key = frozenset(self._allowed)
        names = self._link_names
        n_links = len(names)
        objs = list(self._objects.values())
        first: list[int] = []
        second: list[int] = []
        for i, j in self._self_pairs:
            if frozenset((names[i], names[j])) not in self._allowed:
                first.append(i)
                second.append(j)
        for k, obj in enumerate(objs):
            for i in range(n_links):
                if not self._is_allowed(names[i], obj.name, True):
                    first.append(i)
                    second.append(n_links + k)
        if self._attached is not None:
            a_idx = n_links + len(objs)
            a_name = self._attached.name
            for k, obj in enumerate(objs):
                if frozenset((a_name, obj.name)) not in self._allowed:
                    first.append(a_idx)
                    second.append(n_links + k)
            exempt = set(self.robot.gripper_links) | self._touch_links
            for i in range(n_links):
                if names[i] not in exempt and not self._is_allowed(names[i], a_name, True):
                    first.append(a_idx)
                    second.append(i)
        self._pairs = (np.array(first, dtype=np.intp), np.array(second, dtype=np.intp))
        return self._pairs

    def _margin(self, a: Body, b: Body) -> float:
        """Contact margin of a pair: ``-tolerance``, or 0 with a mesh (coal's limitation)."""
        mesh = isinstance(a.geometry, coal.BVHModelBase) or isinstance(
            b.geometry, coal.BVHModelBase
        )
        return 0.0 if mesh else -self.tolerance

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

    def _pair_margins(self, clearance: float = 0.0) -> FloatArray:
        """Security margin of every active pair, metres, shape (P,) (cached till the world changes).

        Without clearance, the contact margin. With it, pairs with one moving body
        need ``clearance`` and pairs of two moving bodies twice that.
        """
        key = float(max(clearance, 0.0))
        cached = self._margin_cache.get(key)
        if cached is None:
            cached = self._margin_cache[key] = self._compute_margins(key)
        return cached

    def _compute_margins(self, clearance: float) -> FloatArray:
        first, second = self._active_pairs()
        bodies = self._bodies()
        base = np.array(
            [self._margin(bodies[a], bodies[b]) for a, b in zip(first, second, strict=True)]
        )
        if clearance <= 0.0:
            return base
        n_moving = self._pair_moving()
        return np.where(n_moving > 0, clearance * n_moving, base)

    def _pair_moving(self) -> IndexArray:
        """How many of each active pair's two bodies the arm moves (0, 1 or 2), shape (P,)."""
        first, second = self._active_pairs()
        moving = np.zeros(len(self._bodies()), dtype=bool)
        moving[: len(self._links)] = self._link_joint >= 0
        if self._attached is not None:
            moving[-1] = True
        return moving[first].astype(np.intp) + moving[second].astype(np.intp)

    def _fixed_frame(self, k: int) -> FloatArray | None:
        """World transform of link ``k`` if no joint moves it as a set, else None.

        A link on the first joint whose geometry is symmetric about that joint's
        axis (a sphere centred on it, a cylinder or capsule along it) occupies the
        same space at every angle: Panda's ``panda_link1``.
        """
        j = int(self._link_joint[k])
        link = self._links[k]
        if j < 0:
            return link.transform
        chain = self.robot.chain
        if chain.parents[j] >= 0:
            return None
        axis = chain.axes[j]
        on_axis = bool(np.linalg.norm(np.cross(axis, link.transform[:3, 3])) < 1e-9)
        geom = link.geometry
        if isinstance(geom, coal.Sphere):
            symmetric = on_axis
        elif isinstance(geom, (coal.Cylinder, coal.Capsule)):
            symmetric = on_axis and abs(abs(float(axis @ link.transform[:3, 2])) - 1.0) < 1e-12
        else:
            symmetric = False
        return chain.placements[j] @ link.transform if symmetric else None

    def _sphere_world(self) -> sc.SphereWorld:
        """Sphere covers of every body, each in the frame that moves it (cached, see the module)."""
        if self._sworld is not None:
            return self._sworld
        bodies = self._bodies()
        n_links = len(self._links)
        covers: list[SphereCover | None] = []
        frames: list[int] = []
        boxes: dict[int, tuple[FloatArray, FloatArray]] = {}
        fixed: list[FloatArray | None] = []
        for k, body in enumerate(bodies):
            if k < n_links:
                t_fixed = self._fixed_frame(k)
                frame, t = (-1, t_fixed) if t_fixed is not None else (
                    int(self._link_joint[k]), body.transform)  # fmt: skip
            elif self._attached is body:
                frame = self.robot._tool_joint
                t = self.robot._t_joint_tool @ body.transform
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

    def _chain_arrays(self) -> sc.ChainArrays:
        cached = self._chain_cache
        if cached is None or cached[0] is not self.robot.chain:
            chain = self.robot.chain
            arrays = sc.ChainArrays(chain.placements, chain.axes, chain.parents.astype(np.int64))
            cached = self._chain_cache = (chain, arrays)
        return cached[1]

    def _path_levels(
        self, max_step_m: float, margins: FloatArray | None = None
    ) -> tuple[FloatArray, FloatArray, IndexArray] | None:
        """The path kernel's margin levels (see :func:`.sphere_check.path_flagged`) for a path
        interpolated at ``max_step_m``, or None when two fixed bodies are within their contact
        margin.

        Level 0 is ``margins`` (P,), by default the path clearance (half a step per moving
        body, cached till the world changes); level l stands for the ``PATH_REACH[l]``
        configurations on either side: it adds that many steps per moving body.
        """
        key = float(max_step_m)
        if margins is None and key in self._path_margin_cache:
            return self._path_margin_cache[key]
        base = self._pair_margins(max_step_m / 2.0) if margins is None else margins
        idx, pairs, fixed_idx, dists = self._sphere_pairs()
        levels = None
        # fixed pairs do not move relative to each other: their distance is known, and
        # only their contact margin applies (no clearance)
        if not np.any(dists <= np.maximum(self._pair_margins()[fixed_idx], 0.0) + 1e-6):
            n_moving = self._pair_moving()[idx]
            m = np.maximum(base[idx], 0.0)[None] + (PATH_REACH * max_step_m)[:, None] * n_moving
            levels = (*sc.sorted_margins(pairs, m), PATH_REACH)
        if margins is None:
            self._path_margin_cache[key] = levels
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
        _, pairs, _, _ = self._sphere_pairs()
        first, tests = sc.path_flagged(
            self._sphere_world(), self._chain_arrays(), dense, pairs, levels
        )
        self.n_checks += tests
        return first

    def _sphere_pairs(self) -> tuple[IndexArray, sc.PairBlocks, IndexArray, FloatArray]:
        """Active pairs split for the kernels: moving ones, and fixed ones (distance known).

        Returns the indices of the pairs with a moving body and their blocks for the
        kernels, the indices of the pairs of two fixed bodies and coal's exact distance
        of each (computed once: it does not depend on the configuration).
        """
        if self._spairs is not None:
            return self._spairs
        world = self._sphere_world()
        first, second = self._active_pairs()
        # two bodies no joint moves, or moved by the same joint (a grasped part and its
        # hand's links): their distance does not depend on the configuration
        moving = world.frame[first] != world.frame[second]
        fixed_idx = np.flatnonzero(~moving)
        bodies = self._bodies()
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
                        t_home = self._transforms(self.robot.home[None])[0]
                    ta, tb = t_home[a], t_home[b]
                assert ta is not None and tb is not None
                res = coal.DistanceResult()
                ga, gb = bodies[a].geometry, bodies[b].geometry
                d = float(coal.distance(ga, coal_transform(ta), gb, coal_transform(tb), req, res))
                self._fixed_dist[(a, b)] = d
            dists[n] = d
        idx = np.flatnonzero(moving)
        blocks = sc.pair_blocks(world, np.column_stack([first[idx], second[idx]]))
        self._spairs = (idx, blocks, fixed_idx, dists)
        return self._spairs

    def sphere_flags(self, qs: ArrayLike, margins: FloatArray | None = None) -> BoolArray:
        """Active pairs the sphere covers cannot clear, per configuration, shape (n, P).

        Unflagged pairs are certainly free in coal's exact check (the covers are
        conservative, :mod:`~thirdhand.execute.spheres`); ``margins`` (P,) default
        to the contact margins. Pairs of two bodies no joint moves are flagged from
        their exact distance, computed once.
        """
        qa = np.asarray(qs, dtype=np.float64).reshape(-1, self.robot.dof)
        m = self._pair_margins() if margins is None else margins
        world = self._sphere_world()
        idx, pairs, fixed_idx, dists = self._sphere_pairs()
        out = np.zeros((qa.shape[0], len(m)), dtype=bool)
        out[:, idx] = sc.flags(world, self._chain_arrays(), qa, pairs, m[idx])
        out[:, fixed_idx] = (dists <= np.maximum(m[fixed_idx], 0.0) + 1e-6)[None]
        return out

    def sphere_free_mask(self, qs: ArrayLike, margins: FloatArray | None = None) -> BoolArray:
        """True where the sphere covers alone prove a configuration collision-free, shape (n,).

        Conservative: may say "not free" where coal finds no contact, never "free"
        where it finds one. Joint limits are not checked.
        """
        qa = np.asarray(qs, dtype=np.float64).reshape(-1, self.robot.dof)
        m = self._pair_margins() if margins is None else margins
        world = self._sphere_world()
        idx, pairs, fixed_idx, dists = self._sphere_pairs()
        if np.any(dists <= np.maximum(m[fixed_idx], 0.0) + 1e-6):
            return np.zeros(qa.shape[0], dtype=bool)
        return sc.free(world, self._chain_arrays(), qa, pairs, m[idx])

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

    def _bodies(self) -> list[Body]:
        bodies = self._links + list(self._objects.values())
        if self._attached is not None:
            bodies.append(self._attached)
        return bodies

    def _transforms(self, qs: FloatArray) -> FloatArray:
        """World transforms of all bodies, shape (n, B, 4, 4)."""
        n = qs.shape[0]
        bodies = self._bodies()
        out = np.empty((n, len(bodies), 4, 4))
        tj = self.robot.chain.joint_transforms(qs)
        n_links = len(self._links)
        local = np.array([b.transform for b in self._links])
        static = self._link_joint < 0
        out[:, :n_links] = local[None]
        mv = ~static
        out[:, :n_links][:, mv] = tj[:, self._link_joint[mv]] @ local[mv]
        k = n_links
        for obj in self._objects.values():
            out[:, k] = obj.transform
            k += 1
        if self._attached is not None:
            out[:, k] = self.robot.tool_transforms(qs) @ self._attached.transform
        return out

    # -- checking ---------------------------------------------------------------------

    def valid_mask(
        self, qs: ArrayLike, *, stop_at_first: bool = False, exact: bool = False
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

        Returns
        -------
        ndarray of bool, shape (n,)
        """
        qa = np.asarray(qs, dtype=np.float64).reshape(-1, self.robot.dof)
        return self._check(qa, self._pair_margins(), stop_at_first, exact=exact)

    def _candidates(self, qa: FloatArray, margins: FloatArray, exact: bool) -> BoolArray:
        """Pairs coal must decide per configuration (n, P): sphere flags, or overlapping boxes."""
        if not exact and self.use_spheres:
            return self.sphere_flags(qa, margins)
        first, second = self._active_pairs()
        bodies = self._bodies()
        centers = np.array([b.center for b in bodies])
        halves = np.array([b.half for b in bodies])
        c, h = world_aabb(self._transforms(qa), centers[None], halves[None])
        reach = h[:, first] + h[:, second] + np.maximum(margins, 0.0)[None, :, None] + 1e-9
        return np.all(np.abs(c[:, first] - c[:, second]) <= reach, axis=2)

    def _check(
        self, qa: FloatArray, margins: FloatArray, stop_at_first: bool, *, exact: bool = False
    ) -> BoolArray:
        """:meth:`valid_mask` with a security margin per active pair."""
        n = qa.shape[0]
        ok = np.all((qa >= self.robot.lower - 1e-9) & (qa <= self.robot.upper + 1e-9), axis=1)
        overlap = self._candidates(qa, margins, exact)
        flagged = np.any(overlap, axis=1)
        if not np.any(flagged & ok):  # no pair for coal: limits decide
            if stop_at_first and not np.all(ok):
                bad = int(np.argmin(ok))
                self.n_checks += bad + 1
                ok[bad:] = False
            else:
                self.n_checks += n
            return ok
        first, second = self._active_pairs()
        bodies = self._bodies()
        rows = np.flatnonzero(flagged)
        t_rows = self._transforms(qa[rows])
        row_of = np.full(n, -1, dtype=np.intp)
        row_of[rows] = np.arange(len(rows))
        requests = self._requests_of(margins)
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

    def is_valid(self, q: ArrayLike) -> bool:
        """True if ``q`` (dof,) is within the joint limits and collision-free."""
        return bool(self.valid_mask(self.robot.check_q(q)[None])[0])

    def collisions(self, q: ArrayLike) -> list[tuple[str, str]]:
        """Every colliding pair of body (link or object) names at ``q`` (dof,), for diagnostics."""
        first, second = self._active_pairs()
        bodies = self._bodies()
        hits = self._pair_hits(self.robot.check_q(q), self._pair_margins())
        out: list[tuple[str, str]] = []
        for p in np.flatnonzero(hits):
            pair = (bodies[first[p]].name, bodies[second[p]].name)
            if pair not in out:
                out.append(pair)
        return out

    def _pair_hits(self, q: FloatArray, margins: FloatArray) -> NDArray[np.bool_]:
        """Which active pairs collide at ``q`` (dof,) under ``margins`` (P,)."""
        first, second = self._active_pairs()
        bodies = self._bodies()
        if self.use_spheres:
            candidates = self.sphere_flags(q[None], margins)[0]
        else:
            candidates = self._candidates(q[None], margins, True)[0]
        hits = np.zeros(len(first), dtype=bool)
        if not np.any(candidates):
            return hits
        t = self._transforms(q[None])[0]
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
        tj = self.robot.chain.joint_transforms(q)[0]
        bodies = self._bodies()
        t = self._transforms(q)[0]
        radius = np.zeros(self.robot.dof)
        n_links = len(self._links)
        for k, body in enumerate(bodies):
            if k < n_links:
                j = int(self._link_joint[k])
                if j < 0:
                    continue
                moved = self.robot.chain.ancestors(j)
            elif self._attached is body:
                moved = self.robot.chain.ancestors(self.robot._tool_joint)
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
        their contact tolerance instead.

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
        margins = self._pair_margins()
        if clearance and len(qa) > 1:
            wide = self._pair_margins(max_step_m / 2.0)
            if not self.use_spheres or np.any(self.sphere_flags(qa[[0, -1]], wide)):
                if not np.all(self._check(qa[[0, -1]], margins, False)):
                    return False
                near = self._pair_hits(qa[0], wide) | self._pair_hits(qa[-1], wide)
                margins = np.where(near, margins, wide)
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
            if first >= 0 and not self._check(dense[first : first + 1], margins, True)[0]:
                return False
        # coarse to fine (bit-reversed order): a colliding stretch is hit after few checks
        dense = dense[_coarse_to_fine(dense.shape[0])]
        for k in range(0, dense.shape[0], chunk):
            if not np.all(self._check(dense[k : k + chunk], margins, True)):
                return False
        return True

    def reset_counter(self) -> None:
        """Set :attr:`n_checks` and :attr:`n_narrow` to zero."""
        self.n_checks = 0
        self.n_narrow = 0
