"""``thirdhand generate``: the demo chair's episodes as a LeRobot dataset, read back and checked.

The physics of the slow tests is a typed settings record, not the defaults: the
weld grasp, convex hulls and tolerances wide enough that every step of the
chair counts as done, so the tests check the dataset (what is recorded, how it
is written, serial against ``--jobs 2``) whatever the friction grasp achieves.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from tests.cli_helpers import call
from thirdhand.task.store import save_task

pytest.importorskip("mujoco")

#: The physics of the slow tests: every planned step of the chair counts as done.
LENIENT = {
    "grasp": "weld", "collision": "hull", "position_tolerance": 1000.0,
    "angle_tolerance": 180.0, "slip_tolerance": 1000.0, "drop_distance": 10000.0,
    "rest_time": 0.5,
}  # fmt: skip
#: Small frames, few of them: the tests check the dataset, not the pictures.
SMALL = {"fps": 5, "width": 64, "height": 48}


def _config(folder: Path, name: str, **tables: dict[str, object]) -> Path:
    path = folder / f"{name}.toml"
    lines = []
    for table, values in tables.items():
        lines += [f"[{table}]"] + [f"{k} = {json.dumps(v)}" for k, v in values.items()]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture(scope="module")
def chair(tmp_path_factory) -> Path:
    from thirdhand.synth import make_scene
    from thirdhand.synth.task import truth_task

    # the legs only: the back, pinched by its top edge, turns out of the fingers in most
    # carries, and a step not planned would leave nothing to check
    task = truth_task(make_scene("chair", seed=0))
    keep = [i for i, s in enumerate(task.plan) if s.child != "back"]
    new = {old: k for k, old in enumerate(keep)}
    plan = [
        task.plan[i].model_copy(update={"after": None if task.plan[i].after is None else
                                        [new[a] for a in task.plan[i].after if a in new]})
        for i in keep
    ]  # fmt: skip
    path = tmp_path_factory.mktemp("task") / "chair.task.json"
    save_task(task.model_copy(update={"plan": plan}), path)
    return path


@pytest.fixture(scope="module")
def physics(tmp_path_factory) -> dict[str, object]:
    """The lenient ``[simulate]`` table, with the meshes when the shared data is there."""
    from conftest import DATA

    meshes = DATA / "3rdhand" / "meshes"
    table = {**LENIENT, "cache": str(tmp_path_factory.mktemp("cache"))}
    if meshes.is_dir():
        table["meshes"] = [str(meshes)]
    return table


# --- bad input: one line each ----------------------------------------------------------------


@pytest.mark.parametrize("n", ["0", "-3"])
def test_no_or_negative_episodes_is_one_line(capsys, tmp_path, chair, n) -> None:
    rc, _, err = call(capsys, "generate", str(chair), "--episodes", n, "-o", str(tmp_path / "d"))
    assert rc == 1 and err.count("\n") == 1 and "--episodes" in err, err
    assert not (tmp_path / "d").exists()


def test_an_existing_folder_is_refused_without_force(capsys, tmp_path, chair) -> None:
    (tmp_path / "d").mkdir()
    rc, _, err = call(capsys, "generate", str(chair), "--episodes", "1", "-o", str(tmp_path / "d"))
    assert rc == 1 and err.count("\n") == 1 and "--force" in err, err


def test_a_frame_rate_of_no_whole_physics_steps_is_one_line(capsys, tmp_path, chair) -> None:
    cfg = _config(tmp_path, "c", generate={"fps": 15})
    rc, _, err = call(
        capsys, "generate", str(chair), "-n", "1", "-o", str(tmp_path / "d"), "--config", str(cfg)
    )
    assert rc == 1 and err.count("\n") == 1 and "[generate] fps 15" in err, err


@pytest.mark.parametrize(
    ("option", "value", "words"),
    [("--jobs", "0", "--jobs"), ("--scheduler", "ftp://x", "expected tcp://HOST:PORT"),
     ("--seed", "-1", "--seed")],
)  # fmt: skip
def test_bad_batch_options_are_one_line(capsys, tmp_path, chair, option, value, words) -> None:
    rc, _, err = call(
        capsys, "generate", str(chair), "-n", "1", "-o", str(tmp_path / "d"), option, value
    )
    assert rc == 1 and err.count("\n") == 1 and words in err, err


@pytest.mark.parametrize("robot", ["baxter", "r2d2"])
def test_a_robot_not_simulated_is_one_line(capsys, tmp_path, chair, robot) -> None:
    rc, _, err = call(
        capsys, "generate", str(chair), "-n", "1", "-o", str(tmp_path / "d"), "--robot", robot
    )
    assert rc == 1 and err.count("\n") == 1 and robot in err, err


# --- the pure parts ---------------------------------------------------------------------------


def test_the_gripper_command_is_the_open_width_or_zero() -> None:
    from thirdhand.generate.record import gripper_command

    assert gripper_command(np.array([70.0, 70.0])) == pytest.approx(0.08)
    assert gripper_command(np.array([-70.0, -70.0])) == 0.0


def test_quaternions_are_made_sign_continuous() -> None:
    from thirdhand.generate.record import continuous_quaternions

    prev = np.array([[0.0, 0.0, 0.0, 1.0], [0.0, 0.6, 0.0, 0.8]])
    now = np.array([[0.0, 0.0, 0.1, -0.995], [0.0, 0.6, 0.0, 0.8]])
    out = continuous_quaternions(now, prev)
    np.testing.assert_array_equal(out, [[0.0, 0.0, -0.1, 0.995], [0.0, 0.6, 0.0, 0.8]])
    np.testing.assert_array_equal(continuous_quaternions(now, None), now)


def test_the_task_text_lists_the_plan(chair) -> None:
    from thirdhand.generate.episodes import task_text
    from thirdhand.task.store import load_task

    text = task_text(load_task(chair), "chair")
    assert text.startswith("assemble the chair: leg2 into the seating, ")
    assert text.count(" into the ") == 4  # the legs: the fixture leaves out the back


# --- the chair, simulated ---------------------------------------------------------------------


@pytest.fixture(scope="module")
def serial(tmp_path_factory, chair, physics) -> tuple[Path, Path]:
    """Two episodes (seeds 3 and 4) written by the command, and its config file."""
    folder = tmp_path_factory.mktemp("serial")
    cfg = _config(folder, "c", simulate=physics, generate=SMALL)
    out = folder / "chair"
    from thirdhand.cli import main

    assert main(["generate", str(chair), "-n", "2", "--seed", "3", "-o", str(out),
                 "--config", str(cfg)]) == 0  # fmt: skip
    return out, cfg


@pytest.mark.slow
def test_the_dataset_reads_back_whole(serial) -> None:
    from thirdhand.lerobot import read_dataset

    root, _ = serial
    ds = read_dataset(root)
    info = json.loads((root / "meta" / "info.json").read_text())
    assert info["fps"] == SMALL["fps"] and info["robot_type"] == "panda"
    assert info["total_episodes"] == len(ds.episodes) == 2
    rows = sum(len(e.timestamps) for e in ds.episodes)
    assert info["total_frames"] == rows
    import pyarrow.parquet as pq

    meta = pq.read_table(root / "meta" / "episodes").to_pydict()
    assert meta["episode_index"] == [0, 1] and sum(meta["length"]) == rows
    data = pq.read_table(root / "data").to_pydict()
    assert len(data["index"]) == rows and data["index"] == list(range(rows))
    feats = info["features"]
    assert feats["observation.state"]["names"][-1] == "gripper_width"
    assert len(feats["observation.state"]["names"]) == len(feats["action"]["names"]) == 8
    assert feats["observation.environment_state"]["names"][:7] == [
        f"seating.{c}" for c in ("x", "y", "z", "qx", "qy", "qz", "qw")
    ]
    assert ds.tasks == [ds.episodes[0].tasks[0]] and ds.tasks[0].startswith("assemble the chair:")
    for e in ds.episodes:
        n = len(e.timestamps)
        for cam in ("observation.images.front", "observation.images.wrist"):
            assert e.videos[cam].shape == (n, SMALL["height"], SMALL["width"], 3)
            assert e.videos[cam].std() > 1.0  # a picture, not a blank frame
        quat = e.features["observation.environment_state"].reshape(n, -1, 7)[..., 3:]
        np.testing.assert_allclose(np.linalg.norm(quat, axis=-1), 1.0, atol=1e-5)
        assert set(e.features["action"][:, -1].tolist()) <= {0.0, np.float32(0.08).item()}


@pytest.mark.slow
def test_every_frame_is_what_the_simulation_recorded(serial, chair) -> None:
    from thirdhand.config import load_settings
    from thirdhand.generate.episodes import EpisodeJob, run_episode
    from thirdhand.generate.settings import GenerateSettings
    from thirdhand.lerobot import read_dataset
    from thirdhand.simulate.settings import SimulateSettings
    from thirdhand.task.store import load_task

    root, cfg = serial
    sim = load_settings(cfg, "simulate", SimulateSettings)
    job = EpisodeJob(
        task=load_task(chair), task_path=str(chair), name="chair", seed=4, robot="panda",
        search=tuple(sim.meshes), simulate=sim,
        settings=load_settings(cfg, "generate", GenerateSettings),
    )  # fmt: skip
    direct = run_episode(job)
    assert direct.kept and direct.recording is not None
    rec = direct.recording
    back = read_dataset(root, decode_videos=False).episodes[1]
    np.testing.assert_array_equal(back.features["observation.state"], rec.state.astype(np.float32))
    np.testing.assert_array_equal(back.features["action"], rec.action.astype(np.float32))
    np.testing.assert_array_equal(
        back.features["observation.environment_state"], rec.environment.astype(np.float32)
    )
    assert back.annotations["annotation.step"] == list(rec.labels)
    # frame i is at i / fps in the dataset and (i + 1) / fps in the simulation
    np.testing.assert_allclose(rec.time, (np.arange(rec.n_frames) + 1) / SMALL["fps"], atol=1e-9)
    # opens (80 mm) and closes on a leg, held across its thickness (under 78 mm)
    assert rec.state[:, -1].max() > 0.08 and rec.state[:, -1].min() < 0.078


@pytest.mark.slow
def test_two_jobs_write_the_same_dataset(capsys, tmp_path, serial, chair) -> None:
    root, cfg = serial
    out = tmp_path / "chair"
    rc, stdout, err = call(capsys, "generate", str(chair), "-n", "2", "--seed", "3", "-o",
                           str(out), "--config", str(cfg), "--jobs", "2")  # fmt: skip
    assert rc == 0, err
    assert "2 of 2 episodes kept (seeds 3, 4)" in stdout
    files = sorted(p.relative_to(root) for p in root.rglob("*") if p.is_file())
    assert files == sorted(p.relative_to(out) for p in out.rglob("*") if p.is_file())
    assert sum(f.suffix == ".mp4" for f in files) == 2
    for f in files:
        assert (root / f).read_bytes() == (out / f).read_bytes(), f


@pytest.mark.slow
def test_a_task_no_episode_completes_is_one_line_with_the_reasons(
    capsys, tmp_path, chair, physics
) -> None:
    strict = {**physics, "position_tolerance": 1e-6, "angle_tolerance": 1e-6}
    cfg = _config(tmp_path, "c", simulate=strict, generate=SMALL)
    rc, _, err = call(capsys, "generate", str(chair), "-n", "1", "-o", str(tmp_path / "d"),
                      "--config", str(cfg))  # fmt: skip
    assert rc == 1 and err.count("\n") == 1, err
    assert "none of 1 episodes completed every step" in err and "×1" in err
    assert "nothing was written" in err and not (tmp_path / "d").exists()


@pytest.mark.slow
def test_an_interruption_keeps_the_finished_episodes(monkeypatch, tmp_path, serial, chair) -> None:
    """Ctrl-C after episode 0 is written: a dataset of episode 0 alone, then the interrupt."""
    import thirdhand.generate.dataset as dataset
    import thirdhand.generate.episodes as episodes
    from thirdhand.lerobot import read_dataset

    root, _ = serial
    back = read_dataset(root).episodes[0]
    from thirdhand.generate.record import Recording

    names = json.loads((root / "meta" / "info.json").read_text())["features"]
    rec = Recording(
        state=back.features["observation.state"].astype(np.float64),
        action=back.features["action"].astype(np.float64),
        environment=back.features["observation.environment_state"].astype(np.float64),
        joints=tuple(names["observation.state"]["names"][:7]),
        parts=("seating", "leg1", "leg2", "leg3", "leg4", "back"),
        front=back.videos["observation.images.front"],
        wrist=back.videos["observation.images.wrist"],
        labels=tuple(back.annotations["annotation.step"]),
        time=back.timestamps.astype(np.float64),
    )

    def fake(job):
        if job.seed == 1:
            raise KeyboardInterrupt
        return episodes.EpisodeOutcome(job.seed, rec, (), {})

    monkeypatch.setattr(dataset, "run_episode", fake)
    from thirdhand.generate.settings import GenerateSettings
    from thirdhand.task.store import load_task

    job = episodes.EpisodeJob(task=load_task(chair), task_path=None, name="chair", seed=0,
                              settings=GenerateSettings(**SMALL))  # fmt: skip
    with pytest.raises(KeyboardInterrupt):
        dataset.generate_dataset([job, replace(job, seed=1)], tmp_path / "d")
    ds = read_dataset(tmp_path / "d")
    assert len(ds.episodes) == 1
    np.testing.assert_array_equal(
        ds.episodes[0].features["observation.state"], back.features["observation.state"]
    )
