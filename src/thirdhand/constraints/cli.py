"""``thirdhand constraints``: fit kinematic constraint models to recorded tracks.

``thirdhand constraints fit TRACK [--parent A --child B] [--json]`` loads any
recording :func:`thirdhand.io.load` reads, takes the single body's pose (an
articulation log) or the child's pose in the parent, fits every model and prints
the chosen one with the BIC of all. The noise is estimated from the track
(``--noise auto``, the default) and reported; ``--noise mocap`` (1 mm floor) or
``--noise camera`` (1 cm floor) override it.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

from thirdhand.config import ConfigOption, load_settings
from thirdhand.constraints.select import (
    demo_track,
    fit_constraint,
    passed_over_types,
    type_probabilities,
)
from thirdhand.constraints.types import ConstraintFitError, JointFit, NoiseModel
from thirdhand.demonstration import DOF_NAMES

app = typer.Typer(
    help="Kinematic constraints (fixed, prismatic, revolute, cylindrical, free) of a track.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
out = Console(highlight=False, soft_wrap=True)

#: Noise presets by name (see :class:`~thirdhand.constraints.types.NoiseModel`);
#: ``auto`` (None) estimates the noise from the track.
NOISE_PRESETS = {"auto": None, "mocap": NoiseModel, "camera": NoiseModel.camera}


@app.callback()
def _group() -> None:
    """Kinematic constraints (fixed, prismatic, revolute, cylindrical, free) of a track."""


def _vec(v: np.ndarray | None, digits: int = 4) -> str:
    if v is None:
        return "-"
    return "[" + ", ".join(f"{x:.{digits}f}" for x in v) + "]"


def _print_table(path: Path, where: str, c: JointFit) -> None:
    out.print(f"[bold]{path.name}[/bold] ({where}, {c.n_samples} valid samples)")
    out.print(f"  type        {c.type}   confidence {c.confidence:.3f}")
    rot = "" if not math.isfinite(c.noise_rot) else f", {math.degrees(c.noise_rot):.2f} deg"
    if math.isfinite(c.noise_pos):
        out.print(
            f"  noise       {1000 * c.noise_pos:.2f} mm{rot} per axis (estimated from the track"
            + ("" if c.noise_source == "estimated" else "; bounds given by --noise")
            + ")"
        )
    for note in c.notes:
        out.print(f"  note        {note}")
    out.print(f"  axis        {_vec(c.axis)}")
    out.print(f"  origin      {_vec(c.origin)} m")
    if c.radius is not None:
        out.print(f"  radius      {c.radius:.4f} m")
    rms_rot = "" if c.rms_rot is None else f", {math.degrees(c.rms_rot):.2f} deg"
    out.print(
        f"  residual    {1000 * c.rms_pos:.2f} mm{rms_rot} rms, outliers {c.outlier_fraction:.1%}"
    )
    free = [(n, r) for n, r in zip(DOF_NAMES, c.ranges, strict=True)]
    out.print(
        "  range       "
        + (
            ", ".join(
                f"{n} [{lo:.4f}, {hi:.4f}] {'m' if n[0] == 't' else 'rad'}"
                for n, (lo, hi) in free
                if lo != hi
            )
            or "all locked"
        )
    )
    ru = c.runner_up
    if ru is not None:
        geom = f", axis {_vec(ru.axis, 3)}" if ru.axis is not None else ""
        if ru.radius is not None:
            geom += f", radius {ru.radius:.3f} m"
        ranges = ", ".join(
            f"{n} [{lo:.3f}, {hi:.3f}] {'m' if n[0] == 't' else 'rad'}"
            for n, (lo, hi) in zip(DOF_NAMES, ru.ranges, strict=True)
            if lo != hi
        )
        out.print(
            f"  runner-up   {ru.type}   probability {ru.confidence:.3f}{geom}"
            + (f", range {ranges}" if ranges and ru.type != "free" else "")
            + f", residual {1000 * ru.rms_pos:.2f} mm rms"
        )
    table = Table("model", "BIC", "probability")
    names, void = passed_over_types(c.notes)
    weights = type_probabilities(c.scores, passed_over=names, void=void)
    for name, score in sorted(c.scores.items(), key=lambda kv: kv[1]):
        table.add_row(name, f"{score:.1f}", f"{weights[name]:.3f}")
    out.print(table)


@app.command()
def fit(
    track: Annotated[Path, typer.Argument(help="A recording (any format thirdhand reads).")],
    parent: Annotated[
        str | None, typer.Option(help="Parent body (recordings of two or more bodies).")
    ] = None,
    child: Annotated[str | None, typer.Option(help="Child body.")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print JSON instead of a table.")] = False,
    config: ConfigOption = None,
) -> None:
    """Fit every constraint model to a track and print the best one (by BIC).

    Settings (``[constraints.fit]`` of ``--config``): ``noise`` (auto, mocap or
    camera) and the candidate ``models``.
    """
    from thirdhand import io
    from thirdhand.constraints.settings import FitSettings

    cfg = load_settings(config, "constraints.fit", FitSettings)
    noise, names = cfg.noise, cfg.models
    if parent is not None and parent == child:
        raise ConstraintFitError(
            f"--parent and --child are both {parent!r}; a constraint needs two bodies"
        )
    demo = io.load(track)
    pos, quat, where = demo_track(demo, parent=parent, child=child)
    preset = NOISE_PRESETS[noise]
    c = fit_constraint(
        pos,
        quat,
        models=names,
        noise=None if preset is None else preset(),
        where=f"{track} ({where})",
    )
    if as_json:
        d = {"file": str(track), "track": where, **c.to_dict()}
        out.print_json(json.dumps(d, allow_nan=False))
    else:
        _print_table(track, where, c)
