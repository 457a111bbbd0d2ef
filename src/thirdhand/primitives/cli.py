"""``thirdhand primitives``: learn motor primitives and primitive libraries.

``fit DEMO… -o OUT.json`` learns, per constraint symbol, one pose DMP
(quaternion DMP for the orientation) and one ProMP from the demonstrations'
segments (child in parent frame), and writes them as a task-file
``stages.primitives`` block. ``library TRACK… [--skills K] [--plot PNG]`` learns
skills and segmentation together and prints each track's parse.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer
from rich.console import Console

from thirdhand import jsontext, options
from thirdhand.config import ConfigOption, load_settings
from thirdhand.errors import FormatError, ThirdhandError
from thirdhand.fileops import atomic_output, check_output, check_outputs, write_bytes

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


@app.command()
def fit(
    demos: Annotated[list[Path], typer.Argument(help="Recordings with constraint labels.")],
    output: Annotated[Path, typer.Option("-o", "--output", help="JSON file to write.")],
    task: Annotated[
        Path | None,
        typer.Option(help="Also store the block as stages.primitives of this task file."),
    ] = None,
    force: Annotated[
        bool, typer.Option(help="Replace an existing OUTPUT (kept as a numbered .bak).")
    ] = False,
    config: ConfigOption = None,
) -> None:
    """Learn one pose DMP and one ProMP per constraint symbol from the demonstrations.

    ``--task`` updates that task file in place (its previous version is kept as
    a numbered backup). Settings (``[primitives.fit]`` of ``--config``): ``weights``,
    ``promp_weights``, ``align``.
    """
    from thirdhand import io
    from thirdhand.primitives.settings import FitSettings
    from thirdhand.primitives.stage import primitives_stage

    try:
        cfg = load_settings(config, "primitives.fit", FitSettings)
        inputs = [*demos, *([task] if task else []), *([config] if config else [])]
        check_output(output, force=force, inputs=inputs)
        if task is not None:
            check_output(task, force=True, inputs=demos, option="--task")
        loaded = [io.load(p) for p in demos]
        block = primitives_stage(
            loaded,
            n_weights=cfg.weights,
            promp_weights=cfg.promp_weights,
            align=cfg.align,
        )
    except ThirdhandError as exc:
        raise _fail(exc) from None
    doc = block.model_dump(mode="json", by_alias=True)
    doc["inputs"] = [str(p) for p in demos]
    try:
        write_bytes(output, jsontext.dumps(doc, what=str(output), indent=1).encode())
        if task is not None:
            from thirdhand.taskfile import load_task, save_task

            tf = load_task(task)
            tf.stages.primitives = block
            save_task(tf, task)
    except ThirdhandError as exc:
        raise _fail(exc) from None
    if task is not None:
        out.print(f"stored as stages.primitives in {task}")
    for key, c in block.constraints.items():
        e = c.imitation_error
        out.print(
            f"{key:>8}  {c.parent}->{c.child} ({c.type}), {c.n_examples} examples, "
            f"{c.dmp.position.n_weights} weights, imitation "
            f"{1000 * e.pos_m:.2f} mm / {e.rot_deg:.2f} deg"
        )
    out.print(f"wrote {output}")


def _table_track(path: Path, arr: np.ndarray) -> Any:
    """A pose track from a table ``t x y z [qx qy qz qw]`` (fewer values: zeros pad x y z)."""
    from thirdhand.primitives.pose_channels import PoseTrack

    if arr.ndim != 2 or arr.shape[1] not in (2, 3, 4, 8):
        raise FormatError(
            path, f"expected columns t x y z [qx qy qz qw] (4 or 8), got shape {arr.shape}"
        )
    bad = np.flatnonzero(~np.isfinite(arr).all(axis=1))
    if bad.size:
        raise FormatError(
            path,
            f"row {int(bad[0]) + 1} has NaN or infinite values ({bad.size} such rows); "
            "remove or interpolate them",
        )
    pos = np.zeros((arr.shape[0], 3))
    pos[:, : min(arr.shape[1] - 1, 3)] = arr[:, 1:4]
    quat = arr[:, 4:8] if arr.shape[1] == 8 else None
    if quat is not None:
        from thirdhand.demonstration import MAX_QUAT_NORM_ERROR

        norm = np.linalg.norm(quat, axis=1, keepdims=True)
        off = np.abs(norm[:, 0] - 1.0) > MAX_QUAT_NORM_ERROR
        if off.any():
            k = int(np.argmax(off))
            raise FormatError(
                path, f"row {k + 1}: quaternion of norm {norm[k, 0]:.6g}, expected a unit one"
            )
        quat = quat / norm
    return PoseTrack(arr[:, 0], pos, quat, name=str(path))


def _read_tracks(path: Path, body: str | None) -> list[Any]:
    """Pose tracks from a CSV/NPY table, a labelled or LASA ``.mat``, or a recording (--body)."""
    from thirdhand.primitives.pose_channels import PoseTrack

    suffix = path.suffix.lower()
    if suffix == ".mat":
        from thirdhand.io.figueroa import read_labelled_mat

        try:
            streams = read_labelled_mat(path)
        except FormatError:
            from thirdhand.datasets.primitive_shapes import lasa_shapes

            shapes = lasa_shapes(path.parent, path.stem)
            return [_table_track(path, np.column_stack([t, y / 1000.0])) for t, y in shapes]
        return [
            PoseTrack(
                s.t,
                s.arms[0].pos,
                s.arms[0].quat,
                s.arms[0].force,
                s.arms[0].torque,
                tuple(a.pos for a in s.arms[1:]),
                name=s.name,
            )
            for s in streams
        ]
    if suffix in (".csv", ".txt", ".npy"):
        import io as _io

        from thirdhand.readlimits import MAX_RECORDING_BYTES, read_input

        raw = read_input(path, what="track file", limit=MAX_RECORDING_BYTES)
        try:
            arr = (
                np.load(_io.BytesIO(raw), allow_pickle=False)
                if suffix == ".npy"
                else np.loadtxt(_io.StringIO(raw.decode("utf-8")), delimiter=",", ndmin=2)
            )
        except (OSError, ValueError) as exc:
            raise FormatError(
                path, f"expected numeric columns t x y z [qx qy qz qw]: {exc}"
            ) from None
        return [_table_track(path, np.asarray(arr, dtype=np.float64))]
    from thirdhand import io

    demo = io.load(path)
    if body is None:
        raise FormatError(path, "a recording needs --body to choose the track")
    if body not in demo.body_names:
        raise FormatError(path, f"no body {body!r}; it has {', '.join(demo.body_names)}")
    ok = demo.valid(body) & np.isfinite(demo.pos(body)).all(axis=1)
    others = tuple(
        np.where(demo.valid(b)[:, None], demo.pos(b), np.nan)[ok]
        for b in demo.body_names
        if b != body
    )
    return [
        PoseTrack(
            demo.t[ok],
            demo.pos(body)[ok],
            demo.quat(body)[ok],
            others=others,
            name=f"{path}:{body}",
        )
    ]


@app.command()
def library(
    tracks: Annotated[
        list[Path],
        typer.Argument(help="CSV/NPY tracks t x y z [qx qy qz qw], labelled .mat, or recordings."),
    ],
    skills: Annotated[
        int | None,
        typer.Option(help="Number of skills K, entry and exit included (default: by BIC, 2-6)."),
    ] = None,
    parser: Annotated[
        str, typer.Option(help="hsmm (the skill library) or cuts (the seed's parser, to compare).")
    ] = "hsmm",
    lib_in: Annotated[
        Path | None,
        typer.Option("--library", help="Parse with this saved library instead of fitting one."),
    ] = None,
    output: Annotated[
        Path | None, typer.Option("-o", "--output", help="Save the fitted library (JSON) here.")
    ] = None,
    body: Annotated[str | None, typer.Option(help="Body to use from a recording.")] = None,
    seed: Annotated[int, typer.Option(help="Seed of the restarts.")] = 0,
    plot: Annotated[Path | None, typer.Option(help="Write a figure of the parses here.")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print JSON.")] = False,
    force: Annotated[
        bool, typer.Option(help="Replace an existing -o or --plot file (kept as a numbered .bak).")
    ] = False,
) -> None:
    """Learn a library of skills from the tracks (or load one); print every track's parse.

    Channels from poses alone (speed, angular rate, height above the work, the
    distance to other tracked bodies), forces and torques when a file has them;
    unchanged by where in the room the task was done.
    """
    from thirdhand.fileops import write_text
    from thirdhand.primitives.pose_channels import check_track_set
    from thirdhand.primitives.skill_library import (
        SkillLibrary,
        SkillParserOptions,
        cuts_parses,
        read_skill_library,
    )

    try:
        if skills is not None:
            options.integer("--skills", skills, low=1, high=100)
        if parser not in ("hsmm", "cuts"):
            raise ThirdhandError(f"--parser must be hsmm or cuts, got {parser!r}")
        options.seed(seed)
        if parser == "cuts" and (lib_in is not None or output is not None):
            raise ThirdhandError("--library and -o save and load the hsmm parser's library only")
        if lib_in is not None and skills is not None:
            raise ThirdhandError("--skills is fixed by the --library given; leave it out")
        check_outputs([("-o", output), ("--plot", plot)], force=force, inputs=[*tracks, lib_in])
        if plot is not None and plot.suffix.lower() not in (".png", ".pdf", ".svg"):
            raise ThirdhandError(
                f"--plot {plot}: a figure is written as .png, .pdf or .svg; "
                f"got the extension {plot.suffix or '(none)'!r}"
            )
        for i, p in enumerate(tracks):
            twice = [q for q in tracks[:i] if q.resolve() == p.resolve()]
            if twice:
                raise ThirdhandError(f"{p}: given twice (as {twice[0]}); give each track once")
        data = [tr for p in tracks for tr in _read_tracks(p, body)]
        check_track_set(data)
        opts = SkillParserOptions(parser=parser, n_skills=skills, seed=seed)  # type: ignore[arg-type]
        result: dict[str, Any] = {"parser": parser}
        if parser == "cuts":
            seed_lib, parses = cuts_parses(data, opts)
            result.update(
                threshold=seed_lib.threshold,
                n_skills=seed_lib.n_skills,
                skill_weights=seed_lib.mixture_.weights_.tolist(),
                log_likelihood=seed_lib.log_likelihood_,
            )
            n_cand = [int(c.size) for c in seed_lib.candidates_]
        else:
            if lib_in is not None:
                lib = read_skill_library(lib_in)
            else:
                lib = SkillLibrary(opts).fit(data)
            parses = [lib.parse(tr) for tr in data]
            result.update(
                n_skills=lib.n_skills_,
                ends=bool(lib.model_.ends_),
                channels=list(lib.channels_),
                skill_weights=lib.skill_fractions(parses),
                log_likelihood=float(sum(p.score for p in parses)),
            )
            if lib.bic_:
                result["bic"] = {str(k): v for k, v in lib.bic_.items()}
            if lib_in is not None:
                result["library"] = str(lib_in)
            n_cand = [
                max(int(np.floor((tr.t[-1] - tr.t[0]) * lib.options.rate_hz)), 0) for tr in data
            ]
            if output is not None:
                write_text(output, jsontext.dumps(lib.to_dict(), what=str(output), indent=1))
                result["saved"] = str(output)
        result["tracks"] = [
            {
                "name": tr.name,
                "cuts_s": p.cuts_s.tolist(),
                "labels": p.skills.tolist(),
                "n_candidates": nc,
            }
            for tr, p, nc in zip(data, parses, n_cand, strict=True)
        ]
        if plot is not None:
            from thirdhand.primitives.plot import plot_skill_parses

            with atomic_output(plot) as tmp:
                plot_skill_parses(data, parses, tmp)
            result["plot"] = str(plot)
    except ThirdhandError as exc:
        raise _fail(exc) from None
    if as_json:
        out.print(jsontext.dumps(result, what="--json", indent=1))
        return
    out.print(
        f"{len(data)} tracks, parser {parser}, {result['n_skills']} skills, share of samples "
        + ", ".join(f"{w:.2f}" for w in result["skill_weights"])
        + (" (entry and exit first and last)" if result.get("ends") else "")
    )
    for i, tr in enumerate(result["tracks"]):
        cuts = ", ".join(f"{c:.2f}" for c in tr["cuts_s"])
        out.print(
            f"track {i} {tr['name']}: {len(tr['labels'])} runs, skills {tr['labels']} "
            f"cuts [{cuts}] s"
        )
    if output is not None and "saved" in result:
        out.print(f"wrote {output}")
    if plot is not None:
        out.print(f"wrote {plot}")
