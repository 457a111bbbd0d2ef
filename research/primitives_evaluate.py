"""``python -m research primitives evaluate``: parsers scored against human phase labels.

The evaluation recipe behind ``research/notes/primitives.md``'s tables (leave one recording
out, K by one standard error, semi-Markov models with entry/exit, level
channels...). The product's parser is ``thirdhand primitives library``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console

from thirdhand import options
from thirdhand.errors import ThirdhandError
from thirdhand.fileops import check_output

app = typer.Typer(
    help="Primitive-library parsers against human phase labels.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
out = Console(highlight=False, soft_wrap=True)


def _fail(exc: Exception) -> typer.Exit:
    """Print one ``research: error:`` line; the exit to raise."""
    import sys

    sys.stderr.write(f"research: error: {' '.join(str(exc).split())}\n")
    return typer.Exit(1)


def _names(value: str) -> tuple[str, ...]:
    return tuple(v.strip() for v in value.split(",") if v.strip())


@app.command()
def evaluate(
    files: Annotated[
        list[Path], typer.Argument(help="Labelled .mat files (proc_data/True_states or Data_*).")
    ],
    skills: Annotated[
        int | None,
        typer.Option(help="Number of skills K (default: selected over 2-6, see --select)."),
    ] = None,
    select: Annotated[
        str,
        typer.Option(
            help="How K is selected without --skills: onese (the smallest K within one "
            "standard error of the best cross-validated log-likelihood on the training "
            "recordings), heldout (the best) or bic; the tables are printed."
        ),
    ] = "onese",
    model: Annotated[
        str,
        typer.Option(
            help="library (ProMP skills over candidate segments) or hsmm (hidden "
            "semi-Markov model over the level channels, fitted without labels)."
        ),
    ] = "library",
    label_trained: Annotated[
        bool,
        typer.Option(
            help="Supervised: fit an HSMM on the other recordings' human labels and parse "
            "the held-out one with it (not an unsupervised figure)."
        ),
    ] = False,
    zero_ft: Annotated[
        bool,
        typer.Option(help="Subtract each arm's force/torque over the first 0.5 s (sensor offset)."),
    ] = False,
    ends: Annotated[
        bool,
        typer.Option(
            help="HSMM: an entry state only at the start of a recording and an exit state only "
            "at its end (approach, withdrawal) around the K states of the work."
        ),
    ] = False,
    adapt: Annotated[
        bool,
        typer.Option(
            help="HSMM: after fitting on the other recordings, adapt the model to the one "
            "parsed by hard EM on its samples (never its labels); transductive, report apart."
        ),
    ] = False,
    normalise: Annotated[
        str,
        typer.Option(
            help="Level channels per recording: none, scale (divided by the recording's "
            "standard deviation) or zscore (also centred on its median)."
        ),
    ] = "none",
    shape: Annotated[
        str, typer.Option(help="Shape channels per arm: pos, rot, force, torque (comma list).")
    ] = "pos",
    levels: Annotated[
        str,
        typer.Option(
            help="Level channels: force, torque, speed, angular, velocity, forcevec, "
            "torquevec, bodyangular, logforce, logtorque, logspeed, logangular per arm; "
            "relpos, objpos, objvel, holdangular, objcyl, objcylvel per pair of arms ('' for none)."
        ),
    ] = "force",
    arms: Annotated[
        str | None, typer.Option(help="Arms to use, e.g. 0 or 0,1 (default all).")
    ] = None,
    tolerance: Annotated[float, typer.Option(help="Boundary tolerance, seconds.")] = 1.0,
    grid: Annotated[
        float, typer.Option(help="Extra candidate cut every GRID seconds (0: speed minima only).")
    ] = 0.5,
    subsample: Annotated[int, typer.Option(help="Keep every n-th sample for the parse.")] = 5,
    threshold: Annotated[
        float | None, typer.Option(help="Speed threshold of the cuts (default 5% of peak).")
    ] = None,
    trim_rest: Annotated[
        bool, typer.Option(help="Leave rest at the ends of a recording out of the skills.")
    ] = False,
    phases: Annotated[
        int | None,
        typer.Option(help="Group runs of skills into this many phases (default: no grouping)."),
    ] = None,
    switch_penalty: Annotated[
        float, typer.Option(help="Cost of a change of skill in the parse, nats.")
    ] = 0.0,
    rate: Annotated[
        float | None, typer.Option(help="Sampling rate of files without dt, Hz (default 100).")
    ] = None,
    seed: Annotated[int, typer.Option(help="Seed of the EM restarts.")] = 0,
    json_out: Annotated[Path | None, typer.Option("--json", help="Write the results here.")] = None,
    force: Annotated[
        bool, typer.Option(help="Replace an existing --json file (kept as a numbered .bak).")
    ] = False,
) -> None:
    """Parse each labelled recording with a library fitted on the others; score it.

    Frame accuracy under the best skill-to-label map (Hungarian), boundary
    precision/recall/F1 within --tolerance, per recording and per file.
    """
    from research.primitive_labels import (
        MODELS,
        NORMALISATIONS,
        SELECTIONS,
        ParserConfig,
        evaluate_streams,
    )
    from thirdhand.fileops import write_text
    from thirdhand.io.figueroa import read_labelled_mat

    try:
        if skills is not None:
            options.integer("--skills", skills, low=1, high=100)
        if select not in SELECTIONS:
            raise ThirdhandError(f"--select must be onese, heldout or bic, got {select!r}")
        if model not in MODELS:
            raise ThirdhandError(f"--model must be library or hsmm, got {model!r}")
        if normalise not in NORMALISATIONS:
            raise ThirdhandError(f"--normalise must be none, scale or zscore, got {normalise!r}")
        if ends and (model != "hsmm" or label_trained):
            raise ThirdhandError(
                "--ends is an option of the unsupervised HSMM "
                "(--model hsmm without --label-trained)"
            )
        if adapt and model != "hsmm" and not label_trained:
            raise ThirdhandError(
                "--adapt is an option of the HSMM (--model hsmm or --label-trained)"
            )
        options.finite("--tolerance", tolerance, low=0.0)
        options.finite("--grid", grid, low=0.0)
        options.integer("--subsample", subsample, low=1, high=1000)
        if phases is not None:
            options.integer("--phases", phases, low=1, high=100)
        options.finite("--switch-penalty", switch_penalty, low=0.0)
        options.seed(seed)
        if threshold is not None:
            options.finite("--threshold", threshold, low=0.0, low_open=True)
        if rate is not None:
            options.finite("--rate", rate, low=0.0, low_open=True)
        arm_ids: tuple[int, ...] | None = None
        if arms is not None:
            try:
                arm_ids = tuple(int(a) for a in _names(arms))
            except ValueError:
                raise ThirdhandError(
                    f"--arms must be comma-separated integers, got {arms!r}"
                ) from None
        if json_out is not None:
            check_output(json_out, force=force, inputs=files)
        cfg = ParserConfig(
            shape=_names(shape),
            levels=_names(levels),
            arms=arm_ids,
            n_skills=skills,
            select=select,
            subsample=subsample,
            grid=grid or None,
            threshold=threshold,
            trim_rest=trim_rest,
            n_phases=phases,
            switch_penalty=switch_penalty,
            seed=seed,
            model="hsmm" if label_trained else model,
            label_trained=label_trained,
            zero_ft=zero_ft,
            ends=ends,
            normalise=normalise,
            adapt=adapt,
            k_range=(1, 2, 3, 4, 5, 6) if ends else (2, 3, 4, 5, 6),
        )
        results = {}
        for f in files:
            streams = read_labelled_mat(f, rate_hz=rate)
            results[str(f)] = (streams, evaluate_streams(streams, cfg, tolerance=tolerance))
    except ThirdhandError as exc:
        raise _fail(exc) from None
    doc: dict[str, Any] = {
        "format": "thirdhand.primitives-evaluation/1",
        "tolerance_s": tolerance,
        "config": {k: v for k, v in cfg.__dict__.items()},
        "files": [],
    }
    for fname, (streams, res) in results.items():
        if cfg.label_trained:
            named = sum((r.named_accuracy or 0.0) * r.n_samples for r in res.streams) / sum(
                r.n_samples for r in res.streams
            )
            out.print(
                f"{fname}: LABEL-TRAINED (supervised) HSMM, each recording parsed by a model "
                f"fitted on the others' human labels; frame accuracy with labels as named "
                f"{named:.3f}"
            )
        if cfg.adapt:
            out.print(
                f"{fname}: ADAPTED (transductive): each recording parsed by a model fitted on "
                "the others, then adapted to it by hard EM on its samples (not its labels)"
            )
        out.print(
            f"{fname}: {len(streams)} recordings, K = "
            f"{'/'.join(str(r.n_skills) for r in res.streams)}, frame accuracy "
            f"{res.accuracy:.3f} (one map for all: {res.global_accuracy:.3f}), "
            f"boundaries P {res.boundaries.precision:.2f} "
            f"R {res.boundaries.recall:.2f} F1 {res.boundaries.f1:.2f} "
            f"({res.boundaries.n_matched}/{res.boundaries.n_true} true within {tolerance:g} s, "
            f"{res.boundaries.n_pred} predicted); map skill->label {res.mapping}"
        )
        out.print(
            f"  {'recording':<30} {'samples':>7} {'acc':>6} {'P':>5} {'R':>5} {'F1':>5} "
            f"{'true':>4} {'pred':>4} {'cands':>5} {'phases':>6} {'fit s':>6}"
        )
        for r in res.streams:
            b = r.boundaries
            note = " (in-sample)" if r.in_sample else ""
            out.print(
                f"  {r.name[:30]:<30} {r.n_samples:>7} {r.accuracy:>6.3f} {b.precision:>5.2f} "
                f"{b.recall:>5.2f} {b.f1:>5.2f} {b.n_true:>4} {b.n_pred:>4} {r.n_candidates:>5} "
                f"{r.n_phases:>6} {r.fit_s:>6.1f}{note}"
            )
        for r in res.streams:
            if r.selection is None:
                continue
            sel = r.selection
            out.print(
                f"  without {r.name[:30]}: K = {sel.chosen} by {select}; BIC "
                + (", ".join(f"{k}: {v:.0f}" for k, v in sel.bic.items()) or "-")
                + "; held-out log-lik per obs "
                + ", ".join(f"{k}: {v:.3f}" for k, v in sel.heldout.items())
            )
        doc["files"].append(
            {
                "file": fname,
                "label_trained": cfg.label_trained,
                "accuracy": res.accuracy,
                "global_accuracy": res.global_accuracy,
                "boundaries": _bscore(res.boundaries),
                "raw_boundaries": _bscore(res.raw_boundaries),
                "mapping": {str(k): v for k, v in res.mapping.items()},
                "bic": {str(k): v for k, v in res.bic.items()},
                "heldout_loglik_per_obs": {str(k): v for k, v in res.heldout.items()},
                "rate_assumed": any(s.rate_assumed for s in streams),
                "recordings": [
                    {
                        "name": r.name,
                        "samples": r.n_samples,
                        "accuracy": r.accuracy,
                        "global_accuracy": r.global_accuracy,
                        "boundaries": _bscore(r.boundaries),
                        "true_boundaries_s": s.boundaries.tolist(),
                        "n_candidates": r.n_candidates,
                        "n_segments": r.n_segments,
                        "n_phases": r.n_phases,
                        "n_skills": r.n_skills,
                        "in_sample": r.in_sample,
                        "fit_s": r.fit_s,
                        "named_accuracy": r.named_accuracy,
                        "k_selection": None
                        if r.selection is None
                        else {
                            "by": select,
                            "chosen": r.selection.chosen,
                            "bic": {str(k): v for k, v in r.selection.bic.items()},
                            "heldout_loglik_per_obs": {
                                str(k): v for k, v in r.selection.heldout.items()
                            },
                            "heldout_folds": {
                                str(k): [[ll, n] for ll, n in v]
                                for k, v in r.selection.folds.items()
                            },
                        },
                    }
                    for r, s in zip(res.streams, streams, strict=True)
                ],
            }
        )
    if json_out is not None:
        try:
            write_text(json_out, json.dumps(doc, indent=1))
        except ThirdhandError as exc:
            raise _fail(exc) from None
        out.print(f"wrote {json_out}")


def _bscore(b: Any) -> dict[str, Any]:
    return {
        "precision": b.precision,
        "recall": b.recall,
        "f1": b.f1,
        "n_true": b.n_true,
        "n_pred": b.n_pred,
        "n_matched": b.n_matched,
        "tolerance_s": b.tolerance,
    }
