"""The hinge-radius prior, the runner-up type, and bad input of any size."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from thirdhand.constraints import fit_constraint
from thirdhand.constraints.noise import estimate_noise
from thirdhand.constraints.robust import fit_model, prepare_track
from thirdhand.constraints.select import (
    HINGE_NOTE,
    MAX_HINGE_RADIUS,
    bow_standard_error,
    effective_samples,
    type_probabilities,
    unphysical_turn,
)
from thirdhand.constraints.types import ConstraintFitError


def _arc(radius: float, turn_deg: float, n: int, noise: float, seed: int = 0) -> np.ndarray:
    """A horizontal arc about a vertical axis through (0.2, -0.1, 0.3), metres, (n, 3)."""
    rng = np.random.default_rng(seed)
    theta = np.linspace(0.0, math.radians(turn_deg), n)
    pos = np.column_stack(
        [0.2 + radius * np.cos(theta), -0.1 + radius * np.sin(theta), np.full(n, 0.3)]
    )
    return pos + noise * rng.standard_normal(pos.shape)


def _fits(pos: np.ndarray) -> tuple[dict, float]:
    p, _ = prepare_track(pos, None)
    nm = estimate_noise(p).noise_model()
    fits = {k: fit_model(k, p, None, noise=nm) for k in ("fixed", "prismatic", "revolute")}
    return fits, effective_samples(fits)


def test_unphysical_turn_arithmetic() -> None:
    """The note's bow deficit is the 1 m arc's bow over the fitted chord less the fitted
    bow, in the standard errors of :func:`bow_standard_error`; noise-free, the fit
    recovers the radius and turn exactly."""
    fits, n_eff = _fits(_arc(2.0, 20.0, 200, 0.0))
    arc = fits["revolute"]
    lever = arc.geom.lever - (arc.geom.lever @ arc.geom.axis) * arc.geom.axis
    assert float(np.linalg.norm(lever)) == pytest.approx(2.0, rel=1e-6)
    assert math.degrees(float(np.ptp(arc.proj.latent[:, 0]))) == pytest.approx(20.0, rel=1e-6)
    chord = 2.0 * 2.0 * math.sin(math.radians(10.0))
    bow = 2.0 * (1.0 - math.cos(math.radians(10.0)))
    bow_max = MAX_HINGE_RADIUS * (1.0 - math.cos(math.asin(chord / (2.0 * MAX_HINGE_RADIUS))))
    se = bow_standard_error(arc, n_eff)
    assert se == pytest.approx(arc.sigma_pos * math.sqrt(12.0 / n_eff))
    note = unphysical_turn(arc, n_eff=n_eff)
    assert note is not None and HINGE_NOTE in note
    assert f"{1e3 * bow:.1f} mm, {1e3 * (bow_max - bow):.1f} mm" in note
    assert f"{1e3 * chord:.0f} mm chord" in note
    # A door within the prior is no concern of the test.
    fits, n_eff = _fits(_arc(0.8, 40.0, 200, 0.0))
    assert unphysical_turn(fits["revolute"], n_eff=n_eff) is None
    # Nor a prismatic fit.
    assert unphysical_turn(fits["prismatic"], n_eff=n_eff) is None


@pytest.mark.parametrize(
    ("radius", "turn", "kind"),
    [
        (0.4, 30.0, "revolute"),  # a cabinet door opened a little
        (0.9, 25.0, "revolute"),  # a room door
        (2.0, 20.0, "prismatic"),  # no hinge: a stroke bent by 3 cm
        (3.0, 12.0, "prismatic"),
    ],
)
def test_hinge_prior_on_arcs(radius: float, turn: float, kind: str) -> None:
    """Position-only arcs with 0.5 mm of white noise: doors of furniture stay revolute,
    arcs of a radius no hinge has are void (the chosen line's confidence is the floor's
    complement: the arc keeps only its share of the floor)."""
    c = fit_constraint(_arc(radius, turn, 200, 5e-4, seed=1))
    assert c.type == kind, (c.scores, c.notes)
    if kind == "prismatic":
        assert c.scores["revolute"] < c.scores["prismatic"]
        note = next(n for n in c.notes if n.startswith("revolute"))
        assert HINGE_NOTE in note or "% of its chord" in note
        probs = type_probabilities(c.scores, passed_over=("revolute",), void=("revolute",))
        assert c.confidence == pytest.approx(probs["prismatic"])
    else:
        assert c.radius == pytest.approx(radius, rel=0.02)


def test_runner_up_is_the_next_type_with_its_geometry() -> None:
    """The runner-up is the most probable other type, fitted; its probability and the
    chosen one's are the table's; the JSON form carries it."""
    c = fit_constraint(_arc(0.4, 60.0, 150, 1e-3, seed=2))
    assert c.type == "revolute"
    ru = c.runner_up
    assert ru is not None and ru.type != "revolute"
    probs = type_probabilities(c.scores)
    assert ru.confidence == pytest.approx(max(v for k, v in probs.items() if k != "revolute"))
    assert ru.runner_up is None
    d = json.loads(json.dumps(c.to_dict(), allow_nan=False))
    assert d["runner_up"]["type"] == ru.type
    assert d["runner_up"]["probability"] == pytest.approx(ru.confidence)
    # A line's runner-up, on a clean stroke, is the arc; its range is an angle.
    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 0.3, 120)
    line = np.column_stack([t, 0.5 * t, np.zeros_like(t)]) + 1e-3 * rng.standard_normal((120, 3))
    c = fit_constraint(line)
    assert c.type == "prismatic"
    assert c.runner_up is not None and c.runner_up.type in ("revolute", "free", "fixed")


def test_cli_prints_the_runner_up(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from typer.testing import CliRunner

    from thirdhand.constraints.cli import app

    path = tmp_path / "arc.txt"
    np.savetxt(path, _arc(0.4, 60.0, 150, 1e-3, seed=2))
    result = CliRunner().invoke(app, ["fit", str(path)])
    assert result.exit_code == 0, result.output
    assert "runner-up" in result.output
    result = CliRunner().invoke(app, ["fit", str(path), "--json"])
    assert json.loads(result.output)["runner_up"]["type"] in ("prismatic", "free", "fixed")


def test_two_samples_and_nans_are_one_line_errors() -> None:
    with pytest.raises(ConstraintFitError, match=r"^track: 2 valid sample\(s\) of 2;"):
        fit_constraint(np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]]))
    pos = _arc(0.4, 60.0, 40, 1e-3)
    pos[3:] = np.nan
    with pytest.raises(ConstraintFitError) as err:
        fit_constraint(pos)
    assert "\n" not in str(err.value)
    assert "3 valid sample(s) of 40" in str(err.value)


@pytest.mark.slow
def test_a_million_samples_is_a_result() -> None:
    """10^6 samples (a 0.4 m stroke, 1 mm of noise): a result, with its runner-up."""
    rng = np.random.default_rng(0)
    n = 10**6
    t = np.linspace(0.0, 1.0, n)
    pos = np.column_stack([0.4 * t, np.zeros(n), np.zeros(n)])
    pos += 1e-3 * rng.standard_normal((n, 3))
    c = fit_constraint(pos)
    assert c.type == "prismatic"
    assert c.n_samples == n
    assert c.runner_up is not None
    assert c.noise_pos == pytest.approx(1e-3, rel=0.05)
