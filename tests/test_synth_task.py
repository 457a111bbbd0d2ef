"""Ground-truth task files of synthetic scenes, and part-mesh geometry."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from thirdhand.errors import TaskFileError
from thirdhand.se3 import matrix_from_quat
from thirdhand.synth import make_scene
from thirdhand.synth.geometry import MESH_BOUNDS_MM, stl_bounds
from thirdhand.synth.task import truth_task
from thirdhand.task.meshes import (
    MESH_PATH_ENV,
    align_bounds,
    box_triangles,
    object_triangles,
    resolve_mesh,
)
from thirdhand.taskfile import TaskFile, dump_task, parse_task


@pytest.fixture(scope="module")
def chair_truth() -> TaskFile:
    return truth_task(make_scene("chair", seed=3))


def test_chair_truth_has_the_five_constraints_in_plan_order(chair_truth: TaskFile) -> None:
    types = sorted(c.type for c in chair_truth.constraints)
    assert types == ["fixed", "revolute", "revolute", "revolute", "revolute"]
    assert [s.constraint for s in chair_truth.plan] == [c.id for c in chair_truth.constraints]
    assert all(s.parent == "seating" for s in chair_truth.plan)
    times = [s.time for s in chair_truth.plan]
    assert times == sorted(times)
    for s in chair_truth.plan:
        assert set(s.keyframe) >= {"seating", "leg1", "leg2", "leg3", "leg4", "back"}


def test_truth_constraint_poses_match_the_labels(chair_truth: TaskFile) -> None:
    demo = make_scene("chair", seed=3)
    for c in chair_truth.constraints:
        ev = next(e for e in demo.labels.constraints if (e.parent, e.child) == (c.parent, c.child))
        assert np.allclose(c.pos, ev.pos) and np.allclose(c.quat, ev.quat)
        assert np.allclose(c.free_dof_array(), ev.free_dofs.array())


def test_truth_task_round_trips(chair_truth: TaskFile) -> None:
    again = parse_task(dump_task(chair_truth))
    assert again.to_json_dict() == chair_truth.to_json_dict()


def test_bench_truth_has_four_revolute_legs() -> None:
    task = truth_task(make_scene("bench", seed=1))
    assert [c.type for c in task.constraints] == ["revolute"] * 4
    legs = {o.name: o for o in task.objects}["leg1"]
    assert legs.mesh == "bench_leg.stl" and legs.scale == 1e-3


@pytest.mark.parametrize("perm", list(itertools.permutations(range(3))))
def test_align_bounds_maps_a_box_onto_a_permuted_box(perm: tuple[int, int, int]) -> None:
    mesh_lo, mesh_hi = np.array([-0.1, 0.0, 0.3]), np.array([0.2, 0.05, 0.4])  # 0.3, 0.05, 0.1
    ext = (mesh_hi - mesh_lo)[list(perm)]
    body_lo = np.array([0.01, -0.02, 0.03])
    body_hi = body_lo + ext
    pose = align_bounds(mesh_lo, mesh_hi, body_lo, body_hi)
    rot = matrix_from_quat(np.asarray(pose.quat))
    assert np.isclose(np.linalg.det(rot), 1.0)
    corners = box_triangles(mesh_lo, mesh_hi).reshape(-1, 3) @ rot.T + np.asarray(pose.pos)
    assert np.allclose(corners.min(0), body_lo) and np.allclose(corners.max(0), body_hi)


def test_box_triangles_close_a_box_with_outward_normals() -> None:
    tri = box_triangles((0, 0, 0), (1, 2, 3))
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    outward = np.einsum("ij,ij->i", normals, tri.mean(1) - np.array([0.5, 1.0, 1.5]))
    assert tri.shape == (12, 3, 3) and np.all(outward > 0)
    # divergence theorem: the volume of the closed surface
    volume = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6
    assert np.isclose(volume, 6.0)


def test_mesh_bounds_table_matches_the_files(shared_data) -> None:
    folder = shared_data / "3rdhand" / "meshes"
    for name, (lo, hi) in MESH_BOUNDS_MM.items():
        flo, fhi = stl_bounds(folder / name)
        assert np.allclose(flo, lo, atol=0.06) and np.allclose(fhi, hi, atol=0.06), name


def test_real_meshes_fill_the_body_bounding_boxes(shared_data, monkeypatch, chair_truth) -> None:
    monkeypatch.setenv(MESH_PATH_ENV, str(shared_data / "3rdhand" / "meshes"))
    for obj in chair_truth.objects:
        if obj.mesh is None:
            continue
        assert resolve_mesh(obj) is not None
        tri = object_triangles(obj)
        assert tri is not None and tri.shape[0] > 12
        pts = tri.reshape(-1, 3)
        assert np.allclose(pts.min(0), obj.bbox_min, atol=2e-4), obj.name
        assert np.allclose(pts.max(0), obj.bbox_max, atol=2e-4), obj.name


def test_missing_mesh_falls_back_to_the_bounding_box(tmp_path, monkeypatch, chair_truth) -> None:
    monkeypatch.delenv(MESH_PATH_ENV, raising=False)
    leg = {o.name: o for o in chair_truth.objects}["leg1"]
    assert resolve_mesh(leg, tmp_path / "task.json") is None
    tri = object_triangles(leg, tmp_path / "task.json")
    assert tri is not None and tri.shape == (12, 3, 3)
    # a file next to the task file wins
    (tmp_path / "chair_leg.stl").write_bytes(b"solid x\nendsolid x\n")
    assert resolve_mesh(leg, tmp_path / "task.json") == tmp_path / "chair_leg.stl"


def test_a_bounding_box_with_min_above_max_is_refused(chair_truth: TaskFile) -> None:
    data = chair_truth.to_json_dict()
    data["objects"][0]["bbox_min"] = [0.2, 0.0, 0.0]
    with pytest.raises(TaskFileError, match=r"bbox_min\.x"):
        parse_task(__import__("json").dumps(data))
