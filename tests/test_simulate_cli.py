"""``thirdhand simulate``: bad input in one line, a recorded run, the synthetic chair end to end."""

from __future__ import annotations

import json

import pytest

from tests.cli_helpers import call, settings_file
from thirdhand.task.store import save_task


@pytest.fixture
def chair_task(tmp_path):
    from thirdhand.synth import make_scene
    from thirdhand.synth.task import truth_task

    path = tmp_path / "chair.task.json"
    save_task(truth_task(make_scene("chair", seed=0)), path)
    return path


def test_without_the_extra_says_how_to_install_it(capsys, monkeypatch, chair_task) -> None:
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda n, *a: None if n == "mujoco" else real(n, *a)
    )
    rc, _, err = call(capsys, "simulate", str(chair_task))
    assert rc == 1 and err.count("\n") == 1
    assert "pip install 'thirdhand[sim]'" in err and "mujoco" in err


def test_a_run_recorded_for_another_task_is_one_line(capsys, tmp_path, chair_task) -> None:
    pytest.importorskip("mujoco")
    run = tmp_path / "run.json"
    doc = {
        "schema": "thirdhand.trajectory/1", "robot": "panda",
        "base_pose": {"pos": [0, 0, 0], "quat": [0, 0, 0, 1]},
        "joint_names": [f"panda_joint{i}" for i in range(1, 8)],
        "t": [0.0, 0.1], "q": [[0.0] * 7, [0.0] * 7], "segments": [],
        "steps": [{"index": 0, "constraint": "c1", "parent": "/toolbox/side_front",
                   "child": "/toolbox/side_left", "success": True, "status": "done"}],
    }  # fmt: skip
    run.write_text(json.dumps(doc))
    rc, _, err = call(capsys, "simulate", str(chair_task), "--run", str(run))
    assert rc == 1 and err.count("\n") == 1, err
    assert "recorded for another task" in err and "/toolbox/side_left" in err


def test_a_malformed_run_is_one_line(capsys, tmp_path, chair_task) -> None:
    pytest.importorskip("mujoco")
    run = tmp_path / "run.json"
    run.write_text('{"t": [0, 1]}')
    rc, _, err = call(capsys, "simulate", str(chair_task), "--run", str(run))
    assert rc == 1 and err.count("\n") == 1 and "not a run recorded by" in err, err


def test_video_must_be_mp4(capsys, tmp_path, chair_task) -> None:
    pytest.importorskip("mujoco")
    rc, _, err = call(capsys, "simulate", str(chair_task), "--video", str(tmp_path / "v.avi"))
    assert rc == 1 and err.count("\n") == 1 and "expected a .mp4 file" in err, err


def test_settings_are_listed_with_defaults(capsys) -> None:
    rc, out, _ = call(capsys, "config", "simulate")
    assert rc == 0
    assert 'grasp = "friction"' in out and "gripper_force = 70.0" in out


@pytest.mark.slow
def test_synthetic_chair_end_to_end(capsys, tmp_path, chair_task, shared_data) -> None:
    pytest.importorskip("mujoco")
    pytest.importorskip("coacd")
    out, video = tmp_path / "sim.json", tmp_path / "sim.mp4"
    cfg = settings_file(
        tmp_path, "simulate", meshes=[str(shared_data / "3rdhand" / "meshes")],
        cache=str(tmp_path / "cache"), fps=5, width=320, height=240,
    )  # fmt: skip
    rc, stdout, _ = call(
        capsys, "simulate", str(chair_task), "--json", str(out), "--video", str(video),
        "--config", str(cfg),
    )  # fmt: skip
    doc = json.loads(out.read_text())
    assert doc["schema"] == "thirdhand.simulation/1" and doc["grasp"] == "friction"
    assert len(doc["steps"]) == 5
    statuses = {"done", "slipped", "dropped", "jammed", "failed"}
    for s in doc["steps"]:
        assert s["status"] in statuses
        assert {"position_error_mm", "angle_error_deg", "slip_mm", "peak_force_n"} <= set(s)
    assert doc["sim_time_s"] > 10.0 and doc["wall_time_s"] > 0.0
    # every leg seated (a leg that stops on its pocket's rim is slid in) and the back carried
    assert [s["status"] for s in doc["steps"]] == ["done"] * 5 and rc == 0
    # seated within 1 mm and 1° of the goal (SEAT_TOLERANCE_*), plus a measurement period
    assert max(s["position_error_mm"] for s in doc["steps"]) < 1.5
    assert max(s["angle_error_deg"] for s in doc["steps"]) < 1.5
    assert doc["rest"]["largest_displacement_mm"] < 0.1
    # the re-aim brings a part turned in the hand back without flinging the arm
    assert max(s["tracking_error_deg"] for s in doc["steps"]) < 10.0
    if doc["video"] is not None:
        from thirdhand.simulate.video import count_frames

        assert count_frames(video) == doc["frames"] > 0
    else:
        assert "video refused" in stdout and not video.exists()


def test_no_renderer_refuses_the_video_with_the_reason(monkeypatch, tmp_path) -> None:
    mujoco = pytest.importorskip("mujoco")
    from thirdhand.simulate.video import open_video

    def broken(*args, **kwargs):
        raise RuntimeError("cannot initialize EGL display")

    monkeypatch.setattr(mujoco, "Renderer", broken)
    writer, why = open_video(
        None, tmp_path / "v.mp4", fps=5, width=64, height=64, lookat=[0, 0, 0], distance=1.0
    )
    assert writer is None and not (tmp_path / "v.mp4").exists()
    assert "no offscreen renderer" in why and "cannot initialize EGL display" in why
    assert "libegl1" in why and "\n" not in why
