"""Part geometry for physics: mass from volume, a decomposition that keeps a hole, its cache."""

from __future__ import annotations

import numpy as np
import pytest

from tests.sim_scenes import HOLE, PLATE, PLATE_H, box_mesh, plate_with_hole
from thirdhand.simulate.measure import box_corners, pose_error, slip_mm, step_status
from thirdhand.simulate.parts import SimulateError, convex_hull, convex_pieces, mass_properties
from thirdhand.task.constraint import Constraint


def test_mass_and_inertia_of_a_box_from_its_volume() -> None:
    a, b, c = 0.04, 0.06, 0.1
    mp = mass_properties(box_mesh([0, 0, 0], [a, b, c]), 500.0)
    m = 500.0 * a * b * c
    assert mp.mass == pytest.approx(m, rel=1e-9)
    np.testing.assert_allclose(mp.com, [a / 2, b / 2, c / 2], atol=1e-12)
    want = m / 12.0 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
    np.testing.assert_allclose(mp.inertia, want, rtol=1e-9, atol=1e-15)


def test_plate_mass_excludes_its_hole() -> None:
    mp = mass_properties(plate_with_hole(), 1000.0)
    assert mp.volume == pytest.approx((PLATE**2 - HOLE**2) * PLATE_H, rel=1e-9)


def _inside_any(pieces, point) -> bool:
    from scipy.spatial import Delaunay

    return any(Delaunay(p.vertices).find_simplex(point) >= 0 for p in pieces)


def test_decomposition_keeps_the_hole_and_is_cached(tmp_path) -> None:
    plate = plate_with_hole()
    pieces, cached = convex_pieces(plate, name="plate", cache=tmp_path)
    assert not cached and len(pieces) >= 4
    centre = np.array([0.0, 0.0, PLATE_H / 2])
    assert not _inside_any(pieces, centre)  # the hole stays open
    assert _inside_any(convex_hull(plate), centre)  # the hull fills it
    ring = np.array([(PLATE + HOLE) / 4, 0.0, PLATE_H / 2])
    assert _inside_any(pieces, ring)
    again, cached = convex_pieces(plate, name="plate", cache=tmp_path)
    assert cached and len(again) == len(pieces)
    for p, q in zip(pieces, again, strict=True):
        np.testing.assert_array_equal(p.vertices, q.vertices)


def test_failed_decomposition_is_one_line(tmp_path) -> None:
    flat = np.zeros((2, 3, 3))
    flat[0] = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
    flat[1] = [[1, 0, 0], [1, 1, 0], [0, 1, 0]]
    with pytest.raises(SimulateError, match="part 'flat': convex decomposition failed") as e:
        convex_pieces(flat, name="part 'flat'", cache=tmp_path)
    assert "\n" not in str(e.value)


def test_pose_error_ignores_free_dofs() -> None:
    c = Constraint(
        id="c", parent="p", child="k", type="revolute", pos=(0.1, 0.0, 0.0),
        free_dofs={"rz": (-np.pi, np.pi)},
    )  # fmt: skip
    child = np.eye(4)
    child[:3, 3] = [0.1, 0.002, 0.0]
    a = np.deg2rad(40.0)
    child[:3, :3] = [[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]]
    err = pose_error(np.eye(4), child, c)
    assert err.position_mm == pytest.approx(2.0, abs=1e-9)
    assert err.angle_deg == pytest.approx(0.0, abs=1e-9)


def test_slip_of_a_turned_part_is_measured_at_its_corners() -> None:
    corners = box_corners(np.array([-0.1, -0.01, -0.01]), np.array([0.1, 0.01, 0.01]))
    t0 = np.eye(4)
    t1 = np.eye(4)
    a = np.deg2rad(1.0)
    t1[:3, :3] = [[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]]
    # the far corners move 0.1 m * 1 degree (chord) and a bit from the 10 mm half width
    assert slip_mm(t1, t0, corners) == pytest.approx(np.hypot(0.1, 0.01) * a * 1e3, rel=1e-3)


@pytest.mark.parametrize(
    ("kw", "status"),
    [
        ({}, "done"),
        ({"planned": False}, "failed"),
        ({"held": False}, "dropped"),
        ({"slip": 40.0}, "dropped"),
        ({"slip": 8.0, "error": (9.0, 0.0)}, "slipped"),
        ({"slip": 8.0}, "done"),
        ({"error": (9.0, 0.0), "blocked": True}, "jammed"),
        ({"error": (0.0, 4.0)}, "failed"),
        ({"error": None}, "failed"),
    ],
)
def test_step_status(kw, status) -> None:
    from thirdhand.simulate.measure import PoseError

    args = {"planned": True, "held": True, "slip": 1.0, "error": (1.0, 1.0), "blocked": False}
    args.update(kw)
    err = args.pop("error")
    got = step_status(
        **args, error=None if err is None else PoseError(*err), position_tolerance=5.0,
        angle_tolerance=3.0, slip_tolerance=5.0, drop_distance=30.0,
    )  # fmt: skip
    assert got == status
