"""Grasps from the demonstration end to end: ``execute --demo`` holds parts where fingers did."""

from __future__ import annotations

import json

import numpy as np
import pytest

from thirdhand import se3
from thirdhand.execute.goals import invert
from thirdhand.execute.grasps import (
    Grasp,
    _finger_approach,
    demo_grasps,
    rod_turns,
    square_to_box,
    tool_frame,
    within_fingers,
)
from thirdhand.execute.record import TOOL_BODY


def test_rod_turns_keep_the_place_along_the_axis_and_the_angle_to_it() -> None:
    lo, hi = np.array([0.0, -0.04, -0.03]), np.array([0.28, 0.04, 0.05])  # axis: x through (0, .01)
    g = Grasp(tool_frame([0.1, 0.05, 0.01], [-1.0, -1.0, 0.0], [0.0, 0.0, 1.0]), "demo", "demo:rh")
    out = rod_turns([g], lo, hi, n=12)
    assert len(out) == 12 and out[0] is g
    assert [o.label for o in out[1:4]] == ["demo:rh@30", "demo:rh@60", "demo:rh@90"]
    assert all(o.source == "demo" for o in out)
    axis_point = np.array([0.0, 0.0, 0.01])
    for o in out:
        p = o.pose[:3, 3]
        assert p[0] == pytest.approx(0.1)  # same place along the rod
        assert np.linalg.norm(p[1:] - axis_point[1:]) == pytest.approx(0.05)  # same radius
        assert o.pose[0, 2] == pytest.approx(g.pose[0, 2])  # same angle of approach to the axis
        np.testing.assert_allclose(o.pose[:3, :3].T @ o.pose[:3, :3], np.eye(3), atol=1e-12)
    # a quarter turn about x maps the approach (-1, -1, 0)/√2 to (-1, 0, -1)/√2
    np.testing.assert_allclose(
        out[3].pose[:3, 2], np.array([-1.0, 0.0, -1.0]) / np.sqrt(2), atol=1e-12
    )
    # not a rod: returned as given
    assert rod_turns([g], [0, 0, 0], [0.3, 0.3, 0.02]) == [g]


@pytest.mark.slow
def test_execute_with_demo_holds_each_leg_where_the_fingers_did(tmp_path, shared_data) -> None:
    import typer
    from typer.testing import CliRunner

    from thirdhand import io
    from thirdhand.execute.cli import execute_command
    from thirdhand.synth import make_scene
    from thirdhand.synth.task import truth_task
    from thirdhand.taskfile import save_task

    demo = make_scene("bench", seed=1)
    task = truth_task(demo)
    task_path, demo_path = tmp_path / "bench.json", tmp_path / "bench_demo.parquet"
    save_task(task, task_path)
    io.save(demo, demo_path)
    app = typer.Typer()
    app.command()(execute_command)
    out = tmp_path / "run.parquet"
    meshes = str(shared_data / "3rdhand" / "meshes")
    cfg = tmp_path / "settings.toml"
    cfg.write_text(f"[execute]\nmeshes = [{meshes!r}]\n")
    res = CliRunner().invoke(
        app,
        [str(task_path), "--demo", str(demo_path), "--record", str(out), "--config",
         str(cfg), "--seed", "1"],
        env={"COLUMNS": "220"},
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    assert "demo:rh" in res.output and "(demo)" in res.output
    doc = json.loads(out.with_suffix(".json").read_text())
    steps = doc["steps"]
    assert doc["n_collisions"] == 0 and all(s["success"] for s in steps)
    assert all(s["grasp_source"] == "demo" for s in steps), [s["grasp"] for s in steps]
    assert any("@" not in s["grasp"] for s in steps)  # one leg held exactly as demonstrated
    # the replay: when the leg is lifted, the tool holds it at the demonstrated grasp
    replay = io.load(out)
    by_child = {c.child: c for c in task.constraints}
    for s in steps:
        c = by_child[s["child"]]
        obj = next(o for o in task.objects if o.name == c.child)
        box = (np.asarray(obj.bbox_min), np.asarray(obj.bbox_max))
        found = square_to_box(demo_grasps(demo, c.child, c.time, bbox=box))
        hints = {g.label: g for g in rod_turns(found, *box)}
        lift = next(
            g for g in doc["segments"] if g["step"] == s["index"] and g["segment"] == "lift"
        )
        k = int(np.argmin(np.abs(replay.t - lift["t_start"])))
        t_part = se3.matrix_from_pose(replay.pos(c.child)[k], replay.quat(c.child)[k])
        t_tool = se3.matrix_from_pose(replay.pos(TOOL_BODY)[k], replay.quat(TOOL_BODY)[k])
        np.testing.assert_allclose(invert(t_part) @ t_tool, hints[s["grasp"]].pose, atol=1e-3)


BOARD = (np.array([-0.2125, -0.06, 0.008]), np.array([0.2125, 0.06, 0.025]))  # the real side_left


def test_a_pinch_of_a_board_approaches_across_the_fingers_from_the_nearer_edge() -> None:
    """Thumb under, index and middle on top of a 1.7-cm board, 2 cm in from its +y edge:
    the hand reached over that edge (approach -y), whatever the fingers' slant."""
    z0 = 0.0165  # mid-plane
    tips = np.array(
        [
            [0.00, 0.04, z0 - 0.0085],  # thumb, under
            [-0.01, 0.04, z0 + 0.0085],  # index, on top
            [0.01, 0.04, z0 + 0.0085],  # middle, beside it along the edge
        ]
    )
    closing = tips[1:].mean(axis=0) - tips[0]
    a = _finger_approach(tips, [0], [1, 2], closing, BOARD)
    np.testing.assert_allclose(a / np.linalg.norm(a), [0.0, -1.0, 0.0], atol=1e-12)
    # mirrored to the -y edge: the approach flips
    tips[:, 1] *= -1
    a = _finger_approach(tips, [0], [1, 2], closing, BOARD)
    np.testing.assert_allclose(a / np.linalg.norm(a), [0.0, 1.0, 0.0], atol=1e-12)
    # one finger besides the thumb: the nearest face across the closing direction (+y)
    a = _finger_approach(tips[:2], [0], [1], tips[1] - tips[0], BOARD)
    np.testing.assert_allclose(a / np.linalg.norm(a), [0.0, 1.0, 0.0], atol=1e-12)


def test_square_to_box_closes_along_the_faces_normal_and_keeps_the_place() -> None:
    slant = tool_frame([0.05, 0.0, 0.0165], [0.3, -1.0, 0.4], [0.35, 0.3, 1.0])
    g = Grasp(slant, "demo", "demo:rh")
    out = square_to_box([g])
    assert [o.label for o in out] == ["demo:rh", "demo:rh/square"] and out[0] is g
    sq = out[1].pose
    np.testing.assert_allclose(sq[:3, 3], slant[:3, 3])  # the same place on the board
    np.testing.assert_allclose(sq[:3, 1], [0.0, 0.0, 1.0], atol=1e-12)  # across its thickness
    np.testing.assert_allclose(sq[:3, 2], [0.0, -1.0, 0.0], atol=1e-12)  # over its +y edge
    np.testing.assert_allclose(sq[:3, :3].T @ sq[:3, :3], np.eye(3), atol=1e-12)
    assert np.linalg.det(sq[:3, :3]) == pytest.approx(1.0)
    # already square, past 45°, or from the shape: no copy
    square = Grasp(sq, "demo", "x")
    steep = Grasp(tool_frame([0, 0, 0], [0, 0, -1], [1.0, 1.0, 0.0]), "demo", "y")
    shape = Grasp(slant, "shape", "side")
    assert square_to_box([square, steep, shape]) == [square, steep, shape]


def test_within_fingers_slides_a_deep_grasp_back_and_centres_it() -> None:
    from thirdhand.execute.grasps import FINGER_DEPTH_M

    lo, hi = np.array([-0.2, -0.06, 0.0]), np.array([0.2, 0.06, 0.017])
    # a board's middle held from its -y edge (approach +y), 60 mm in: 25 mm deeper than the fingers
    g = Grasp(tool_frame([0.05, 0.0, 0.0125], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]), "demo", "d")
    (fit,) = within_fingers([g], lo, hi)
    # slid back to the fingers' reach and centred on the board's mid-plane (z 8.5 mm)
    np.testing.assert_allclose(fit.pose[:3, 3], [0.05, -0.06 + FINGER_DEPTH_M, 0.0085], atol=1e-12)
    np.testing.assert_allclose(fit.pose[:3, :3], g.pose[:3, :3])
    # held 10 mm in by its edge: slid in to the fingers' reach (the board's middle is farther)
    shallow = Grasp(tool_frame([0.05, -0.05, 0.0085], [0, 1, 0], [0, 0, 1]), "demo", "s")
    (deeper,) = within_fingers([shallow], lo, hi)
    np.testing.assert_allclose(deeper.pose[:3, 3], [0.05, -0.06 + FINGER_DEPTH_M, 0.0085],
                               atol=1e-12)  # fmt: skip
    np.testing.assert_allclose(deeper.pose[:3, :3], shallow.pose[:3, :3])
    # a leg (a rod, 80 mm thick) pinched on its shoulder from above, off its axis: the
    # tool point goes onto the axis where it was along it, backed off 40 - 35 mm
    rod_lo, rod_hi = np.array([0.0, -0.04, -0.04]), np.array([0.28, 0.04, 0.04])
    top = Grasp(tool_frame([0.1, 0.012, 0.03], [0, 0, -1], [0, 1, 0]), "demo", "t")
    (held,) = within_fingers([top], rod_lo, rod_hi)
    np.testing.assert_allclose(held.pose[:3, 3], [0.1, 0.0, 0.04 - FINGER_DEPTH_M], atol=1e-12)
    shape = Grasp(g.pose, "shape", "face")
    assert within_fingers([shape], lo, hi) == [shape]


def test_a_grasp_closing_along_a_rod_is_turned_to_close_across_it() -> None:
    lo, hi = np.array([0.0, -0.04, -0.04]), np.array([0.28, 0.04, 0.04])  # a chair leg
    approach = np.array([-0.07, 0.92, -0.38]) / np.linalg.norm([-0.07, 0.92, -0.38])
    g = Grasp(tool_frame([0.14, 0.0, -0.015], approach, [1.0, 0.0, 0.0]), "demo", "demo:lh")
    (out,) = within_fingers([g], lo, hi)
    r = out.pose[:3, :3]
    np.testing.assert_allclose(r.T @ r, np.eye(3), atol=1e-12)
    assert np.linalg.det(r) == pytest.approx(1.0)
    np.testing.assert_allclose(r[:, 2], g.pose[:3, 2], atol=1e-12)  # same approach
    assert abs(r[0, 1]) < 0.1  # closing across the leg, no longer along it
    assert out.pose[0, 3] == pytest.approx(0.14, abs=1e-3)  # same place along the leg
    # a grasp that already closes across the leg keeps its orientation
    across = Grasp(tool_frame([0.14, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]), "demo", "rh")
    (kept,) = within_fingers([across], lo, hi)
    np.testing.assert_allclose(kept.pose[:3, :3], across.pose[:3, :3], atol=1e-12)
