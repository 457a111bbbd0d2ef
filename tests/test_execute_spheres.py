"""The sphere layer: covers hold their geometry, FK matches pinocchio, verdicts are conservative."""

from __future__ import annotations

import itertools

import coal
import numpy as np
import pinocchio as pin
import pytest

from thirdhand.execute import CollisionScene, Robot, plan_motion
from thirdhand.execute import sphere_check as sc
from thirdhand.execute.collision_check import geometry_cover
from thirdhand.execute.meshes import box, mesh_from_triangles
from thirdhand.execute.spheres import cover_geometry, mesh_triangles, transform_cover
from thirdhand.se3 import pose_from_matrix


@pytest.fixture(scope="module")
def panda() -> Robot:
    return Robot.load("panda", base_pose=([0.0, 0.0, 0.75], [0, 0, 0, 1]))


@pytest.fixture(scope="module")
def baxter() -> Robot:
    return Robot.load("baxter", base_pose=([-0.25, 0.22, 0.93], [0.0, 0.0, 0.0, 1.0]))


def _inside(points: np.ndarray, spheres: np.ndarray) -> np.ndarray:
    """Whether each point (n, 3) lies in some sphere (m, 4)."""
    out = np.empty(len(points), dtype=bool)
    for k in range(0, len(points), 500):
        p = points[k : k + 500]
        d2 = np.sum((p[:, None, :] - spheres[None, :, :3]) ** 2, axis=2)
        out[k : k + 500] = np.any(d2 <= spheres[None, :, 3] ** 2, axis=1)
    return out


def _samples(geometry: coal.CollisionGeometry, rng: np.random.Generator, n: int) -> np.ndarray:
    """Points of what coal counts as the geometry: primitives solid (boundary included), meshes
    their triangles."""
    u = rng.uniform(-1.0, 1.0, size=(n, 3))
    if isinstance(geometry, coal.Sphere):
        d = rng.normal(size=(n, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        return d * geometry.radius * np.sqrt(rng.uniform(0.0, 1.0, size=(n, 1)))
    if isinstance(geometry, coal.Cylinder):
        ang = rng.uniform(0.0, 2 * np.pi, n)
        rad = geometry.radius * np.sqrt(rng.uniform(0.0, 1.0, n))
        rad[: n // 2] = geometry.radius  # half on the mantle, the worst place
        z = u[:, 2] * geometry.halfLength
        z[: n // 8] = np.sign(z[: n // 8]) * geometry.halfLength  # rims
        return np.column_stack([rad * np.cos(ang), rad * np.sin(ang), z])
    if isinstance(geometry, coal.Box):
        p = u * np.asarray(geometry.halfSide)
        p[: n // 2] = np.sign(p[: n // 2]) * np.asarray(geometry.halfSide)  # corners
        return p
    tri = mesh_triangles(geometry)
    k = rng.integers(0, len(tri), n)
    a, b = rng.uniform(size=(2, n, 1))
    flip = (a + b) > 1
    a, b = np.where(flip, 1 - a, a), np.where(flip, 1 - b, b)
    t = tri[k]
    return t[:, 0] + a * (t[:, 1] - t[:, 0]) + b * (t[:, 2] - t[:, 0])


@pytest.mark.parametrize("name", ["panda", "baxter"])
def test_every_link_cover_holds_its_geometry(name: str, request) -> None:
    robot = request.getfixturevalue(name)
    rng = np.random.default_rng(0)
    for g in robot.geometry.geometryObjects:
        cover = geometry_cover(g.geometry)
        pts = _samples(g.geometry, rng, 4000)
        inside = _inside(pts, cover.spheres)
        assert inside.all(), (g.name, pts[~inside][:3])
        # the groups hold their spheres, the bound holds the groups
        for (a, b), grp in zip(cover.group_range, cover.groups, strict=True):
            reach = np.linalg.norm(cover.spheres[a:b, :3] - grp[:3], axis=1) + cover.spheres[a:b, 3]
            assert np.all(reach <= grp[3] + 1e-12)
        reach = np.linalg.norm(cover.groups[:, :3] - cover.bound[:3], axis=1) + cover.groups[:, 3]
        assert np.all(reach <= cover.bound[3] + 1e-12)


def _ring_mesh() -> coal.BVHModelOBBRSS:
    """A closed, long and thin triangle mesh (a twisted tube 30 cm long), metres."""
    k, n = 12, 6
    ang = np.linspace(0, 2 * np.pi, k, endpoint=False)
    z = np.linspace(0.0, 0.3, n)
    ring = lambda zz, tw: np.column_stack(  # noqa: E731
        [0.03 * np.cos(ang + tw), 0.015 * np.sin(ang + tw), np.full(k, zz)]
    )
    tris = []
    for i in range(n - 1):
        a, b = ring(z[i], 0.3 * i), ring(z[i + 1], 0.3 * (i + 1))
        for j in range(k):
            jj = (j + 1) % k
            tris += [[a[j], a[jj], b[j]], [a[jj], b[jj], b[j]]]
    return mesh_from_triangles(np.array(tris))


def test_mesh_and_box_covers_hold_their_surface_and_solid() -> None:
    rng = np.random.default_rng(1)
    mesh = _ring_mesh()
    for geom in (mesh, box((0.3, 0.05, 0.02)), box((0.08, 0.08, 0.28))):
        cover = cover_geometry(geom)
        pts = _samples(geom, rng, 10000)
        assert _inside(pts, cover.spheres).all()
    # the cover of a mesh stays close to it: no sphere much larger than the cell
    assert cover_geometry(mesh).spheres[:, 3].max() < 0.02
    # moved covers move with their geometry
    t = np.eye(4)
    t[:3, :3] = pin.rpy.rpyToMatrix(0.3, -0.2, 1.1)
    t[:3, 3] = [0.1, -0.2, 0.3]
    moved = transform_cover(cover_geometry(mesh), t)
    pts = _samples(mesh, rng, 5000) @ t[:3, :3].T + t[:3, 3]
    assert _inside(pts, moved.spheres).all()


@pytest.mark.parametrize("name", ["panda", "baxter"])
def test_numba_forward_kinematics_matches_pinocchio(name: str, request) -> None:
    robot = request.getfixturevalue(name)
    qs = robot.random_q(np.random.default_rng(2), 200)
    chain = robot.chain
    t = sc.joint_transforms_nb(qs, chain.placements, chain.axes, chain.parents.astype(np.int64))
    data = robot.model.createData()
    for q, tq in zip(qs, t, strict=True):
        pin.forwardKinematics(robot.model, data, q)
        for j in range(robot.dof):
            np.testing.assert_allclose(tq[j], data.oMi[j + 1].homogeneous, atol=1e-9, rtol=0)


def _world(robot: Robot, table_z: float, x0: float) -> CollisionScene:
    """Table, a post, a mesh part lying on the table, a box part in the hand."""
    scene = CollisionScene(robot)
    scene.add_table(height=table_z, center=(x0 + 0.6, 0.0), size=(1.2, 1.6))
    scene.add_box("post", ([x0 + 0.45, 0.2, table_z + 0.15], [0, 0, 0, 1]), (0.05, 0.05, 0.3))
    t_tube = np.array(
        [[0, 0, 1, x0 + 0.4], [0, 1, 0, -0.25], [-1, 0, 0, table_z + 0.04], [0, 0, 0, 1.0]]
    )
    scene.add_geometry("tube", _ring_mesh(), pose_from_matrix(t_tube))
    scene.add_object("held", ([x0 + 0.5, 0.0, table_z + 0.3], [0, 0, 0, 1]), size=(0.04, 0.04, 0.2))
    q = robot.ik(([x0 + 0.5, 0.0, table_z + 0.3], [1.0, 0, 0, 0]), seed=0)
    assert q is not None
    scene.attach("held", q)
    return scene


@pytest.mark.slow
@pytest.mark.parametrize(("name", "table_z", "x0"), [("panda", 0.75, 0.0), ("baxter", 0.75, 0.1)])
def test_spheres_never_say_free_where_coal_says_collision(name, table_z, x0, request) -> None:
    robot = request.getfixturevalue(name)
    scene = _world(robot, table_z, x0)
    qs = robot.random_q(np.random.default_rng(3), 10_000)
    free = scene.sphere_free_mask(qs)
    exact = scene.valid_mask(qs, exact=True)
    assert not np.any(free & ~exact)  # conservative: "free" only where coal finds no contact
    assert free.sum() > 0.5 * exact.sum()  # and not vacuous
    # spheres as the broad phase: the same verdicts as the bounding boxes
    np.testing.assert_array_equal(scene.valid_mask(qs[:3000]), exact[:3000])
    # with a security margin too (the clearance of path checks)
    wide = scene.checks.pair_margins(0.005)
    flags = scene.checks.sphere_flags(qs[:500], wide)
    exact_wide = scene.checks.valid_mask(qs[:500], margins=wide, exact=True)
    assert not np.any(~flags.any(axis=1) & ~exact_wide)


def test_path_check_by_spheres_implies_the_exact_one_and_plans_are_clean(panda: Robot) -> None:
    scene = CollisionScene(panda)
    scene.add_table(height=0.75)
    scene.add_box("wall", ([0.5, 0.0, 0.95], [0, 0, 0, 1]), (0.3, 0.04, 0.4))
    rng = np.random.default_rng(4)
    n_free = 0
    for _ in range(60):
        a, b = panda.random_q(rng, 2)
        if scene.path_free_spheres(np.stack([a, b])):
            n_free += 1
            assert scene.check_path(np.stack([a, b]))
    assert n_free > 0
    qa = panda.ik(([0.5, -0.25, 0.9], [1.0, 0, 0, 0]), seed=0, accept=scene.is_valid)
    qb = panda.ik(([0.5, 0.25, 0.9], [1.0, 0, 0, 0]), seed=0, accept=scene.is_valid)
    for seed in range(3):
        res = plan_motion(panda, scene, qa, qb, seed=seed, time_limit=20.0)
        assert res.success and res.path is not None
        dense = scene.interpolate(res.path, max_step_m=0.005, max_step_rad=0.01)
        assert scene.valid_mask(dense, exact=True).all()


def test_path_levels_give_the_dense_verdict_and_stay_sound(panda: Robot) -> None:
    """The path kernel clears a stretch by one test at its middle with margins widened by
    the stretch's reach. Cross-checked against brute force on short random segments in a
    cluttered world with a part in the hand: every path the dense sphere check (each
    configuration at the path margins) clears is cleared; every path cleared passes coal's
    exact dense check with the clearance; the tests made are at most two per configuration."""
    scene = _world(panda, 0.75, 0.0)
    rng = np.random.default_rng(11)
    step = 0.01
    margins = scene.checks.pair_margins(step / 2.0)
    q0 = panda.random_q(rng, 400)
    counts = {"dense free": 0, "cleared": 0, "fewer tests": 0}
    for qa in q0:
        qb = np.clip(qa + rng.normal(0.0, 0.4, panda.dof), panda.lower, panda.upper)
        seg = np.stack([qa, qb])
        dense = scene.interpolate(seg, max_step_m=step)
        dense_free = bool(scene.sphere_free_mask(dense, margins).all())
        before = scene.n_checks
        cleared = scene.path_free_spheres(seg, max_step_m=step)
        tests = scene.n_checks - before
        assert tests <= 2 * len(dense)
        if dense_free:
            assert cleared
            counts["dense free"] += 1
            counts["fewer tests"] += tests < len(dense)
        if cleared:
            counts["cleared"] += 1
            assert scene.check_path(seg, max_step_m=step)
    # not vacuous: many free paths, and most of them cleared with fewer tests than configurations
    assert counts["dense free"] >= 40
    assert counts["fewer tests"] >= counts["dense free"] // 2


def test_fixed_links_and_pairs_are_decided_once(panda: Robot) -> None:
    """panda_link1 turns about its own axis: it is a fixed body for the spheres."""
    scene = CollisionScene(panda)
    scene.add_table(height=0.75)
    # a block 1 cm from link1's bottom sphere: close at every angle of joint 1
    scene.add_box("block", ([0.105, 0.0, 0.80], [0, 0, 0, 1]), (0.01, 0.05, 0.05))
    world = scene.checks.sphere_world()
    names = [b.name for b in scene.checks.bodies.bodies]
    link1 = [k for k, n in enumerate(names) if n == "panda_link1"]
    assert all(world.frame[k] == -1 for k in link1)
    qs = panda.random_q(np.random.default_rng(5), 300)
    np.testing.assert_array_equal(scene.valid_mask(qs), scene.valid_mask(qs, exact=True))


def test_a_fixed_pair_within_the_clearance_does_not_block_the_path_check(panda: Robot) -> None:
    """Two fixed bodies closer than a path's clearance but apart by more than their contact
    margin never move relative to each other: paths are still cleared by the spheres."""
    scene = CollisionScene(panda)
    scene.add_table(height=0.75)
    # a block 3 mm from link1's bottom sphere (1 cm in the test above)
    scene.add_box("block", ([0.098, 0.0, 0.80], [0, 0, 0, 1]), (0.01, 0.05, 0.05))
    _, _, fixed_idx, dists = scene.checks.sphere_pairs()
    table = scene.checks.pair_table()
    first, second = table.first, table.second
    names = [b.name for b in scene.checks.bodies.bodies]
    near = [
        d for p, d in zip(fixed_idx, dists, strict=True)
        if {names[first[p]], names[second[p]]} == {"panda_link1", "block"}
    ]  # fmt: skip
    assert near and 0.0 < min(near) < 0.005  # within half a 1-cm step, apart
    rng = np.random.default_rng(12)
    cleared = 0
    for qa in panda.random_q(rng, 100):
        seg = np.stack(
            [qa, np.clip(qa + rng.normal(0.0, 0.2, panda.dof), panda.lower, panda.upper)]
        )
        if scene.path_free_spheres(seg):
            cleared += 1
            assert scene.check_path(seg)
    assert cleared >= 20


def test_allowing_and_disallowing_a_pair_brings_back_its_checks(panda: Robot) -> None:
    """Step search allows and disallows a gripper at its part hundreds of times: the pairs,
    margins and kernel split of an allowed set are kept and brought back (the very same
    arrays), with the verdicts of a fresh scene; moving an object drops them."""

    def world() -> CollisionScene:
        scene = CollisionScene(panda)
        scene.add_table(height=0.75)
        scene.add_box("post", ([0.45, 0.2, 0.9], [0, 0, 0, 1]), (0.05, 0.05, 0.3))
        scene.add_object("held", ([0.5, 0.0, 1.05], [0, 0, 0, 1]), size=(0.04, 0.04, 0.2))
        return scene

    scene = world()
    qs = panda.random_q(np.random.default_rng(13), 400)
    base = scene.valid_mask(qs)
    split = scene.checks.sphere_pairs()
    scene.allow("gripper", "held")
    allowed = scene.valid_mask(qs)
    assert np.any(allowed & ~base)  # not vacuous: the gripper meets the part somewhere
    scene.disallow("gripper", "held")
    assert scene.checks.sphere_pairs() is split
    np.testing.assert_array_equal(scene.valid_mask(qs), base)
    scene.allow("gripper", "held")
    np.testing.assert_array_equal(scene.valid_mask(qs), allowed)
    scene.disallow("gripper", "held")
    # a moved object: new distances, new verdicts, the same as a scene built that way
    scene.set_object_pose("held", ([0.3, -0.3, 1.0], [0, 0, 0, 1]))
    assert scene.checks.sphere_pairs() is not split
    fresh = world()
    fresh.set_object_pose("held", ([0.3, -0.3, 1.0], [0, 0, 0, 1]))
    moved = scene.valid_mask(qs)
    assert np.any(moved != base)
    np.testing.assert_array_equal(moved, fresh.valid_mask(qs, exact=True))


def test_compiled_interpolation_is_the_reference_one(panda: Robot) -> None:
    """``interpolate`` (compiled) gives the configurations of its definition: per segment
    ``ceil(max(Σ|Δq|·lever / step_m, max|Δq| / step_rad))`` (at least 1) evenly spaced
    steps, the waypoints included. The sphere path check over them proves free only what
    the exact one accepts, and never a path leaving the joint limits."""
    scene = CollisionScene(panda)
    scene.add_table(height=0.75)
    lever = scene.checks.motion_bound()
    rng = np.random.default_rng(9)
    for n in (2, 3, 5):
        qs = panda.random_q(rng, n)
        qs[1] = qs[0]  # a zero-length segment: one step
        got = scene.interpolate(qs, max_step_m=0.01, max_step_rad=0.02)
        parts = [qs[:1]]
        for a, b in itertools.pairwise(qs):
            d = np.abs(b - a)
            c = max(int(np.ceil(max(d @ lever / 0.01, d.max() / 0.02))), 1)
            s = (np.arange(1, c + 1) / c)[:, None]
            parts.append((1.0 - s) * a + s * b)
        want = np.vstack(parts)
        assert got.shape == want.shape
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-15)
        free = scene.path_free_spheres(qs)
        # the spheres prove free only what the exact check of the clearance accepts
        if free:
            assert scene.check_path(qs)
    # a waypoint outside the joint limits: never free
    bad = panda.random_q(rng, 2)
    bad[1, 0] = panda.upper[0] + 0.1
    assert not scene.path_free_spheres(bad)


def test_block_pruning_flags_exactly_what_the_pairs_flag(panda: Robot) -> None:
    """The blocks' box and side-sphere tests only skip pairs no sphere could flag: the
    pair flags equal those of the same blocks tested by their cluster spheres alone."""
    import dataclasses

    scene = _world(panda, 0.75, 0.0)
    world = scene.checks.sphere_world()
    idx, blocks, _, _ = scene.checks.sphere_pairs()
    assert np.any(blocks.blocks[:, 4] == 1)  # a link's side of the fingers is pruned
    assert np.any(blocks.cluster_frame <= -2)  # the table is tested as a box
    plain = dataclasses.replace(
        blocks,
        blocks=np.column_stack([blocks.blocks[:, :4], np.zeros(len(blocks.blocks), np.int64)]),
        cluster_frame=np.where(blocks.cluster_frame <= -2, -1, blocks.cluster_frame),
        scratch=tuple(a.copy() for a in blocks.scratch),
    )
    chain = scene.checks.chain_arrays()
    qs = panda.random_q(np.random.default_rng(11), 3000)
    for margin in (0.0, 0.01):
        m = scene.checks.pair_margins(margin)[idx]
        pruned = sc.flags(world, chain, qs, blocks, m)
        np.testing.assert_array_equal(pruned, sc.flags(world, chain, qs, plain, m))
        assert pruned.any() and not pruned.all()
        np.testing.assert_array_equal(sc.free(world, chain, qs, blocks, m), ~pruned.any(axis=1))


def _brute_flags(world: sc.SphereWorld, t: np.ndarray, pairs: np.ndarray,
                 margins: np.ndarray) -> np.ndarray:  # fmt: skip
    """Pair flags of one configuration (joint frames ``t``) with no hierarchy: some sphere of
    one body within the margin of some sphere of the other, or of the box."""

    def body_spheres(b: int) -> np.ndarray:
        g0, g1 = world.body_groups[b]
        s = world.spheres[world.group_range[g0, 0] : world.group_range[g1 - 1, 1]].copy()
        if world.frame[b] >= 0:
            m = t[world.frame[b]]
            s[:, :3] = s[:, :3] @ m[:3, :3].T + m[:3, 3]
        return s

    out = np.zeros(len(pairs), dtype=bool)
    for p, (a, b) in enumerate(pairs):
        margin = max(float(margins[p]), 0.0)
        if world.kind[a] == sc.BOX and world.kind[b] == sc.BOX:
            out[p] = True
            continue
        if world.kind[a] == sc.BOX:
            a, b = b, a
        sa = body_spheres(a)
        if world.kind[b] == sc.BOX:
            local = sa[:, :3] @ world.box_inv[b, :3, :3].T + world.box_inv[b, :3, 3]
            gap = np.linalg.norm(np.maximum(np.abs(local) - world.box_half[b], 0.0), axis=1)
            out[p] = bool(np.any(gap <= sa[:, 3] + margin))
        else:
            sb = body_spheres(b)
            d = np.linalg.norm(sa[:, None, :3] - sb[None, :, :3], axis=2)
            out[p] = bool(np.any(d <= sa[:, None, 3] + sb[None, :, 3] + margin))
    return out


def test_batched_kernel_flags_what_every_sphere_pair_flags(panda: Robot) -> None:
    """The batch kernel (configurations carried together through forward kinematics and
    the cluster tests, then pair by pair) flags exactly the pairs with two spheres within
    their margin, counted with no hierarchy; a batch that does not fill its last lanes, and
    each configuration alone, give the same flags; its forward kinematics is the scalar one."""
    scene = _world(panda, 0.75, 0.0)
    world = scene.checks.sphere_world()
    idx, blocks, _, _ = scene.checks.sphere_pairs()
    chain = scene.checks.chain_arrays()
    qs = panda.random_q(np.random.default_rng(5), 2 * sc.LANES + 5)
    t = sc.joint_transforms_nb(qs, chain.placements, chain.axes, chain.parents)
    tl = np.empty((panda.dof + 1, 12, sc.LANES))
    for i0 in range(0, len(qs), sc.LANES):
        sc._fk_lanes(qs, i0, chain.placements, chain.axes, chain.parents, tl)
        for lane in range(sc.LANES):
            i = min(i0 + lane, len(qs) - 1)
            np.testing.assert_allclose(
                tl[: panda.dof, :, lane].reshape(-1, 3, 4), t[i, :, :3], atol=1e-12, rtol=0
            )
    m = scene.checks.pair_margins(0.01)[idx]
    flags = sc.flags(world, chain, qs, blocks, m)
    assert flags.any() and not flags.all()
    for i, q in enumerate(qs):
        np.testing.assert_array_equal(flags[i], _brute_flags(world, t[i], blocks.pairs[
            np.argsort(blocks.order)], m))  # fmt: skip
        np.testing.assert_array_equal(sc.flags(world, chain, q[None], blocks, m)[0], flags[i])


def test_compiled_sincos_is_libms_to_an_ulp() -> None:
    """The kernels' sin and cos (range reduction by π/2, fdlibm's polynomials) against
    numpy's, on a dense grid over ±100 rad and at the quadrant boundaries."""
    import numba

    from thirdhand.execute.kinematics import sincos

    @numba.njit
    def both(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        s, c = np.empty_like(q), np.empty_like(q)
        for i in range(q.size):
            s[i], c[i] = sincos(q[i])
        return s, c

    k = np.arange(-64, 65) * (np.pi / 4)
    q = np.concatenate([np.linspace(-100.0, 100.0, 400_001), k, np.nextafter(k, 10), [0.0]])
    s, c = both(q)
    np.testing.assert_allclose(s, np.sin(q), atol=3e-16, rtol=0)
    np.testing.assert_allclose(c, np.cos(q), atol=3e-16, rtol=0)
