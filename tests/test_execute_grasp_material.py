"""Physics planning keeps only grasps whose finger pads close on the part's material."""

from __future__ import annotations

import numpy as np

from thirdhand.execute.grasps import (
    PAD_HALF_M,
    Grasp,
    inside_mesh,
    is_wide_plate,
    mesh_centroid,
    nearest_com,
    on_material,
    pinch_grasps,
    shape_grasps,
    tool_frame,
)
from thirdhand.execute.layout import pinched_through_face
from thirdhand.task.meshes import box_triangles

#: Two 30 mm thick slats, 100 mm wide, with a 100 mm gap between them (body frame, m).
SLATS = np.concatenate(
    [
        box_triangles([-0.15, -0.2, -0.015], [-0.05, 0.2, 0.015]),
        box_triangles([0.05, -0.2, -0.015], [0.15, 0.2, 0.015]),
    ]
)


def test_inside_mesh_matches_the_boxes_point_by_point() -> None:
    rng = np.random.default_rng(3)
    pts = rng.uniform([-0.2, -0.25, -0.03], [0.2, 0.25, 0.03], size=(400, 3))
    got = inside_mesh(SLATS, pts)
    in_y = (np.abs(pts[:, 1]) < 0.2) & (np.abs(pts[:, 2]) < 0.015)
    want = in_y & (np.abs(np.abs(pts[:, 0]) - 0.1) < 0.05)
    assert got.dtype == bool and got.shape == (400,)
    np.testing.assert_array_equal(got, want)
    assert 0 < want.sum() < 400  # both cases occur


def test_inside_mesh_of_a_box_on_its_faces_axes_and_far_away() -> None:
    box = box_triangles([-1.0, -1.0, -1.0], [1.0, 1.0, 1.0])
    pts = np.array([[0, 0, 0], [0.999, 0, 0], [1.001, 0, 0], [0, 0, 5], [0.5, -0.5, 0.5]])
    np.testing.assert_array_equal(inside_mesh(box, pts), [True, True, False, False, True])


def test_on_material_drops_the_grasp_that_closes_in_the_gap() -> None:
    # onto the top edge (approach -y, tool point 20 mm in), closing across the thickness
    grasps = [
        Grasp(tool_frame([x, 0.2 - 0.02, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]), "shape", f"{x}")
        for x in (-0.1, 0.0, 0.1, -0.055)
    ]
    kept = on_material(grasps, SLATS)
    # the gap, and a grasp whose pad hangs half over the slat's edge (2 of 4 corners out)
    assert [g.label for g in kept] == ["-0.1", "0.1"]
    assert PAD_HALF_M[0] > 0.005  # -0.055 is within the pad's half width of the edge


def test_on_material_keeps_every_shape_grasp_of_a_solid_box() -> None:
    lo, hi = np.array([-0.02, -0.02, -0.15]), np.array([0.02, 0.02, 0.15])
    grasps = shape_grasps(lo, hi)
    inside = [g for g in grasps if np.all(np.abs(g.pose[:3, 3]) < hi)]
    assert len(inside) > 0
    assert on_material(inside, box_triangles(lo, hi)) == inside
    assert on_material([], box_triangles(lo, hi)) == []


def _slatted_back() -> np.ndarray:
    """A 380 mm rail (y from -0.42 to -0.22) over three 70 mm slats 20 mm apart (to y = 0)."""
    rail = box_triangles([-0.19, -0.42, -0.015], [0.19, -0.22, 0.015])
    slats = [
        box_triangles([x - 0.035, -0.2199, -0.015], [x + 0.035, 0.0, 0.015])
        for x in (-0.09, 0.0, 0.09)
    ]
    return np.concatenate([rail, *slats])


def test_pinch_grasps_close_on_a_slat_with_the_fingers_in_the_gaps() -> None:
    tri = _slatted_back()
    grasps = pinch_grasps(tri)
    face = [g for g in grasps if abs(g.pose[2, 2]) > 0.99]  # approach through the face
    assert face and all(g.source == "shape" and g.label == "pinch" for g in grasps)
    for g in face:
        p, closing = g.pose[:3, 3], g.pose[:3, 1]
        assert abs(closing[0]) > 0.99  # across a slat's 70 mm, not the rail's 380
        assert min(abs(p[0] - x) for x in (-0.09, 0.0, 0.09)) < 1e-9  # centred on a slat
        assert p[1] > -0.2199 + PAD_HALF_M[0]  # the finger stays off the rail
        assert abs(p[2]) < 1e-9  # 15 mm in through the 30 mm board: its mid-plane
    assert on_material(grasps, tri) == grasps
    # nearest the centre of mass: the middle slat, next to the rail
    best = nearest_com(grasps, mesh_centroid(tri), 1)[0]
    assert abs(best.pose[0, 3]) < 1e-9 and best.pose[1, 3] < -0.19


def test_a_solid_plate_is_pinched_by_its_edges_only() -> None:
    tri = box_triangles([-0.15, -0.15, -0.01], [0.15, 0.15, 0.01])
    grasps = pinch_grasps(tri)
    assert grasps
    assert all(abs(g.pose[2, 2]) < 1e-9 for g in grasps)  # never through the face
    assert all(abs(g.pose[2, 1]) > 0.99 for g in grasps)  # across its 20 mm thickness
    np.testing.assert_allclose(mesh_centroid(tri), 0.0, atol=1e-12)
    assert is_wide_plate([-0.15, -0.15, -0.01], [0.15, 0.15, 0.01])
    assert not is_wide_plate([-0.02, -0.02, -0.15], [0.02, 0.02, 0.15])  # a leg


def test_only_a_plate_with_a_slat_is_pinched_through_its_face() -> None:
    assert pinched_through_face(_slatted_back())
    assert not pinched_through_face(box_triangles([-0.15, -0.15, -0.01], [0.15, 0.15, 0.01]))
    assert not pinched_through_face(box_triangles([0.0, -0.02, -0.02], [0.28, 0.02, 0.02]))
    assert not pinched_through_face(None)


def test_pinch_grasps_of_a_mesh_seen_before_are_the_same_and_a_fresh_list() -> None:
    tri = _slatted_back()
    first = pinch_grasps(tri)
    first.clear()
    again, other = pinch_grasps(tri.copy()), pinch_grasps(tri, step=0.02)
    assert again and len(other) < len(again)
    for g, h in zip(again, pinch_grasps(tri), strict=True):
        np.testing.assert_array_equal(g.pose, h.pose)
