"""Labelled recordings for the primitive-library parser: the .mat reader, the metrics,
level channels, ``python -m research primitives evaluate`` and its bad-input errors."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import scipy.io
from scipy.spatial.transform import Rotation

from research.primitive_scores import (
    apply_map,
    best_label_map,
    change_times,
    match_boundaries,
    segments_to_frames,
)
from research.tests.helpers import call
from thirdhand.errors import FormatError
from thirdhand.io.figueroa import read_labelled_mat
from thirdhand.primitives import PrimitiveError, PrimitiveLibrary
from thirdhand.primitives.segment_features import segment_stats

DATA = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "figueroa"
WIPING = DATA / "circular_wiping.mat"
PEELING = DATA / "peeling_noobj.mat"
needs_data = pytest.mark.skipif(
    not WIPING.is_file(), reason=f"real data not found: {DATA} (see ../shared/data/README.md)"
)


def _min_jerk(n: int) -> np.ndarray:
    s = np.linspace(0.0, 1.0, n)
    return 10 * s**3 - 15 * s**4 + 6 * s**5


def _arm_rows(pos: np.ndarray, force: np.ndarray) -> np.ndarray:
    n = pos.shape[0]
    quat_wxyz = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    return np.hstack([pos, quat_wxyz, force, np.zeros((n, 3))]).T


def _wiping_like(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Reach down (1.5 s), two circles in contact at 20 N (3 s), lift (1.5 s); 100 Hz."""
    rng = np.random.default_rng(seed)
    n1, n2, n3 = 150, 300, 150
    down = np.outer(_min_jerk(n1), [0.0, 0.0, -0.2]) + np.array([0.4, 0.0, 0.5])
    ang = np.linspace(0, 4 * np.pi, n2)
    circ = np.stack([0.4 + 0.05 * np.sin(ang), 0.05 - 0.05 * np.cos(ang), np.full(n2, 0.3)], 1)
    up = np.outer(_min_jerk(n3), [0.0, 0.0, 0.2]) + np.array([0.4, 0.0, 0.3])
    pos = np.vstack([down, circ, up]) + rng.normal(0, 1e-4, (n1 + n2 + n3, 3))
    f = np.zeros((pos.shape[0], 3))
    f[n1 : n1 + n2, 2] = -20.0
    f += rng.normal(0, 0.1, f.shape)
    labels = np.repeat([1, 2, 3], [n1, n2, n3])
    return _arm_rows(pos, f), labels


def _write_proc(path: Path, demos: list[tuple[np.ndarray, np.ndarray]], **drop: bool) -> None:
    fields = [("name", object), ("dt", object)] + ([] if drop.get("X") else [("X", object)])
    arr = np.zeros((len(demos),), dtype=np.dtype(fields))
    for i, (x, _) in enumerate(demos):
        arr[i] = (f"demo{i}", 0.01) if drop.get("X") else (f"demo{i}", 0.01, x)
    mat: dict[str, object] = {"proc_data": arr}
    if not drop.get("labels"):
        lab = np.empty((len(demos),), dtype=object)
        for i, (_, y) in enumerate(demos):
            lab[i] = y.astype(float)
        mat["True_states"] = lab
    scipy.io.savemat(path, mat)


# ------------------------------------------------------------------ reader
@needs_data
def test_real_wiping_file_reads_with_quaternions_matching_h() -> None:
    streams = read_labelled_mat(WIPING)
    assert [s.n_samples for s in streams] == [1238, 1096, 1457, 1120]
    raw = scipy.io.loadmat(WIPING, squeeze_me=True, struct_as_record=False)
    for s, d in zip(streams, raw["proc_data"], strict=True):
        assert set(np.unique(s.labels)) == {1, 2, 3}
        assert s.t[1] == pytest.approx(float(d.dt))
        rot = Rotation.from_matrix(np.moveaxis(d.H[:3, :3], 2, 0))
        err = (Rotation.from_quat(s.arms[0].quat).inv() * rot).magnitude()
        assert err.max() < 1e-9  # the file's w x y z read as thirdhand's x y z w
        assert not s.rate_assumed


@needs_data
def test_real_peeling_file_has_two_arms_and_the_stated_phase_changes() -> None:
    streams = read_labelled_mat(PEELING)
    assert [s.n_samples for s in streams] == [13820, 7333]
    assert [len(s.arms) for s in streams] == [2, 2]
    assert [s.boundaries.size for s in streams] == [44, 32]
    assert all(s.rate_assumed for s in streams)
    assert streams[0].t[-1] == pytest.approx(13819 / 100.0)


def test_reader_round_trip_of_a_written_file(tmp_path: Path) -> None:
    demos = [_wiping_like(0), _wiping_like(1)]
    _write_proc(tmp_path / "w.mat", demos)
    streams = read_labelled_mat(tmp_path / "w.mat")
    assert len(streams) == 2
    np.testing.assert_allclose(streams[0].arms[0].pos, demos[0][0][:3].T)
    np.testing.assert_allclose(streams[0].arms[0].quat, np.tile([0, 0, 0, 1.0], (600, 1)))
    np.testing.assert_array_equal(streams[1].labels, demos[1][1])
    np.testing.assert_allclose(streams[0].boundaries, [1.495, 4.495])


def test_reader_rejects_missing_fields_in_one_line(tmp_path: Path) -> None:
    demos = [_wiping_like(0)]
    _write_proc(tmp_path / "nolab.mat", demos, labels=True)
    with pytest.raises(FormatError, match=r"nolab\.mat: has proc_data but no True_states"):
        read_labelled_mat(tmp_path / "nolab.mat")
    _write_proc(tmp_path / "nox.mat", demos, X=True)
    with pytest.raises(FormatError, match=r"nox\.mat \(proc_data\[0\]\): missing field 'X'"):
        read_labelled_mat(tmp_path / "nox.mat")
    scipy.io.savemat(tmp_path / "other.mat", {"foo": np.zeros(3)})
    with pytest.raises(FormatError, match=r"expected proc_data .* variables found: foo"):
        read_labelled_mat(tmp_path / "other.mat")
    x, y = demos[0]
    _write_proc(tmp_path / "rows.mat", [(x[:12], y)])
    with pytest.raises(FormatError, match="expected 13 rows per arm"):
        read_labelled_mat(tmp_path / "rows.mat")
    _write_proc(tmp_path / "short.mat", [(x, y[:-1])])
    with pytest.raises(FormatError, match=r"True_states\[0\].*expected 600 labels"):
        read_labelled_mat(tmp_path / "short.mat")
    (tmp_path / "junk.mat").write_bytes(b"not a mat file at all")
    with pytest.raises(FormatError, match=r"junk\.mat"):
        read_labelled_mat(tmp_path / "junk.mat")
    for p in tmp_path.iterdir():
        with pytest.raises(FormatError) as info:
            read_labelled_mat(p)
        assert "\n" not in str(info.value)


# ----------------------------------------------------------------- metrics
def test_boundary_matching_is_one_to_one_within_tolerance() -> None:
    b = match_boundaries([1.0, 2.0, 10.0], [1.2, 1.4, 2.9, 20.0], tolerance=1.0)
    # 1.2 ↔ 1.0, 1.4 ↔ 2.0 (0.6 s), 2.9 left over (2.0 taken), 10 and 20 unmatched
    assert (b.n_true, b.n_pred, b.n_matched) == (3, 4, 2)
    assert b.precision == 0.5
    assert b.recall == pytest.approx(2 / 3)
    assert b.f1 == pytest.approx(2 * 0.5 * (2 / 3) / (0.5 + 2 / 3))
    assert match_boundaries([], [], tolerance=1.0).f1 == 1.0
    assert match_boundaries([1.0], [], tolerance=1.0).f1 == 0.0
    with pytest.raises(PrimitiveError, match="tolerance"):
        match_boundaries([1.0], [1.0], tolerance=-1.0)


def test_hungarian_map_undoes_a_permutation_and_counts_spare_skills_wrong() -> None:
    true = [np.array([1, 1, 2, 2, 3, 3]), np.array([3, 3, 1])]
    pred = [np.array([7, 7, 0, 0, 4, 4]), np.array([4, 4, 7])]
    mapping, ok, n = best_label_map(pred, true)
    assert mapping == {7: 1, 0: 2, 4: 3}
    assert (ok, n) == (9, 9)
    # four skills for three labels: the skill left out counts as wrong
    mapping, ok, n = best_label_map([np.array([0, 1, 2, 3, 3, 3])], [np.array([1, 1, 2, 3, 3, 3])])
    assert ok == 5 and len(mapping) == 3
    np.testing.assert_array_equal(apply_map([5, 0], {0: 2}), [-1, 2])


def test_frames_from_segments_and_change_times() -> None:
    frames = segments_to_frames([0, 3, 6], [4, 5], 7)
    np.testing.assert_array_equal(frames, [4, 4, 4, 5, 5, 5, 5])
    t = np.arange(7) * 0.5
    np.testing.assert_allclose(change_times(t, frames), [1.25])
    with pytest.raises(PrimitiveError, match="bounds"):
        segments_to_frames([0, 3], [1, 2], 4)


# ------------------------------------------------------------- levels / parse
def test_level_sums_equal_direct_sums(rng: np.random.Generator) -> None:
    y = rng.normal(size=(40, 2))
    lev = rng.normal(size=(40, 3))
    a = np.array([0, 5, 10, 0])
    b = np.array([5, 20, 39, 39])
    st = segment_stats(y, a, b, levels=lev)
    for h in range(a.size):
        part = lev[a[h] + 1 : b[h] + 1]
        np.testing.assert_allclose(st.lev_sum[h], part.sum(axis=0), atol=1e-12)
        np.testing.assert_allclose(st.lev_sq[h], (part**2).sum(axis=0), atol=1e-12)
        assert st.lev_n[h] == b[h] - a[h]


def _level_track(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Six identical 1-D moves (speed 0 between); the level is 0 or 5 per move."""
    rng = np.random.default_rng(seed)
    n = 50
    pattern = rng.permutation([0, 1, 0, 1, 1, 0])
    ys, ls, y0 = [], [], 0.0
    for k in pattern:
        ys.append(y0 + _min_jerk(n)[1:] if ys else y0 + _min_jerk(n))
        y0 += 1.0
        ls.append(np.full(ys[-1].size, 5.0 * k))
    y = np.concatenate(ys)[:, None]
    lev = np.concatenate(ls)[:, None] + rng.normal(0, 0.1, (y.shape[0], 1))
    return np.arange(y.shape[0]) * 0.01, y, lev, pattern


def test_levels_tell_apart_moves_of_the_same_shape_and_merge_repetitions() -> None:
    tracks = [_level_track(s) for s in range(3)]
    lib = PrimitiveLibrary(2, threshold=0.3, seed=0, n_init=2).fit(
        [(t, y, lev) for t, y, lev, _ in tracks]
    )
    t, y, lev, pattern = _level_track(10)
    p = lib.parse(t, y, levels=lev)
    frames = p.frame_labels()
    truth = np.repeat(pattern, 49)
    truth = np.concatenate([truth[:1], truth])
    _, ok, n = best_label_map([frames], [truth])
    assert ok / n > 0.97  # the boundary sample may go either way
    merged = p.merged()
    runs = 1 + int(np.sum(pattern[1:] != pattern[:-1]))
    assert merged.labels.size == runs
    np.testing.assert_array_equal(merged.frame_labels(), frames)


def test_grid_cuts_give_a_motion_that_never_stops_candidates() -> None:
    t = np.arange(600) * 0.01
    y = np.stack([np.cos(t * 2 * np.pi), np.sin(t * 2 * np.pi)], 1)
    lib = PrimitiveLibrary(1, threshold=0.05, grid=0.5, n_init=1)
    assert lib.prepare(t, y, "circle").nodes.size - 2 == 11
    assert PrimitiveLibrary(1, threshold=0.05).prepare(t, y, "circle").nodes.size == 2


def test_rest_at_the_ends_joins_the_first_and_last_segment() -> None:
    _, y, _, _ = _level_track(0)
    pad = 40
    y2 = np.vstack([np.repeat(y[:1], pad, 0), y, np.repeat(y[-1:], pad, 0)])
    t2 = np.arange(y2.shape[0]) * 0.01
    lib = PrimitiveLibrary(1, threshold=0.3, trim_rest=True, n_init=1).fit([(t2, y2)])
    p = lib.parse(t2, y2)
    assert p.bounds[0] == 0 and p.bounds[-1] == y2.shape[0] - 1
    assert p.bounds[1] > pad  # no segment of pure rest at the start
    assert np.all(p.candidates > pad)


def test_library_errors_for_k_and_short_tracks() -> None:
    t, y, _, _ = _level_track(0)
    with pytest.raises(PrimitiveError, match=r"possible segments for 500 skills"):
        PrimitiveLibrary(500, threshold=0.3).fit([(t, y)])
    with pytest.raises(PrimitiveError, match="at least 1 skill"):
        PrimitiveLibrary(0, threshold=0.3).fit([(t, y)])
    with pytest.raises(PrimitiveError, match=r"track 0: expected at least 15 samples .*window"):
        PrimitiveLibrary(2, threshold=0.3, window=15).fit([(t[:10], y[:10])])
    lib = PrimitiveLibrary(2, threshold=0.3, n_init=1).fit([(t, y)])
    with pytest.raises(PrimitiveError, match="2 dimensions and 0 levels, the library has 1 and 0"):
        lib.parse(t, np.hstack([y, y]))


def test_library_score_of_its_training_tracks_is_its_log_likelihood() -> None:
    tracks = [_level_track(s)[:3] for s in range(3)]
    lib = PrimitiveLibrary(2, threshold=0.3, seed=0, n_init=2).fit(tracks)
    assert lib.score(tracks) == pytest.approx(lib.log_likelihood_, rel=1e-12)
    # a track's score is its own term of the sum
    assert lib.score(tracks[:1]) + lib.score(tracks[1:]) == pytest.approx(
        lib.log_likelihood_, rel=1e-12
    )


def test_heldout_likelihood_prefers_the_skills_the_data_has() -> None:
    from research.primitive_labels import ParserConfig, fit_library, heldout_scores

    tracks = [_level_track(s)[:3] for s in range(3)]
    held = heldout_scores(tracks, ParserConfig(n_init=2), [1, 2], 0.3)
    # one skill for moves at level 0 and at level 5 (noise 0.1): each level sample
    # under N(2.5, 2.5²) instead of N(0 or 5, 0.1²) loses log(2.5 / 0.1) ≈ 3.2 nats,
    # and levels are half the scalar observations: ≈ 1.6 nats per observation
    assert held[2] - held[1] > 1.0
    cfg = ParserConfig(n_skills=None, k_range=(1, 2), n_init=2, threshold=0.3)
    lib, sel = fit_library(tracks, cfg)
    assert sel is not None and sel.chosen == 2 == lib.n_skills
    assert set(sel.bic) == set(sel.heldout) == {1, 2}
    bic_cfg = ParserConfig(n_skills=None, k_range=(1, 2), n_init=2, threshold=0.3, select="bic")
    _, by_bic = fit_library(tracks, bic_cfg)
    assert by_bic is not None and by_bic.chosen == min(by_bic.bic, key=by_bic.bic.__getitem__)
    with pytest.raises(PrimitiveError, match="'onese', 'heldout' or 'bic', got 'aic'"):
        fit_library(tracks, ParserConfig(n_skills=None, select="aic"))


# --------------------------------------------------------------------- CLI
def test_evaluate_command_table_and_json(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _write_proc(tmp_path / "w.mat", [_wiping_like(s) for s in range(3)])
    out = tmp_path / "res.json"
    rc, so, se = call(
        capsys,
        "primitives",
        "evaluate",
        str(tmp_path / "w.mat"),
        "--skills",
        "3",
        "--json",
        str(out),
    )
    assert rc == 0, se
    assert "frame accuracy" in so and "demo0" in so
    doc = json.loads(out.read_text())
    f = doc["files"][0]
    assert len(f["recordings"]) == 3
    assert 0.0 <= f["accuracy"] <= 1.0
    assert f["recordings"][0]["boundaries"]["n_true"] == 2
    rc, _, se = call(capsys, "primitives", "evaluate", str(tmp_path / "w.mat"), "--json", str(out))
    assert rc == 1 and "exists" in se and "--force" in se


@pytest.mark.slow
def test_evaluate_selects_k_by_heldout_likelihood_and_reports_bic(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from research.primitive_labels import one_se_choice, per_observation

    _write_proc(tmp_path / "w.mat", [_wiping_like(s) for s in range(3)])
    out = tmp_path / "res.json"
    rc, so, se = call(capsys, "primitives", "evaluate", str(tmp_path / "w.mat"), "--json", str(out))
    assert rc == 0, se
    doc = json.loads(out.read_text())
    for r in doc["files"][0]["recordings"]:
        sel = r["k_selection"]
        held, bic = sel["heldout_loglik_per_obs"], sel["bic"]
        assert set(held) == set(bic) == {"2", "3", "4", "5", "6"}
        assert sel["by"] == "onese" and r["n_skills"] == sel["chosen"]
        folds = {int(k): [(ll, n) for ll, n in v] for k, v in sel["heldout_folds"].items()}
        assert sel["chosen"] == one_se_choice(folds)
        assert held[str(sel["chosen"])] == pytest.approx(per_observation(folds)[sel["chosen"]])
        assert f"without {r['name']}: K = {sel['chosen']} by onese; BIC" in so


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--skills", "0"], "--skills"),
        (["--skills", "60", "--grid", "0"], "possible segments for 60 skills"),
        (["--tolerance", "-1"], "--tolerance"),
        (["--select", "aic"], "--select must be onese, heldout or bic"),
        (["--model", "crf"], "--model must be library or hsmm"),
        (["--model", "hsmm", "--levels", ""], "the HSMM needs level channels"),
        (["--levels", "force,relpos"], "level 'relpos' needs two arms"),
        (["--shape", "speed"], "unknown shape channel 'speed'"),
        (["--arms", "3"], "no arm 3"),
        (["--normalise", "rank"], "--normalise must be none, scale or zscore"),
        (["--ends"], "--ends is an option of the unsupervised HSMM"),
        (["--ends", "--label-trained"], "--ends is an option of the unsupervised HSMM"),
        (["--adapt"], "--adapt is an option of the HSMM"),
    ],
)
def test_evaluate_bad_options_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    _write_proc(tmp_path / "w.mat", [_wiping_like(0), _wiping_like(1)])
    rc, _, se = call(capsys, "primitives", "evaluate", str(tmp_path / "w.mat"), *args)
    assert rc != 0
    assert message in se
    assert se.count("\n") == 1 and "Traceback" not in se


def test_evaluate_bad_files_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _write_proc(tmp_path / "nolab.mat", [_wiping_like(0)], labels=True)
    rc, _, se = call(capsys, "primitives", "evaluate", str(tmp_path / "nolab.mat"))
    assert rc == 1 and "no True_states" in se and se.count("\n") == 1
    x, y = _wiping_like(0)
    _write_proc(tmp_path / "tiny.mat", [(x[:, :12], y[:12])])
    rc, _, se = call(capsys, "primitives", "evaluate", str(tmp_path / "tiny.mat"))
    assert rc == 1 and "window" in se and se.count("\n") == 1


# ------------------------------------------------------------------ phases
def test_phase_grouper_splits_one_skill_by_where_it_goes() -> None:
    from thirdhand.primitives.phases import PhaseGrouper, run_descriptors
    from thirdhand.primitives.primitive_library import Parse

    # free move down (skill 0), contact (skill 1), free move up (skill 0)
    y = np.concatenate([np.linspace(10, 0, 30), np.zeros(40), np.linspace(0, 10, 30)])[:, None]
    parse = Parse(np.array([0, 29, 69, 99]), np.array([0, 1, 0]), 0.0, np.array([29, 69]))
    desc, length = run_descriptors(y, parse, 2)
    np.testing.assert_allclose(desc[:, :2], [[1, 0], [0, 1], [1, 0]])
    np.testing.assert_allclose(desc[:, 2], [-10, 0, 10])
    np.testing.assert_array_equal(length, [29, 40, 30])
    g = PhaseGrouper(3, n_skills=2).fit([desc, desc], [length, length])
    phases = g.predict(desc)
    assert len(set(phases.tolist())) == 3  # the two free moves are different phases
    grouped = g.group(y, parse)
    assert grouped.labels.size == 3
    two = PhaseGrouper(2, n_skills=2).fit([desc], [length]).group(y, parse)
    assert two.labels.size in (2, 3)
    with pytest.raises(PrimitiveError, match=r"3 runs of skills .* for 5 phases"):
        PhaseGrouper(5, n_skills=2).fit([desc], [length])


def test_evaluate_streams_with_phases_on_wiping_like_data() -> None:
    from research.primitive_labels import ParserConfig, evaluate_streams

    streams = []
    for s in range(3):
        x, y = _wiping_like(s)
        streams.append(_stream_from(x, y, f"demo{s}"))
    cfg = ParserConfig(levels=("force",), n_skills=2, n_phases=3, n_init=2)
    res = evaluate_streams(streams, cfg, tolerance=0.5)
    # contact on/off are the label changes: both found in every held-out recording
    assert res.boundaries.recall == 1.0
    assert res.accuracy > 0.9
    assert all(r.n_skills == 2 for r in res.streams)


def _stream_from(x: np.ndarray, labels: np.ndarray, name: str):  # type: ignore[no-untyped-def]
    from thirdhand.io.figueroa import ArmTrack, LabelledStream

    b = x.T
    arm = ArmTrack(b[:, :3], b[:, [4, 5, 6, 3]], b[:, 7:10], b[:, 10:13])
    return LabelledStream(name, np.arange(b.shape[0]) * 0.01, (arm,), labels.astype(np.int64))


def test_stream_channels_units_and_layout() -> None:
    from research.primitive_channels import LEVEL_UNITS, SHAPE_UNITS, stream_channels

    n = 50
    ang = np.linspace(0.0, 0.5, n)
    quat = Rotation.from_rotvec(np.outer(ang, [0.0, 0.0, 1.0])).as_quat()
    x = np.hstack(
        [np.outer(np.arange(n) * 0.01, [1.0, 0, 0]), quat[:, [3, 0, 1, 2]], np.zeros((n, 6))]
    ).T
    x[9] = 4.0  # force z
    s = _stream_from(x, np.ones(n, dtype=np.int64), "s")
    y, lev = stream_channels(
        s, shape=("pos", "rot"), levels=("force", "speed", "velocity"), window=1
    )
    assert y.shape == (n, 6) and lev.shape == (n, 5)
    np.testing.assert_allclose(y[:, 5], ang / SHAPE_UNITS["rot"], atol=1e-9)  # log map about z
    np.testing.assert_allclose(lev[:, 0], 4.0 / LEVEL_UNITS["force"])
    np.testing.assert_allclose(lev[:, 1], 1.0 / LEVEL_UNITS["speed"], rtol=1e-9)  # 1 m/s
    np.testing.assert_allclose(lev[:, 2:], [[1.0 / LEVEL_UNITS["velocity"], 0, 0]] * n, atol=1e-9)
    with pytest.raises(PrimitiveError, match="unknown level channel 'jerk'"):
        stream_channels(s, levels=("jerk",))
    with pytest.raises(PrimitiveError, match="at least one shape channel"):
        stream_channels(s, shape=())


def test_stream_channels_zero_ft_and_relpos() -> None:
    from research.primitive_channels import LEVEL_UNITS, stream_channels
    from thirdhand.io.figueroa import ArmTrack, LabelledStream

    n = 200  # 2 s at 100 Hz
    t = np.arange(n) * 0.01
    quat = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
    f0 = np.tile([0.0, 3.0, 0.0], (n, 1))  # a 3 N offset ...
    f0[100:, 2] = 4.0  # ... and a 4 N press after 1 s
    a0 = ArmTrack(np.outer(t, [0.1, 0.0, 0.0]), quat, f0, np.zeros((n, 3)))
    a1 = ArmTrack(np.tile([0.5, 0.2, 0.0], (n, 1)), quat, np.zeros((n, 3)), np.zeros((n, 3)))
    s = LabelledStream("two", t, (a0, a1), np.ones(n, dtype=np.int64))
    _, raw = stream_channels(s, levels=("force",), arms=(0,), window=1)
    _, zeroed = stream_channels(s, levels=("force",), arms=(0,), window=1, zero_ft=True)
    np.testing.assert_allclose(raw[:100, 0], 3.0 / LEVEL_UNITS["force"])
    np.testing.assert_allclose(zeroed[:100, 0], 0.0, atol=1e-12)  # the offset of the first 0.5 s
    np.testing.assert_allclose(zeroed[100:, 0], 4.0 / LEVEL_UNITS["force"])
    _, lev = stream_channels(s, levels=("speed", "relpos"), window=1)
    assert lev.shape == (n, 2 + 3)  # speed per arm, then relpos once
    rel = (a0.pos - a1.pos) / LEVEL_UNITS["relpos"]
    np.testing.assert_allclose(lev[:, 2:], rel, atol=1e-12)


def test_label_trained_hsmm_parses_held_out_wiping_by_the_labels_names() -> None:
    from research.primitive_labels import ParserConfig, evaluate_streams

    streams = [_stream_from(*_wiping_like(s), f"demo{s}") for s in range(3)]
    cfg = ParserConfig(model="hsmm", label_trained=True, levels=("force",), n_skills=None)
    res = evaluate_streams(streams, cfg, tolerance=0.5)
    # reach and lift have the same force (none): only the learned order 1 → 2 → 3 tells
    # them apart, and it does, by name, with no map; a boundary is blurred by at most
    # the level smoothing (5 parse samples, 0.25 s)
    for r in res.streams:
        assert r.named_accuracy is not None and r.named_accuracy > 0.95
        assert r.boundaries.n_matched == r.boundaries.n_true == 2 == r.boundaries.n_pred
    assert res.mapping == {1: 1, 2: 2, 3: 3}


@pytest.mark.parametrize("adapt", [False, True])
def test_evaluate_label_trained_command_says_supervised(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], adapt: bool
) -> None:
    _write_proc(tmp_path / "w.mat", [_wiping_like(s) for s in range(3)])
    out = tmp_path / "sup.json"
    rc, so, se = call(
        capsys,
        "primitives",
        "evaluate",
        str(tmp_path / "w.mat"),
        "--label-trained",
        *(["--adapt"] if adapt else []),
        "--json",
        str(out),
    )
    assert rc == 0, se
    assert "LABEL-TRAINED (supervised)" in so
    assert ("ADAPTED (transductive)" in so) is adapt
    doc = json.loads(out.read_text())
    assert doc["config"]["adapt"] is adapt
    f = doc["files"][0]
    assert f["label_trained"] is True
    # the synthetic recordings look alike: adapting to the parsed one keeps the phases
    assert all(r["named_accuracy"] > 0.95 for r in f["recordings"])


def test_unsupervised_hsmm_with_ends_parses_held_out_wiping() -> None:
    from research.primitive_labels import ParserConfig, evaluate_streams

    streams = [_stream_from(*_wiping_like(s), f"demo{s}") for s in range(3)]
    cfg = ParserConfig(model="hsmm", ends=True, levels=("force",), zero_ft=True, n_skills=1)
    res = evaluate_streams(streams, cfg, tolerance=0.5)
    # reach and lift have the same force (none); without labels, the entry and exit
    # states tell them apart by where they occur: entry → contact → exit, three states
    for r in res.streams:
        assert r.accuracy > 0.95
        assert r.boundaries.n_matched == r.boundaries.n_true == 2 == r.boundaries.n_pred
        assert r.n_skills == 1 and len(set(r.skills.tolist())) == 3


def test_normalise_levels_per_recording() -> None:
    from research.primitive_labels import normalise_levels

    lev = np.array([[1.0, 5.0], [3.0, 5.0], [5.0, 5.0], [7.0, 5.0]])
    scaled = normalise_levels(lev, "scale")
    np.testing.assert_allclose(scaled[:, 0], lev[:, 0] / np.sqrt(5.0))  # sd of 1, 3, 5, 7
    np.testing.assert_allclose(scaled[:, 1], 5.0)  # a constant channel is left unscaled
    z = normalise_levels(lev, "zscore")
    np.testing.assert_allclose(z[:, 0], (lev[:, 0] - 4.0) / np.sqrt(5.0))
    np.testing.assert_allclose(z[:, 1], 0.0)
    np.testing.assert_array_equal(normalise_levels(lev, "none"), lev)
    assert normalise_levels(lev, "none") is not lev
    with pytest.raises(PrimitiveError, match="normalisation must be one of"):
        normalise_levels(lev, "rank")
