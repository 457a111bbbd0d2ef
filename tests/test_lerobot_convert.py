"""``thirdhand convert REC DIR --to lerobot``: a human recording as a LeRobot dataset."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.cli_helpers import call
from thirdhand import io
from thirdhand.lerobot.human import INTERACTIONS, POSE_COLUMNS, STATE, TRACKED
from thirdhand.lerobot.reader import read_dataset
from thirdhand.synth import make_scene


@pytest.fixture(scope="module")
def chair(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The noise-free synthetic chair (seed 5), its first 6 s, as a native recording."""
    demo = make_scene("chair", seed=5, sensor=None).slice(0.0, 6.0)
    path = tmp_path_factory.mktemp("rec") / "chair.parquet"
    io.save(demo, path)
    return path


def test_synthetic_recording_round_trip(
    chair: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rc, out, err = call(
        capsys, "convert", str(chair), str(tmp_path / "ds"), "--to", "lerobot", "--fps", "20"
    )
    assert rc == 0, err
    assert "LeRobot dataset" in out
    demo = io.load(chair)
    res = demo.with_continuous_quaternions().resample(20.0)
    back = read_dataset(tmp_path / "ds")
    assert back.info["fps"] == 20 and back.info["robot_type"] is None
    assert back.info["total_frames"] == res.n_frames == len(back.episodes[0].timestamps)
    (ep,) = back.episodes
    names = back.info["features"][STATE]["names"]
    assert names[:7] == [f"{demo.body_names[0]}.{c}" for c in POSE_COLUMNS]
    want = np.concatenate(
        [np.concatenate([res.pos(b), res.quat(b)], axis=1) for b in res.body_names], axis=1
    )
    # Every pose of every frame is the recording's at frame / fps, to float32 precision.
    np.testing.assert_allclose(ep.features[STATE], want, rtol=0, atol=2e-6)
    np.testing.assert_array_equal(ep.features[TRACKED], 1.0)  # noise-free: always tracked
    np.testing.assert_allclose(ep.timestamps, np.arange(res.n_frames) / 20, atol=1e-6)
    labels = ep.annotations[INTERACTIONS]
    assert len(labels) == res.n_frames
    for iv in res.labels.interactions:
        inside = np.flatnonzero((res.t >= iv.start) & (res.t <= iv.end))
        assert all(f"{iv.a}+{iv.b}" in labels[k].split("; ") for k in inside)
    outside = [
        k
        for k, t in enumerate(res.t)
        if not any(iv.start <= t <= iv.end for iv in res.labels.interactions)
    ]
    assert outside and all(labels[k] == "" for k in outside)
    assert back.tasks == ["human demonstration chair.parquet"]


def test_existing_folder_refused_without_force(
    chair: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    target = tmp_path / "ds"
    assert (
        call(capsys, "convert", str(chair), str(target), "--to", "lerobot", "--fps", "10")[0] == 0
    )
    rc, _out, err = call(capsys, "convert", str(chair), str(target), "--to", "lerobot")
    assert rc != 0 and "exists; pass --force" in err and len(err.strip().splitlines()) == 1
    rc, _out, err = call(
        capsys, "convert", str(chair), str(target), "--to", "lerobot", "--fps", "5", "--force"
    )
    assert rc == 0, err
    assert read_dataset(target).info["fps"] == 5
    assert read_dataset(tmp_path / "ds.bak").info["fps"] == 10
    rc, _out, err = call(
        capsys, "convert", str(chair), str(tmp_path / "x"), "--to", "lerobot", "--fps", "0"
    )
    assert rc != 0 and "positive whole number" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x").exists()


def test_real_recording(
    shared_data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The first second of a real Polhemus recording (toolbox_coop_4_excerpt, lost samples)."""
    excerpt = shared_data / "3rdhand" / "toolbox_coop_4_excerpt"
    rc, _out, err = call(capsys, "convert", str(excerpt), str(tmp_path / "ds"), "--to", "lerobot")
    assert rc == 0, err
    demo = io.load(excerpt)
    fps = round(demo.rate)  # about 100 Hz (Polhemus G4)
    res = demo.with_continuous_quaternions().resample(float(fps))
    back = read_dataset(tmp_path / "ds")
    (ep,) = back.episodes
    assert back.info["fps"] == fps and back.info["total_frames"] == res.n_frames
    kept = back.info["features"][TRACKED]["names"]
    assert kept == [b for b in res.body_names if res.valid(b).any()]
    for j, b in enumerate(kept):
        valid = res.valid(b)
        np.testing.assert_array_equal(ep.features[TRACKED][:, j], valid.astype(np.float32))
        pose = np.concatenate([res.pos(b), res.quat(b)], axis=1)[valid]
        np.testing.assert_allclose(ep.features[STATE][valid, 7 * j : 7 * j + 7], pose, atol=2e-6)
    assert np.isfinite(ep.features[STATE]).all()  # gaps hold the nearest tracked pose
    assert 0 < ep.features[TRACKED].mean() < 1  # the excerpt loses samples
