"""Constraint types of real articulated-object tracks (Sturm et al.; Niekum et al.).

Every track was recorded by a camera (checkerboard/marker detection, AR tags).
The fits use the default flags: the noise is estimated from each track. With the
1 mm motion-capture floor (``NoiseModel()``), the cameras' slowly varying errors
of a few millimetres read as evidence of a 2 cm slide along the stapler's hinge
(cylindrical); ``test_mocap_floor_over_reads_camera_error`` pins that down. The
``NoiseModel.camera()`` override (1 cm floor) still gives the same types.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from thirdhand import io, se3
from thirdhand.constraints import NoiseModel, demo_track, fit_constraint, fit_prismatic, select
from thirdhand.constraints.noise import estimate_noise
from thirdhand.constraints.robust import fit_model, prepare_track
from thirdhand.constraints.select import HINGE_NOTE, type_probabilities

CAMERA = NoiseModel.camera()


def _track(path: Path) -> tuple[np.ndarray, np.ndarray | None]:
    pos, quat, _ = demo_track(io.load(path))
    return pos, quat


@pytest.mark.parametrize(("name", "kind"), [("door.txt", "revolute"), ("drawer.txt", "prismatic")])
def test_oriented_articulation_tracks(shared_data: Path, name: str, kind: str) -> None:
    pos, quat = _track(shared_data / "articulation" / name)
    assert quat is not None
    c = fit_constraint(pos, quat)
    assert c.type == kind
    # drawer.txt has 19 samples, 28 mm apart: the type is the likeliest of five, no more.
    assert c.confidence > (0.9 if name == "door.txt" else 0.3)
    assert c.noise_source == "estimated"
    # The camera override says the same, and so does position alone under it.
    assert fit_constraint(pos, quat, noise=CAMERA).type == kind
    assert fit_constraint(pos, noise=CAMERA).type == kind


@pytest.mark.parametrize("index", range(1, 11))
def test_cabinet_one_is_revolute(shared_data: Path, index: int) -> None:
    pos, quat = _track(shared_data / "articulation" / "cabinet_one" / f"{index:03d}.log")
    assert quat is None
    c = fit_constraint(pos)
    assert c.type == "revolute"
    assert c.confidence > 0.9
    assert c.axis is not None and c.radius is not None
    # The cabinet door turns about a vertical hinge, ~38 cm from the handle, by 70-115°.
    assert abs(c.axis[2]) > 0.98
    assert 0.3 < c.radius < 0.45
    assert 70.0 < np.degrees(np.ptp(c.ranges[3])) < 115.0
    if index == 2:
        # The last 17 frames leave the arc smoothly (a real outlier stretch, no jump): the
        # circle calls them outliers at 2.2 mm of noise, far from its 1 cm ceiling, and is
        # kept (``saturated_joint`` passes over only a joint near its ceiling).
        assert c.outlier_fraction == pytest.approx(17 / 112)
        assert c.sigma_pos < 0.5 * 0.01
        assert not c.notes


@pytest.mark.parametrize("index", range(1, 11))
def test_drawer_one_is_prismatic(shared_data: Path, index: int) -> None:
    pos, _ = _track(shared_data / "articulation" / "drawer_one" / f"{index:03d}.log")
    c = fit_constraint(pos)
    assert c.type == "prismatic", c.scores
    assert c.axis is not None
    # Drawers open along the camera's x axis by about 45 cm; 004's line is tilted by 9°
    # towards the 5 cm its grasp slides sideways at the end stop (frames 84 on).
    assert abs(c.axis[0]) > (0.98 if index == 4 else 0.99)
    if index != 4:
        # An arc that bows by under 3 % of its chord is the line's motion: no weight.
        assert c.confidence > 0.99
    assert 0.43 < np.ptp(c.ranges[0]) < 0.47


def test_drawer_one_004_is_prismatic_by_its_score(shared_data: Path) -> None:
    """004's grasp slides 5 cm sideways at the end stop (frames 84 on) and creeps along the
    handle before it; why it is prismatic, and how close the call is.

    Before the hinge-radius prior, the prismatic fit under the 1 cm ceiling stopped at a poor local
    optimum (its noise at the ceiling, no outlier: 726 nats) and the arc scored better;
    the bow test alone kept it a drawer (at 0.46). The fit's second start, from a trimmed
    fit (``robust.fit_model``), finds the line that gives exactly the terminal regime to
    the outlier class at 4.3 mm of noise (816 nats): it now scores better than the arc,
    which is still passed over by the bow test (its 38 mm bow is under 5 standard errors
    of a trend in its residuals, whose slowly varying error leaves about 8 effective
    samples) and is the runner-up. With the tracker's error capped at 5 mm the line needs
    nearly its largest noise (4.3 of 5 mm) and calls a smooth stretch outliers, which is
    no joint (``saturated_joint``): under that cap the call is free, with notes for both
    joints.
    """
    pos, _ = _track(shared_data / "articulation" / "drawer_one" / "004.log")
    c = fit_constraint(pos)
    assert c.type == "prismatic"
    assert c.scores["prismatic"] < c.scores["revolute"]
    assert any(n.startswith("revolute not chosen") and "standard errors" in n for n in c.notes)
    p, _ = prepare_track(pos, None)
    line = fit_model("prismatic", p, None, noise=estimate_noise(p).noise_model())
    assert line is not None
    np.testing.assert_array_equal(np.flatnonzero(~line.inlier), np.arange(84, p.shape[0]))
    assert 0.004 < line.sigma_pos < 0.005
    # The confidence says it is not a sure call: the arc, passed over, keeps 0.3 of its
    # weight and is the runner-up.
    assert 0.7 < c.confidence < 0.9
    probs = type_probabilities(c.scores, passed_over=("revolute",))
    assert probs["prismatic"] == pytest.approx(c.confidence)
    assert c.runner_up is not None and c.runner_up.type == "revolute"
    assert c.runner_up.confidence == pytest.approx(probs["revolute"])
    p, _ = prepare_track(pos, None)
    capped = dataclasses.replace(estimate_noise(p).noise_model(), pos_ceiling=0.005)
    c5 = fit_constraint(pos, noise=capped)
    assert c5.type == "free"
    assert any(n.startswith("prismatic not chosen") and "near the ceiling" in n for n in c5.notes)
    fit = fit_model("prismatic", p, None, noise=capped)
    assert fit is not None
    assert fit.sigma_pos > 0.8 * 0.005
    np.testing.assert_array_equal(np.flatnonzero(~fit.inlier), np.arange(84, p.shape[0]))
    # Without the slide it is a drawer under the camera preset; the slide is real: the
    # tail sits 5 cm off the stroke's line.
    assert fit_constraint(pos[:84], noise=CAMERA).type == "prismatic"
    line = fit_prismatic(pos[:84], noise=CAMERA)
    assert line.axis is not None
    off = pos[95:108] - line.origin
    dist = np.linalg.norm(off - np.outer(off @ line.axis, line.axis), axis=1)
    assert np.all(dist > 0.03)
    # Before the slide the stroke bends by creeping steps: flat stretches of the sideways
    # coordinate 16 mm apart, each within 2 mm; with the estimated noise the arc scores
    # better there (the stroke alone has more effective samples: its bow is resolved), but
    # it is a 1.6 m radius, flatter than any hinge's (it was revolute before).
    y = pos[:, 1]
    assert y[64:76].mean() - y[47:58].mean() > 0.012
    assert max(y[47:58].std(), y[64:76].std()) < 0.002
    head = fit_constraint(pos[:84])
    assert head.type == "prismatic"
    assert head.scores["revolute"] < head.scores["prismatic"]
    assert any(HINGE_NOTE in n for n in head.notes)


def _stapler(shared_data: Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    z = np.load(shared_data / "niekum" / "stapler_revolute.npz")
    o1, o2 = z["object1"], z["object2"]
    p, q = se3.relative_pose(o1[:, :3], o1[:, 3:], o2[:, :3], o2[:, 3:])
    return {
        "relative1": (z["relative1"][:, :3], z["relative1"][:, 3:]),
        "relative2": (z["relative2"][:, :3], z["relative2"][:, 3:]),
        "object2 in object1": (p, q),
    }


def test_stapler_relative_tracks_are_revolute(shared_data: Path) -> None:
    tracks = _stapler(shared_data)
    # relative2 is exactly the inverse of relative1 (object1 in object2).
    p_inv, q_inv = se3.pose_invert(*tracks["relative1"])
    np.testing.assert_allclose(p_inv, tracks["relative2"][0], atol=1e-12)
    assert np.max(se3.quat_angle(q_inv, tracks["relative2"][1])) < 1e-6
    fits = {k: fit_constraint(p, q) for k, (p, q) in tracks.items()}
    for name, c in fits.items():
        assert c.type == "revolute", (name, c.scores)
        # The 2 cm slide along the hinge keeps a cylindrical joint in the running.
        assert c.confidence > 0.6
        assert c.scores["revolute"] < c.scores["cylindrical"]
        assert fit_constraint(*tracks[name], noise=CAMERA).type == "revolute"
        # The stapler opens by about 160°.
        assert 150.0 < np.degrees(np.ptp(c.ranges[3])) < 170.0
    # relative1 is object2 in object1: same axis as the track computed from the objects.
    a1, a12 = fits["relative1"].axis, fits["object2 in object1"].axis
    assert a1 is not None and a12 is not None
    assert abs(float(a1 @ a12)) > 0.999


def test_mocap_floor_over_reads_camera_error(shared_data: Path) -> None:
    p, q = _stapler(shared_data)["relative1"]
    c = fit_constraint(p, q, noise=NoiseModel())
    assert c.type == "cylindrical"
    # ... by a 2 cm slide along the hinge axis, under the camera's 1 cm floor of noise.
    assert np.ptp(c.ranges[0]) < 0.025


def test_cli_fit_prints_json_and_table(shared_data: Path, tmp_path: Path) -> None:
    import json

    from typer.testing import CliRunner

    from thirdhand.constraints.cli import app

    runner = CliRunner()
    door = shared_data / "articulation" / "door.txt"
    result = runner.invoke(app, ["fit", str(door), "--json"])
    assert result.exit_code == 0, result.output
    d = json.loads(result.output)
    assert d["type"] == "revolute"
    assert d["track"] == "door"
    assert set(d["scores"]) == {"fixed", "prismatic", "revolute", "cylindrical", "free"}
    assert d["confidence"] > 0.9
    # The estimated noise is reported: millimetres, not the 1 mm / 1 cm presets.
    assert d["noise"]["source"] == "estimated"
    assert 1e-3 < d["noise"]["sigma_pos"] < 2e-2
    camera = tmp_path / "camera.toml"
    camera.write_text("[constraints.fit]\nnoise = 'camera'\n")
    result = runner.invoke(app, ["fit", str(door), "--json", "--config", str(camera)])
    assert json.loads(result.output)["noise"]["source"] == "given"
    log = shared_data / "articulation" / "drawer_one" / "001.log"
    result = runner.invoke(app, ["fit", str(log)])
    assert result.exit_code == 0, result.output
    assert "prismatic" in result.output
    assert "tx [" in result.output
    assert "noise" in result.output
    assert "revolute not chosen" in result.output


def test_cli_errors_are_thirdhand_errors(shared_data: Path, tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from thirdhand.constraints.cli import app
    from thirdhand.errors import ThirdhandError

    runner = CliRunner()
    door = str(shared_data / "articulation" / "door.txt")
    loud, hinge = tmp_path / "loud.toml", tmp_path / "hinge.toml"
    loud.write_text("[constraints.fit]\nnoise = 'loud'\n")
    hinge.write_text("[constraints.fit]\nmodels = ['fixed', 'hinge']\n")
    for args, match in (
        (["fit", door, "--config", str(loud)], "noise: Input should be"),
        (["fit", door, "--config", str(hinge)], "unknown model"),
        (["fit", door, "--parent", "table", "--child", "door"], "no body 'table'"),
        (["fit", str(tmp_path / "none.txt")], "no such file"),
    ):
        result = runner.invoke(app, args)
        assert result.exit_code != 0
        assert isinstance(result.exception, ThirdhandError), args
        assert match in str(result.exception)
    short = tmp_path / "short.txt"
    short.write_text("0 0 0\n0.1 0 0\n0.2 0 0\n")
    result = runner.invoke(app, ["fit", str(short)])
    assert isinstance(result.exception, ThirdhandError)
    assert "3 valid sample(s) of 3" in str(result.exception)


def test_attached_toolbox_boards_drift_in_time(shared_data: Path) -> None:
    """The time drift of the synthetic sweep is real: two boards rigidly attached (the
    last 37 s of ``toolbox_coop_4``, a Polhemus magnetic tracker) hold their relative
    pose within 0.01 mm from sample to sample, yet it wanders by millimetres over
    seconds: the means over windows of a tenth of the stretch spread by over 100 times
    the white noise (the sweep's time drift: 2 times). It is still read as fixed."""
    demo = io.load(shared_data / "3rdhand" / "toolbox_coop_4")
    p, q, valid = demo.relative_pose("/toolbox/side_front", "/toolbox/side_left")
    keep = valid & (demo.t >= demo.t[0] + 30.0)
    pos, quat = prepare_track(p[keep], q[keep])
    white = estimate_noise(pos, quat).sigma_pos
    w = pos.shape[0] // 10
    means = np.stack([np.convolve(pos[:, a], np.ones(w) / w, "valid") for a in range(3)], 1)
    slow = float(np.sqrt(((means - means.mean(axis=0)) ** 2).mean()))
    assert white < 5e-5
    assert slow > 100.0 * white
    assert slow > 1e-3
    assert fit_constraint(pos, quat).type == "fixed"


# The second set (camera-tracked, position-only, ~250-390 samples) and cabinet_two (a
# cabinet door opened through ~20-35°, 64-89 samples).
SECOND_SET = [
    *(("second_set/drawer", i, "prismatic") for i in range(1, 9)),
    *(("second_set/left_door", i, "revolute") for i in range(1, 8)),
    *(("second_set/right_door", i, "revolute") for i in (1, 2, 3, 4, 5, 6, 8)),
    *(("second_set/sliding_cabinet", i, "prismatic") for i in range(1, 5)),
    *(("cabinet_two", i, "revolute") for i in (3, 4)),
]


@pytest.mark.parametrize(("folder", "index", "kind"), SECOND_SET)
def test_second_set_and_cabinet_two(shared_data: Path, folder: str, index: int, kind: str) -> None:
    pos, quat = _track(shared_data / "articulation" / folder / f"{index:03d}.log")
    assert quat is None
    c = fit_constraint(pos)
    assert c.type == kind, (c.scores, c.notes)
    assert c.axis is not None
    if folder.endswith("_door"):
        # The doors turn about a vertical hinge 33-40 cm from the handle, by 60-103°.
        assert c.radius is not None and 0.3 < c.radius < 0.45
        assert abs(c.axis[2]) > 0.98
        assert c.confidence > 0.99
    if folder.endswith("drawer"):
        # Drawers open along the camera's x axis by 45-46 cm.
        assert abs(c.axis[0]) > 0.99
        assert 0.44 < np.ptp(c.ranges[0]) < 0.47


def test_sliding_cabinet_001_is_no_hinge(
    shared_data: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A cabinet door sliding 59 cm sideways, its path stepped by ~2 cm (the tracker
    changes by 2 cm along the stroke, twice): its arc (1.9 m radius, 18°) scores far
    better than the line, with a bow of 23 mm that is 8 standard errors of its
    residuals' trend. No hinge a person opens has that radius: the arc is flatter than
    one of :data:`MAX_HINGE_RADIUS` (1 m) over the same chord by 7.6 standard errors,
    and is void (it was revolute at 0.995 before)."""
    pos, _ = _track(shared_data / "articulation" / "second_set" / "sliding_cabinet" / "001.log")
    c = fit_constraint(pos)
    assert c.type == "prismatic"
    assert c.scores["revolute"] < c.scores["prismatic"] - 30.0
    note = next(n for n in c.notes if n.startswith("revolute"))
    assert HINGE_NOTE in note
    assert c.confidence > 0.99
    # Without the prior (any radius a hinge) the arc wins.
    monkeypatch.setattr(select, "MAX_HINGE_RADIUS", math.inf)
    assert fit_constraint(pos).type == "revolute"


@pytest.mark.parametrize("index", [1, 2, 5])
@pytest.mark.xfail(strict=True, reason="short door arcs the track does not resolve")
def test_cabinet_two_short_arcs(shared_data: Path, index: int) -> None:
    """cabinet_two/001, 002, 005 read prismatic: 001's path bows by 1 % of its chord (a
    3 mm bow of the best arc: straight by the track); 002 and 005 bow by 18 mm over
    ~42 cm (a 1.2-1.3 m radius), under 5 standard errors (26-29 mm) of a trend in their
    residuals, whose slowly varying error (4-5 mm rms, 8-9 effective samples) is as
    large as drawer_one/004's grasp shift. No grid of the three choices re-fitted by
    ``research/scripts/constraint_lomo.py`` calls them revolute without losing another track."""
    pos, _ = _track(shared_data / "articulation" / "cabinet_two" / f"{index:03d}.log")
    assert fit_constraint(pos).type == "revolute"


def test_cabinet_two_close_calls_name_the_arc(shared_data: Path) -> None:
    """Where the door's arc is passed over as unresolved the confidence says it is a close
    call and the runner-up is the arc, with its geometry (a vertical hinge)."""
    for index in (2, 5):
        pos, _ = _track(shared_data / "articulation" / "cabinet_two" / f"{index:03d}.log")
        c = fit_constraint(pos)
        assert c.type == "prismatic"
        assert 0.5 < c.confidence < 0.7
        ru = c.runner_up
        assert ru is not None and ru.type == "revolute"
        assert 0.3 < ru.confidence < 0.5
        assert ru.confidence + c.confidence <= 1.0
        assert ru.axis is not None and abs(ru.axis[2]) > 0.99
        assert ru.radius is not None and 1.0 < ru.radius < 1.5
