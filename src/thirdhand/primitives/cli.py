"""``thirdhand primitives``: learn motor primitives and primitive libraries.

``fit DEMO… -o OUT.json`` learns, per constraint symbol, one pose DMP
(quaternion DMP for the orientation) and one ProMP from the demonstrations'
segments (child in parent frame), and writes them as a task-file
``stages.primitives`` block. ``library TRACK… [--skills K] [--plot PNG]`` learns
skills and segmentation together and prints each track's parse.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer
from rich.console import Console

from thirdhand import options
from thirdhand.errors import FormatError, ThirdhandError
from thirdhand.fileops import atomic_output, check_output, write_bytes

app = typer.Typer(
    help="Motor primitives: DMPs and ProMPs per constraint, primitive libraries.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
out = Console(highlight=False, soft_wrap=True)
err = Console(stderr=True, highlight=False, soft_wrap=True)


@app.callback()
def _group() -> None:
    """Motor primitives: DMPs and ProMPs per constraint, primitive libraries."""


def _fail(exc: Exception) -> typer.Exit:
    err.print(f"thirdhand: error: {' '.join(str(exc).split())}", markup=False)
    return typer.Exit(1)


#: Most basis weights per dimension a DMP or ProMP may have.
MAX_WEIGHTS = 1000


@app.command()
def fit(
    demos: Annotated[list[Path], typer.Argument(help="Recordings with constraint labels.")],
    output: Annotated[Path, typer.Option("-o", "--output", help="JSON file to write.")],
    weights: Annotated[
        int | None, typer.Option(help="DMP weights per dimension (default: 15 per second).")
    ] = None,
    promp_weights: Annotated[int, typer.Option(help="ProMP weights per dimension.")] = 10,
    align: Annotated[str, typer.Option(help="Alignment before averaging: phase or dtw.")] = "phase",
    task: Annotated[
        Path | None,
        typer.Option(help="Also store the block as stages.primitives of this task file."),
    ] = None,
    force: Annotated[
        bool, typer.Option(help="Replace an existing OUTPUT (kept as a numbered .bak).")
    ] = False,
) -> None:
    """Learn one pose DMP and one ProMP per constraint symbol from the demonstrations.

    ``--task`` updates that task file in place (its previous version is kept as
    a numbered backup).
    """
    from thirdhand import io
    from thirdhand.primitives.stage import primitives_stage

    if align not in ("phase", "dtw"):
        raise _fail(ValueError(f"--align must be phase or dtw, got {align!r}"))
    try:
        check_output(output, force=force, inputs=[*demos, *([task] if task else [])])
        if weights is not None:
            options.integer("--weights", weights, low=2, high=MAX_WEIGHTS)
        options.integer("--promp-weights", promp_weights, low=2, high=MAX_WEIGHTS)
        if task is not None:
            check_output(task, force=True, inputs=demos, option="--task")
        loaded = [io.load(p) for p in demos]
        block = primitives_stage(
            loaded,
            n_weights=weights,
            promp_weights=promp_weights,
            align=align,  # type: ignore[arg-type]
        )
    except ThirdhandError as exc:
        raise _fail(exc) from None
    block["inputs"] = [str(p) for p in demos]
    try:
        write_bytes(output, json.dumps(block, indent=1).encode())
        if task is not None:
            from thirdhand.taskfile import load_task, save_task

            tf = load_task(task)
            tf.stages["primitives"] = block
            save_task(tf, task)
    except ThirdhandError as exc:
        raise _fail(exc) from None
    if task is not None:
        out.print(f"stored as stages.primitives in {task}")
    for key, c in block["constraints"].items():
        e = c["imitation_error"]
        out.print(
            f"{key:>8}  {c['parent']}->{c['child']} ({c['type']}), {c['n_examples']} examples, "
            f"{c['dmp']['position']['n_weights']} weights, imitation "
            f"{1000 * e['pos_m']:.2f} mm / {e['rot_deg']:.2f} deg"
        )
    out.print(f"wrote {output}")


def _read_tracks(path: Path, body: str | None) -> list[tuple[np.ndarray, np.ndarray]]:
    """Tracks from a LASA ``.mat`` (all demos), a CSV/NPY (time, values…) or a recording."""
    suffix = path.suffix.lower()
    if suffix == ".mat":
        from thirdhand.primitives.datasets import lasa_shapes

        return lasa_shapes(path.parent, path.stem)
    if suffix in (".csv", ".txt", ".npy"):
        try:
            arr = np.load(path) if suffix == ".npy" else np.loadtxt(path, delimiter=",", ndmin=2)
        except (OSError, ValueError) as exc:
            raise FormatError(path, f"expected numeric columns (time, values…): {exc}") from None
        if arr.ndim != 2 or arr.shape[1] < 2:
            raise FormatError(path, f"expected at least 2 columns (time, values…), got {arr.shape}")
        return [(arr[:, 0], arr[:, 1:])]
    from thirdhand import io

    demo = io.load(path)
    if body is None:
        raise FormatError(path, "a recording needs --body to choose the track")
    p = demo.pos(body)
    ok = np.isfinite(p).all(axis=1)
    return [(demo.t[ok], p[ok])]


@app.command()
def library(
    tracks: Annotated[list[Path], typer.Argument(help="LASA .mat, CSV/NPY (t, y…) or recordings.")],
    skills: Annotated[int, typer.Option(help="Number of skills K.")] = 3,
    threshold: Annotated[
        float | None,
        typer.Option(help="Speed threshold of candidate cuts, units/s (default 5% of peak)."),
    ] = None,
    window: Annotated[int, typer.Option(help="Moving-average window, samples.")] = 5,
    weights: Annotated[int, typer.Option(help="ProMP weights per dimension.")] = 8,
    body: Annotated[str | None, typer.Option(help="Body to use from a recording.")] = None,
    seed: Annotated[int, typer.Option(help="Seed of the EM restarts.")] = 0,
    plot: Annotated[Path | None, typer.Option(help="Write a figure of the skills here.")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print JSON.")] = False,
    force: Annotated[
        bool, typer.Option(help="Replace an existing --plot file (kept as a numbered .bak).")
    ] = False,
) -> None:
    """Learn skills and segmentation together; print the most likely parse of every track."""
    from thirdhand.primitives.library import PrimitiveLibrary
    from thirdhand.primitives.segment_features import smoothed_speed

    try:
        options.integer("--skills", skills, low=1, high=100)
        options.integer("--weights", weights, low=2, high=MAX_WEIGHTS)
        options.integer("--window", window, low=1, high=10000)
        options.seed(seed)
        if threshold is not None:
            options.finite("--threshold", threshold, low=0.0, low_open=True)
        if plot is not None:
            check_output(plot, force=force, inputs=tracks)
            if plot.suffix.lower() not in (".png", ".pdf", ".svg"):
                raise ThirdhandError(
                    f"--plot {plot}: a figure is written as .png, .pdf or .svg; "
                    f"got the extension {plot.suffix or '(none)'!r}"
                )
        data = [tr for p in tracks for tr in _read_tracks(p, body)]
        thr = threshold
        if thr is None:
            peaks = [smoothed_speed(y, float(np.median(np.diff(t))), window).max() for t, y in data]
            thr = 0.05 * float(np.median(peaks))
        lib = PrimitiveLibrary(
            skills, threshold=thr, window=window, n_weights=weights, seed=seed
        ).fit(data)
        parses = [lib.parse(t, y) for t, y in data]
    except ThirdhandError as exc:
        raise _fail(exc) from None
    result: dict[str, Any] = {
        "threshold": thr,
        "skill_weights": lib.mixture_.weights_.tolist(),
        "log_likelihood": lib.log_likelihood_,
        "tracks": [
            {
                "cuts_s": [float(t[c]) for c in p.cuts],
                "labels": p.labels.tolist(),
                "n_candidates": int(p.candidates.size),
            }
            for (t, _), p in zip(data, parses, strict=True)
        ],
    }
    if plot is not None:
        from thirdhand.primitives.plot import plot_library

        with atomic_output(plot) as tmp:
            plot_library(lib, tmp, tracks=data[:2])
        result["plot"] = str(plot)
    if as_json:
        out.print(json.dumps(result, indent=1))
        return
    out.print(
        f"{len(data)} tracks, threshold {thr:.4g}/s, skills π = "
        + ", ".join(f"{w:.2f}" for w in lib.mixture_.weights_)
    )
    for i, tr in enumerate(result["tracks"]):
        cuts = ", ".join(f"{c:.2f}" for c in tr["cuts_s"])
        out.print(
            f"track {i}: {len(tr['labels'])} segments (of {tr['n_candidates']} candidate cuts) "
            f"skills {tr['labels']} cuts [{cuts}] s"
        )
    if plot is not None:
        out.print(f"wrote {plot}")
