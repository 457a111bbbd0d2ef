"""Exact convex pieces of parts with pockets, and the re-aiming arithmetic."""

from __future__ import annotations

import numpy as np
import pytest

from tests.sim_scenes import HOLE, PLATE, PLATE_H, box_mesh, plate_with_hole
from thirdhand import se3
from thirdhand.simulate import aim
from thirdhand.simulate.carve import exact_pieces

pytest.importorskip("manifold3d")


def _inside_any(pieces, point) -> bool:
    from scipy.spatial import Delaunay

    return any(Delaunay(p).find_simplex(point) >= 0 for p in pieces)


def _hull_volume(pieces) -> float:
    from scipy.spatial import ConvexHull

    return float(sum(ConvexHull(p).volume for p in pieces))


def _box_with_pocket(lo, hi, plo, phi) -> np.ndarray:
    """Triangles of a box minus a pocket box (manifold3d's exact difference), metres."""
    import manifold3d as mf

    def cube(a, b):
        a, b = np.asarray(a, float), np.asarray(b, float)
        return mf.Manifold.cube((b - a).tolist()).translate(a.tolist())

    m = (cube(lo, hi) - cube(plo, phi)).to_mesh()
    v = np.asarray(m.vert_properties, dtype=np.float64)[:, :3]
    return v[np.asarray(m.tri_verts)]


def test_plate_with_a_hole_is_cut_exactly() -> None:
    carved = exact_pieces(plate_with_hole())
    assert carved is not None and carved.cavities == 1
    want = (PLATE**2 - HOLE**2) * PLATE_H
    assert carved.volume_m3 == pytest.approx(want, rel=1e-6)
    # the pieces tile the part: their volumes add up to it, nothing is missing or filled
    assert _hull_volume(carved.pieces) == pytest.approx(want, rel=1e-5)
    assert carved.missing_m3 < 1e-6 * want and carved.filled_m3 == 0.0
    z = PLATE_H / 2
    assert not _inside_any(carved.pieces, [0.0, 0.0, z])
    # just inside the hole's wall: still open (CoACD's pieces bulge about 1 mm here)
    assert not _inside_any(carved.pieces, [HOLE / 2 - 1e-4, 0.0, z])
    assert _inside_any(carved.pieces, [HOLE / 2 + 1e-4, 0.0, z])


def test_a_blind_pocket_keeps_its_floor_and_a_solid_box_is_one_piece() -> None:
    lo, hi = [0.0, 0.0, 0.0], [0.1, 0.1, 0.03]
    plo, phi = [0.04, 0.04, 0.02], [0.06, 0.06, 0.04]
    carved = exact_pieces(_box_with_pocket(lo, hi, plo, phi))
    assert carved is not None and carved.cavities == 1
    want = 0.1 * 0.1 * 0.03 - 0.02 * 0.02 * 0.01
    assert _hull_volume(carved.pieces) == pytest.approx(want, rel=1e-5)
    assert not _inside_any(carved.pieces, [0.05, 0.05, 0.025])  # the pocket
    assert _inside_any(carved.pieces, [0.05, 0.05, 0.015])  # its floor
    solid = exact_pieces(box_mesh([0, 0, 0], [0.1, 0.05, 0.02]))
    assert solid is not None and len(solid.pieces) == 1 and solid.cavities == 0


def test_a_shallow_dent_is_filled_and_an_open_mesh_is_refused() -> None:
    # a 1 mm deep dent is thinner than MIN_THICKNESS_M: filled, said as a volume
    carved = exact_pieces(_box_with_pocket([0, 0, 0], [0.1, 0.1, 0.03],
                                           [0.02, 0.02, 0.029], [0.08, 0.08, 0.04]))  # fmt: skip
    assert carved is not None and carved.cavities == 0 and len(carved.pieces) == 1
    assert carved.filled_m3 == pytest.approx(0.06 * 0.06 * 0.001, rel=1e-4)
    flat = np.zeros((2, 3, 3))
    flat[0] = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
    flat[1] = [[1, 0, 0], [1, 1, 0], [0, 1, 0]]
    assert exact_pieces(flat) is None


def _pose(rotvec, p) -> np.ndarray:
    t = np.eye(4)
    t[:3, :3] = se3.matrix_from_rotvec(np.asarray(rotvec, float))
    t[:3, 3] = p
    return t


def test_tool_correction_makes_the_part_follow_its_planned_pose() -> None:
    tool = _pose([0.3, -0.2, 1.0], [0.4, 0.1, 0.5])
    g_plan = _pose([0.0, 0.0, 0.5], [0.0, 0.0, 0.05])
    g_now = _pose([0.05, 0.02, 0.45], [0.003, -0.002, 0.052])  # turned and shifted in the hand
    c = aim.tool_correction(g_plan, g_now, 1.0)
    np.testing.assert_allclose(tool @ c @ g_now, tool @ g_plan, atol=1e-12)
    np.testing.assert_allclose(aim.tool_correction(g_plan, g_now, 0.0), np.eye(4), atol=1e-15)
    half = aim.tool_correction(g_plan, g_now, 0.5)
    full = g_plan @ se3.transform_invert(g_now)
    np.testing.assert_allclose(half[:3, 3], full[:3, 3] / 2, atol=1e-15)


def test_integrated_offset_is_bounded_and_pose_twist_inverts_shifted() -> None:
    planned = _pose([0.1, 0.0, 0.0], [0.5, 0.0, 0.3])
    measured = _pose([0.1, 0.0, 0.02], [0.5, 0.004, 0.3])
    off = aim.integrate_offset(np.zeros(6), planned, measured, gain=0.5)
    np.testing.assert_allclose(off[:3], [0.0, -0.002, 0.0], atol=1e-12)
    np.testing.assert_allclose(aim.shifted(measured, aim.pose_twist(measured, planned)),
                               planned, atol=1e-12)  # fmt: skip
    far = _pose([0.0, 0.0, 1.0], [1.0, 0.0, 0.0])
    off = aim.integrate_offset(np.zeros(6), far, np.eye(4), gain=1.0)
    assert np.linalg.norm(off[:3]) == pytest.approx(aim.MAX_OFFSET_M)
    assert np.linalg.norm(off[3:]) == pytest.approx(aim.MAX_OFFSET_RAD)


def test_offset_in_contact_grows_only_across_the_insertion_axis() -> None:
    planned = _pose([0.0, 0.0, 0.0], [0.5, 0.0, 0.3])
    measured = _pose([0.0, 0.0, 0.0], [0.502, -0.001, 0.309])  # 9 mm short, 2 and 1 mm aside
    axis = np.array([0.0, 0.0, -0.05])  # in: straight down, any length
    off = aim.integrate_offset(np.zeros(6), planned, measured, gain=0.5, across=axis)
    np.testing.assert_allclose(off[:3], [-0.001, 0.0005, 0.0], atol=1e-15)
    tilted = np.array([0.0, 1.0, -1.0])  # along a slanted axis: the error across it only
    off = aim.integrate_offset(np.zeros(6), planned, measured, gain=1.0, across=tilted)
    assert float(off[:3] @ tilted) == pytest.approx(0.0, abs=1e-15)
    err = planned[:3, 3] - measured[:3, 3]
    np.testing.assert_allclose(off[:3] + (err @ tilted) / 2.0 * tilted, err, atol=1e-15)


def test_joint_step_keeps_joints_at_their_limits_still() -> None:
    rng = np.random.default_rng(1)
    j = rng.normal(size=(6, 7))
    twist = np.array([1e-3, -2e-3, 5e-4, 1e-3, 0.0, -2e-3])
    free = np.array([True, True, True, True, False, True, True])
    dq = aim.joint_step(j, twist, damping=0.0, free=free)
    assert dq[4] == 0.0
    np.testing.assert_allclose(j @ dq, twist, atol=1e-12)  # six joints still reach it


def test_joint_step_moves_the_tool_by_the_twist_and_blend_is_smooth() -> None:
    rng = np.random.default_rng(0)
    j = rng.normal(size=(6, 7))
    twist = np.array([1e-3, -2e-3, 5e-4, 1e-3, 0.0, -2e-3])
    dq = aim.joint_step(j, twist, damping=0.0)
    np.testing.assert_allclose(j @ dq, twist, atol=1e-12)
    # damping shrinks the step, never turns it
    damped = aim.joint_step(j, twist)
    assert float(damped @ dq) > 0 and np.linalg.norm(damped) < np.linalg.norm(dq)
    assert aim.blend(0.0, 1.0) == 0.0 and aim.blend(1.0, 1.0) == 1.0
    assert aim.blend(0.5, 1.0) == pytest.approx(0.5) and aim.blend(3.0, 0.0) == 1.0
