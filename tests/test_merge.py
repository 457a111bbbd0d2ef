"""``thirdhand merge``: clock offset, drift and world transform recovered; gaps kept; bad input."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from cli_helpers import call
from research.merge_synthetic import make_pair, motion
from thirdhand import io, se3
from thirdhand.demonstration import BodyInfo, Demonstration
from thirdhand.io import rosbag
from thirdhand.merge import MergeError, merge

MS = 1e-3
MM = 1e-3
DEG = 0.1


def _errors(al, truth) -> tuple[float, float, float, float]:  # type: ignore[no-untyped-def]
    return (
        abs(al.offset_s - truth.offset_s),
        abs(al.drift - truth.drift),
        float(np.linalg.norm(np.asarray(al.translation) - truth.translation)),
        float(np.degrees(se3.quat_angle(np.asarray(al.rotation), truth.rotation))),
    )


def test_noise_free_pair_recovered_exactly() -> None:
    ref, other, truth = make_pair()
    _, (al,) = merge([ref, other])
    dt, dd, dp, da = _errors(al, truth)
    # Only the linear interpolation of the 120 Hz reference limits it (µm, µs).
    assert dt < 1e-6 and dd < 1e-8 and dp < 1e-6 and da < 1e-4
    assert al.time_source == "motion" and al.frame_source == "motion"
    assert all(r.rms_m < 1e-5 for r in al.residuals)


@pytest.mark.parametrize("seed", [0, 1])
def test_noisy_pair_with_outliers_and_gaps_within_1ms_1mm_01deg(seed: int) -> None:
    ref, other, truth = make_pair(noise_m=0.5 * MM, outliers=0.1, gaps=True, seed=seed)
    _, (al,) = merge([ref, other])
    dt, dd, dp, da = _errors(al, truth)
    assert dt < 1 * MS and dp < 1 * MM and da < DEG
    assert dd < 20e-6  # 20 ppm: 1 ms over the 55 s of overlap
    res = {r.body: r for r in al.residuals}
    # 10 % outliers of body a are rejected, the noise is what is left.
    assert res["a"].inliers < 0.95 * res["a"].pairs
    assert res["b"].rms_m < 2.5 * np.sqrt(2 * 3) * 0.5 * MM


@pytest.mark.parametrize("seed", [0, 5])
def test_two_mm_noise_within_1ms_1mm_01deg_with_smoothing(seed: int) -> None:
    """Noise twice the motion between samples: the clock from smoothed tracks (--smooth) holds.

    At 2 mm per axis and 0.1 m/s, one sample places its time to about 20 ms; over
    some 18,000 pairs the offset's standard error is of order 0.2 ms, and the
    drift's lever (27 s to the overlap's end) about doubles it: 1 ms is 2-3 of those.
    """
    ref, other, truth = make_pair(noise_m=2 * MM, seed=seed)
    _, (al,) = merge([ref, other], smooth=True)
    assert al.smoothed
    dt, dd, dp, da = _errors(al, truth)
    assert dt < 1 * MS and dp < 1 * MM and da < DEG
    assert dd < 40e-6


def test_smoothing_keeps_cubics_and_splits_at_missing_samples() -> None:
    from thirdhand.merge.align import smooth_track

    t = np.arange(0.0, 2.0, 1 / 120)
    cubic = np.stack([t**3 - t, 0.5 * t**2, np.full_like(t, 0.3)], 1)
    # a cubic Savitzky-Golay filter reproduces a cubic exactly (rounding only)
    out, done = smooth_track(t, cubic)
    assert done.all() and np.abs(out - cubic).max() < 1e-12
    noisy = cubic + np.random.default_rng(0).normal(0.0, 1e-3, cubic.shape)
    assert np.std(smooth_track(t, noisy)[0] - cubic) < 0.5 * np.std(noisy - cubic)
    # one missing sample ends a run; a run shorter than the 0.2 s window stays raw
    keep = np.ones(t.size, bool)
    keep[[10, 100]] = False
    out, done = smooth_track(t[keep], noisy[keep])
    assert not done[:10].any() and done[10:98].all()
    assert np.array_equal(out[:10], noisy[keep][:10])
    assert not np.array_equal(out[10:98], noisy[keep][10:98])


def test_large_drift_and_negative_offset() -> None:
    ref, other, truth = make_pair(offset=-4.0, drift=-2e-3, duration=80.0)
    # A negative offset: the other recording started first.
    _, (al,) = merge([ref, other])
    dt, dd, dp, da = _errors(al, truth)
    assert dt < 1 * MS and dd < 1e-6 and dp < 1 * MM and da < DEG


def test_given_transform_estimates_time_only() -> None:
    ref, other, truth = make_pair(noise_m=0.3 * MM, seed=3)
    given = (truth.translation, truth.rotation)
    _, (al,) = merge([ref, other], transforms=[given])
    assert al.frame_source == "given" and al.time_source == "motion"
    assert abs(al.offset_s - truth.offset_s) < 1 * MS
    np.testing.assert_allclose(al.translation, truth.translation, atol=1e-12)


def test_merged_axis_keeps_gaps_and_fuses_shared_bodies() -> None:
    ref, other, _truth = make_pair(gaps=True, seed=4)
    merged, (al,) = merge([ref, other])
    assert set(merged.body_names) == {"a", "b", "hand", "camera"}
    assert merged.rate == pytest.approx(120.0)
    t0 = merged.meta["merge"]["reference_time_of_t0_s"]
    assert t0 == pytest.approx(0.0)  # the reference starts first
    t_ref = merged.t + t0
    # The camera (other system only) is valid only inside the other's span, and
    # never inside one of its gaps longer than 0.1 s.
    cam = merged.valid("camera")
    span = al.map_time(other.t[[0, -1]])
    assert not cam[(t_ref < span[0] - 1e-9) | (t_ref > span[1] + 1e-9)].any()
    v_src = other.valid("camera")
    gap_times = al.map_time(other.t[~v_src])
    inside_gap = np.isin(np.searchsorted(gap_times, t_ref), np.arange(1, gap_times.size))
    # frames strictly between two missing samples of the camera stay missing
    lo = np.searchsorted(gap_times, t_ref) - 1
    hi = lo + 1
    ok = (lo >= 0) & (hi < gap_times.size)
    between = np.zeros_like(cam)
    between[ok] = (gap_times[hi[ok]] - gap_times[lo[ok]]) < 0.011
    assert not cam[between & inside_gap].any()
    # Camera poses land in the reference world frame: compare with the analytic motion.
    p_true, _ = motion(t_ref[cam], 3)
    np.testing.assert_allclose(merged.pos("camera")[cam], p_true, atol=2e-4)
    # Body a: the reference's own samples where it has them, the other's in its gaps.
    filled = merged.meta["merge"]["frames_filled_from_other_recordings"]
    assert filled["a"] > 0
    np.testing.assert_allclose(
        merged.pos("a")[merged.valid("a")], motion(t_ref[merged.valid("a")], 0)[0], atol=2e-4
    )


def test_no_shared_body_and_no_transform_is_one_error() -> None:
    ref, other, _ = make_pair()
    with pytest.raises(MergeError, match="share no tracked body"):
        merge([ref.select(["hand"]), other.select(["camera"])], sources=["A", "B"])


def test_no_shared_body_with_transform_and_offset() -> None:
    ref, other, truth = make_pair(drift=0.0)
    merged, (_al,) = merge(
        [ref.select(["hand"]), other.select(["camera"])],
        offsets=[truth.offset_s],
        transforms=[(truth.translation, truth.rotation)],
    )
    cam = merged.valid("camera")
    t_ref = merged.t + merged.meta["merge"]["reference_time_of_t0_s"]
    np.testing.assert_allclose(merged.pos("camera")[cam], motion(t_ref[cam], 3)[0], atol=2e-4)


# ------------------------------------------------------------------ real data
def _moved_copy(demo: Demonstration, off: float, drift: float, p_r, q_r, rate=None):  # type: ignore[no-untyped-def]
    """``demo`` from ``off`` s on, re-timed by a clock ``drift`` fast, in another world frame."""
    d = demo.slice(start=off)
    pi, qi = se3.pose_invert(p_r, q_r)
    tracks = {}
    for n in d.body_names:
        p, q = se3.pose_compose(pi, qi, d.pos(n), d.quat(n))
        tracks[n] = (p, q, d.valid(n))
    out = d.replace(t=(d.t - off) / (1 + drift), tracks=tracks, meta={})
    return out.resample(rate, max_gap=0.2) if rate else out


@pytest.mark.parametrize(("name", "rate"), [("copy", None), ("copy.c3d", 30.0)])
def test_real_ikea_bag_against_a_re_recorded_copy(
    shared_data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str, rate
) -> None:  # type: ignore[no-untyped-def]
    """Niekum's IKEA bags (AR tags ar_0, ar_13, 23 Hz) against a copy in another format.

    The copy starts 2.5 s later, on a clock 80 ppm fast, in a world frame moved by a
    known transform, written by our writers as a 3rdHand poses.dat folder (same
    samples) or a 30 Hz C3D (resampled): ``thirdhand merge`` recovers all of it.
    """
    bags = sorted((shared_data / "niekum" / "ikea_table_leg_pos_1").glob("part*.bag"))
    ref = rosbag.read(bags)
    ref_path = tmp_path / "ref.parquet"
    io.save(ref, ref_path)
    off, drift = 2.5, 80e-6
    q_r = se3.random_quat(np.random.default_rng(7))
    p_r = np.array([0.4, -0.9, 1.1])
    copy = _moved_copy(ref, off, drift, p_r, q_r, rate)
    path = tmp_path / name
    io.save(copy, path)
    back = io.load(path)
    # A format may start its axis at 0: the copy's t = 0 is then copy.t[0] later.
    want_offset = off + (1 + drift) * (copy.t[0] - back.t[0])
    out_path = tmp_path / "merged.parquet"
    report = tmp_path / "report.json"
    rc, text, err = call(
        capsys, "merge", str(ref_path), str(path), "-o", str(out_path), "--report", str(report)
    )
    assert rc == 0, err
    assert "residual rms" in text
    import json

    al = json.loads(report.read_text())["alignments"][str(path)]
    assert abs(al["offset_s"] - want_offset) < 1 * MS
    assert abs(al["drift"] - drift) < 5e-6
    assert np.linalg.norm(np.asarray(al["translation"]) - p_r) < 1 * MM
    assert np.degrees(se3.quat_angle(np.asarray(al["rotation"]), q_r)) < DEG
    merged = io.load(out_path)
    assert merged.body_names == ["ar_0", "ar_13"]
    assert merged.duration == pytest.approx(ref.duration, abs=0.1)


# ------------------------------------------------------------------ bad input
def _save(demo: Demonstration, path: Path) -> Path:
    io.save(demo, path)
    return path


def test_cli_no_shared_body_one_error_nothing_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    ref, other, _ = make_pair(duration=20.0)
    a = _save(ref.select(["hand"]), tmp_path / "a.parquet")
    b = _save(other.select(["camera"]), tmp_path / "b.parquet")
    target = tmp_path / "m.parquet"
    rc, _, err = call(capsys, "merge", str(a), str(b), "-o", str(target))
    assert rc == 1
    assert err.count("\n") == 1 and "share no tracked body" in err and "--transform" in err
    assert not target.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.parquet", "b.parquet"]


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--transform", "1 2 3"], "expected 7 finite numbers"),
        (["--transform", "0 0 0 0 0 0 2"], "unit norm"),
        (["--offset", "x"], "expected a number"),
        (["--offset", "1", "--offset", "2"], "given 2 times"),
        (["--same", "nope"], "expected REF=OTHER"),
        (["--via", "hand"], "not tracked by both"),
        (["--config", "{cfg}"], "[merge] rate: Input should be less than or equal to 100000"),
    ],
)
def test_cli_bad_options_one_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: list[str], message: str
) -> None:
    ref, other, _ = make_pair(duration=20.0)
    a = _save(ref, tmp_path / "a.parquet")
    b = _save(other, tmp_path / "b.parquet")
    target = tmp_path / "m.parquet"
    cfg = tmp_path / "settings.toml"
    cfg.write_text("[merge]\nrate = inf\n")
    extra = [e.format(cfg=cfg) for e in extra]
    rc, _, err = call(capsys, "merge", str(a), str(b), "-o", str(target), *extra)
    assert rc in (1, 2)
    assert err.count("\n") == 1 and message in err, err
    assert not target.exists()


def test_cli_same_renames_a_body(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    ref, other, _truth = make_pair(duration=25.0, drift=0.0)
    other = other.select(["b"])
    other = Demonstration(
        other.t, [BodyInfo("tag7")], {"tag7": other.pos("b")}, {"tag7": other.quat("b")}
    )
    a = _save(ref, tmp_path / "a.parquet")
    b = _save(other, tmp_path / "b.parquet")
    target = tmp_path / "m.parquet"
    cfg = tmp_path / "settings.yaml"
    cfg.write_text("merge:\n  drift: false\n")
    rc, out, err = call(
        capsys, "merge", str(a), str(b), "-o", str(target), "--same", "b=tag7", "--config", str(cfg)
    )
    assert rc == 0, err
    assert "b: " in out
    merged = io.load(target)
    assert "tag7" not in merged and "b" in merged
    shutil.rmtree(tmp_path)
