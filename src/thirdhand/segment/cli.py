"""``thirdhand segment``: segment, train and evaluate interaction phases.

``thirdhand segment DEMO [--model M] [--json OUT] [--plot PNG]`` segments a
recording (the default command); ``thirdhand segment train DEMOS… -o MODEL.json``
trains a model; ``thirdhand segment evaluate DEMOS…`` runs the report's Table I
protocol (train on the left hand's pairs, test on the right hand's; or leave one
object out, or split in time, within one hand's pairs); ``thirdhand segment
calibrate DEMOS… -o MODEL.json`` refits a model's operating point to a user's
rig from a few labelled intervals (:mod:`thirdhand.segment.calibrate`);
``thirdhand segment batch RECORDINGS|FOLDERS… -o FOLDER [--jobs N] [--scheduler A]``
segments many recordings as independent units (:mod:`thirdhand.segment.batch`).

Label files: ``--labels`` (one per recording); a 3rdHand folder holding an
``ann_kvg.kvg`` uses it when ``--labels`` is not given (train, evaluate, calibrate).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.table import Table
from typer.core import TyperGroup

from thirdhand import jsontext
from thirdhand.config import ConfigOption, load_settings
from thirdhand.errors import ThirdhandError
from thirdhand.fileops import (
    atomic_output,
    check_distinct_inputs,
    check_output,
    check_outputs,
    write_text,
)

DEFAULT_COMMAND = "run"


class DefaultCommandGroup(TyperGroup):
    """A group that runs :data:`DEFAULT_COMMAND` when the first argument is no subcommand."""

    def parse_args(self, ctx: Any, args: list[str]) -> list[str]:
        if args and args[0] not in self.commands and args[0] not in ("--help", "-h"):
            args = [DEFAULT_COMMAND, *args]
        return super().parse_args(ctx, args)


app = typer.Typer(
    cls=DefaultCommandGroup,
    help="Interaction phases per body pair (linear-chain CRF). "
    "`thirdhand segment DEMO` segments a recording.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
out = Console(highlight=False, soft_wrap=True)


def _load(path: Path, labels: Path | None = None) -> Any:
    from thirdhand import io

    demo = io.load(path)
    if labels is None:
        return demo
    return demo.replace(labels=read_label_file(labels, demo))


def read_label_file(path: Path, demo: Any) -> Any:
    """Labels of ``demo`` from a kvg annotation file (frames) or an ELAN file (seconds)."""
    suffix = path.suffix.lower()
    if suffix == ".kvg":
        from thirdhand.io import kvg

        return kvg.read_annotations(path, frame_times=demo.t, bodies=demo.bodies)
    if suffix in (".eaf", ".txt"):
        from thirdhand.io import elan

        reader = elan.read_eaf if suffix == ".eaf" else elan.read_tab
        return reader(path, offset=float(demo.t[0]), bodies=demo.bodies)
    raise ThirdhandError(
        f"{path}: unknown label file type {suffix!r}; expected .kvg, .eaf or ELAN .txt"
    )


def _model(path: Path | None) -> Any:
    from thirdhand.segment.model import resolve_model

    return resolve_model(path)


@app.command(DEFAULT_COMMAND, hidden=True)
def run(
    demo: Annotated[Path, typer.Argument(help="A recording of any supported format.")],
    model: Annotated[
        Path | None,
        typer.Option("--model", "-m", help="Model JSON or built-in: default, synthetic."),
    ] = None,
    json_out: Annotated[Path | None, typer.Option("--json", help="Write phases as JSON.")] = None,
    plot: Annotated[Path | None, typer.Option("--plot", help="Write a PNG (needs labels).")] = None,
    force: Annotated[
        bool, typer.Option(help="Replace existing outputs (kept as numbered .bak).")
    ] = False,
) -> None:
    """Segment a recording into interaction phases per body pair and per hand."""
    from thirdhand.segment.pipeline import scores_by_kind, segment_demonstration

    inputs = [demo] + ([model] if model is not None else [])
    check_outputs([("--json", json_out), ("--plot", plot)], force=force, inputs=inputs)
    if plot is not None:
        check_plot_suffix(plot)
    d = _load(demo)
    from thirdhand import options

    options.body_pairs(len(d), str(demo))
    result = segment_demonstration(d, _model(model))
    out.print(f"{demo}: {len(result.pairs)} pairs, {len(result.times)} latent steps")
    for p in result.pairs:
        if p.intervals:
            spans = ", ".join(f"{s:.2f}–{e:.2f}" for s, e in p.intervals)
            out.print(f"  {p.a} · {p.b}: {spans} s")
    for h in result.hands:
        if h.intervals:
            spans = ", ".join(f"{s:.2f}–{e:.2f}" for s, e in h.intervals)
            out.print(f"  hand {h.hand} · {h.object}: {spans} s")
    for kind, s in scores_by_kind(result).items():
        out.print(f"  vs labels, {kind}: frame F1 {s['frame_f1']:.3f}, IoU {s['interval_iou']:.3f}")
    if json_out is not None:
        write_text(json_out, jsontext.dumps(result.to_dict(), what=str(json_out)))
        out.print(f"wrote {json_out}")
    if plot is not None:
        from thirdhand.segment.plot import plot_phases

        with atomic_output(plot) as tmp:
            plot_phases(result, tmp, only_labelled=True)
        out.print(f"wrote {plot}")


#: Figure formats every plotting option writes (matplotlib's, chosen by extension).
PLOT_SUFFIXES = (".png", ".pdf", ".svg")


def check_plot_suffix(path: Path) -> None:
    """Raise unless ``path`` ends in a figure extension (``.png``, ``.pdf``, ``.svg``)."""
    if path.suffix.lower() not in PLOT_SUFFIXES:
        raise ThirdhandError(
            f"{path}: a figure is written as {', '.join(PLOT_SUFFIXES)}; "
            f"got the extension {path.suffix or '(none)'!r}"
        )


def _with_labels(demos: list[Path], labels: list[Path] | None) -> list[Any]:
    if labels and len(labels) != len(demos):
        raise ThirdhandError(
            f"--labels given {len(labels)} time(s) for {len(demos)} demonstration(s); "
            "give one label file per demonstration, in the same order"
        )
    out = []
    for i, p in enumerate(demos):
        lab = labels[i] if labels else None
        if lab is None and p.is_dir() and (p / "ann_kvg.kvg").is_file():
            lab = p / "ann_kvg.kvg"
        d = _load(p, lab)
        if not d.labels.interactions:
            raise ThirdhandError(f"{p}: no interaction labels; pass a label file with --labels")
        out.append(d)
    return out


@app.command()
def train(
    demos: Annotated[list[Path], typer.Argument(help="Labelled recordings.")],
    output: Annotated[Path, typer.Option("-o", "--output", help="Model JSON to write.")],
    labels: Annotated[
        list[Path] | None,
        typer.Option("--labels", help="Label file (.kvg, .eaf, ELAN .txt), one per demo."),
    ] = None,
    force: Annotated[
        bool, typer.Option(help="Replace an existing model (kept as a numbered .bak).")
    ] = False,
    config: ConfigOption = None,
) -> None:
    """Train a segmentation model on labelled recordings.

    Settings (``[segment.train]`` of ``--config``): ``l2``, ``latent_rate``, ``window``.
    """
    from thirdhand.segment.design import FeatureConfig
    from thirdhand.segment.settings import TrainSettings
    from thirdhand.segment.training import fit_model

    check_distinct_inputs(demos, what="recording")
    settings = load_settings(config, "segment.train", TrainSettings)
    check_output(
        output, force=force, inputs=[*demos, *(labels or []), *([config] if config else [])]
    )
    ds = _with_labels(demos, labels)
    cfg = FeatureConfig(latent_rate=settings.latent_rate, window=settings.window)
    model = fit_model(ds, cfg, l2=settings.l2, training={"demonstrations": [str(p) for p in demos]})
    model.save(output)
    info = model.training
    out.print(
        f"wrote {output}: {info['sequences']} pair sequences, {info['latent_variables']} latent "
        f"variables, train NLL {info['train_nll_per_variable']:.4f} per variable"
    )


@app.command()
def evaluate(
    demos: Annotated[list[Path], typer.Argument(help="Labelled recordings.")],
    labels: Annotated[
        list[Path] | None,
        typer.Option("--labels", help="Label file (.kvg, .eaf, ELAN .txt), one per demo."),
    ] = None,
    split: Annotated[
        str,
        typer.Option(
            help="hand: train on one hand's pairs, test on the other's; object: leave one "
            "object out within one hand's pairs; time: first vs second half; auto: hand "
            "when both hands are labelled, else object."
        ),
    ] = "auto",
    json_out: Annotated[
        Path | None, typer.Option("--json", help="Write the table as JSON.")
    ] = None,
    force: Annotated[
        bool, typer.Option(help="Replace an existing --json file (kept as a numbered .bak).")
    ] = False,
    config: ConfigOption = None,
) -> None:
    """Table I protocol: logistic regression vs CRF, trained on one hand, tested on the other.

    Settings (``[segment.evaluate]`` of ``--config``): ``l2``, ``latent_rate``,
    ``window``, ``train_hand``, ``test_hand``.
    """
    from thirdhand.segment.design import FeatureConfig
    from thirdhand.segment.settings import EvaluateSettings
    from thirdhand.segment.training import (
        labelled_sequences,
        split_folds,
        table_one,
        table_one_folds,
    )

    settings = load_settings(config, "segment.evaluate", EvaluateSettings)
    if json_out is not None:
        check_output(
            json_out, force=force, inputs=[*demos, *(labels or []), *([config] if config else [])]
        )
    if split not in ("auto", "hand", "object", "time"):
        raise ThirdhandError(f"--split: expected auto, hand, object or time, got {split!r}")
    ds = _with_labels(demos, labels)
    # The sides (left, right) whose hands carry labels.
    hands = {
        d.info(body).hand
        for d in ds
        for i in d.labels.interactions
        for body in (i.a, i.b)
        if body in d and d.info(body).hand
    }
    train_hand: str = settings.train_hand
    if train_hand == "auto":
        train_hand = "left" if "left" in hands or not hands else "right"
    test_hand: str = settings.test_hand
    if test_hand == "auto":
        test_hand = "right" if train_hand == "left" else "left"
    if split == "auto":
        split = "hand" if {train_hand, test_hand} <= hands else "object"
    l2 = settings.l2
    cfg = FeatureConfig(latent_rate=settings.latent_rate, window=settings.window)
    if split == "hand":
        tab = table_one(ds, cfg, l2=l2, train_hand=train_hand, test_hand=test_hand)
        title = f"train: {train_hand} hand pairs, test: {test_hand} hand pairs"
    else:
        folds = split_folds(labelled_sequences(ds, cfg, hand=train_hand), split)
        tab = table_one_folds(folds, l2=l2)
        how = "leave one object out" if split == "object" else "split in time"
        title = f"{train_hand} hand pairs, {how} ({len(folds)} folds; test pooled)"
    table = Table(
        "model",
        "split",
        "NLL",
        "NLL / latent var.",
        "frame F1",
        "interval IoU",
        "boundary err. (s)",
        title=title,
    )
    for name, label in (("logistic", "logistic regression"), ("crf", "CRF")):
        for split in ("train", "test"):
            r = tab[name][split]
            table.add_row(
                label,
                f"{split} ({int(r['latent_variables'])})",
                f"{r['nll']:.1f}",
                f"{r['nll_per_variable']:.4f}",
                f"{r['frame_f1']:.3f}",
                f"{r['interval_iou']:.3f}",
                f"{r['boundary_error_s']:.3f}",
            )
    out.print(table)
    out.print(
        "report (its toolbox recording): logistic 12377.2 (0.4391) train / 16371.5 (0.5809) "
        "test; CRF 2464.9 (0.0875) / 1912.8 (0.0679)"
    )
    if json_out is not None:
        write_text(json_out, jsontext.dumps(tab, what=str(json_out), indent=1))


@app.command()
def calibrate(
    demos: Annotated[list[Path], typer.Argument(help="Your labelled recordings.")],
    output: Annotated[Path, typer.Option("-o", "--output", help="Calibrated model JSON.")],
    labels: Annotated[
        list[Path] | None,
        typer.Option("--labels", help="Label file (.kvg, .eaf, ELAN .txt), one per demo."),
    ] = None,
    model: Annotated[
        Path | None, typer.Option("--model", "-m", help="Model JSON or built-in to calibrate.")
    ] = None,
    span: Annotated[
        tuple[float, float] | None,
        typer.Option(
            help="Use only this part of each recording: START END, seconds from its start."
        ),
    ] = None,
    force: Annotated[
        bool, typer.Option(help="Replace an existing model (kept as a numbered .bak).")
    ] = False,
    config: ConfigOption = None,
) -> None:
    """Refit a model's score offset, scale and transitions to your rig from labelled intervals.

    Label every interaction of the pairs you name (within --span when given):
    the other steps of those pairs are taken as "not interacting". Settings
    (``[segment.calibrate]`` of ``--config``): ``prior``, ``keep_scale``, ``keep_transitions``.
    """
    from thirdhand.segment.calibrate import calibrate as run_calibration
    from thirdhand.segment.settings import CalibrateSettings

    settings = load_settings(config, "segment.calibrate", CalibrateSettings)
    inputs = [*demos, *(labels or []), *([config] if config else [])]
    if model is not None and model.exists():
        inputs.append(model)
    check_output(output, force=force, inputs=inputs)
    ds = _with_labels(demos, labels)
    calibrated, report = run_calibration(
        _model(model),
        ds,
        span=span,
        prior=settings.prior,
        scale=not settings.keep_scale,
        transitions=not settings.keep_transitions,
    )
    calibrated.save(output)
    for kind, r in report.items():
        out.print(
            f"{kind}: {r['sequences']} pair(s), {r['steps']} steps ({r['positive_steps']} "
            f"interacting); score offset {r['offset']:+.3f}, scale {r['scale']:.3f}; "
            f"NLL per step {r['nll_per_step_before']:.4f} → {r['nll_per_step_after']:.4f}"
        )
    out.print(f"wrote {output}")


@app.command()
def batch(
    inputs: Annotated[
        list[Path],
        typer.Argument(
            help="Recordings, or folders of recordings (a folder that is no recording "
            "stands for the readable recordings directly inside it)."
        ),
    ],
    output: Annotated[
        Path, typer.Option("-o", "--output", help="Folder for one <name>.phases.json each.")
    ],
    model: Annotated[
        Path | None,
        typer.Option("--model", "-m", help="Model JSON or built-in: default, synthetic."),
    ] = None,
    jobs: Annotated[int, typer.Option(help="Segment in this many local processes.")] = 1,
    scheduler: Annotated[
        str | None,
        typer.Option(
            help="Segment as Dask tasks: tcp://HOST:PORT of a 'dask scheduler', or 'local' "
            "(a local cluster of --jobs workers; docs/how-to/cluster.md; needs the dask extra)."
        ),
    ] = None,
    force: Annotated[
        bool, typer.Option(help="Replace existing phases files (kept as numbered .bak).")
    ] = False,
) -> None:
    """Segment many recordings, one unit each, serially, in processes or on a Dask cluster.

    Every output is checked before any work starts; a recording that cannot be
    read or segmented is reported and the others are still written (the command
    then exits 1). The files are the same whatever ran the units.
    """
    from thirdhand import options
    from thirdhand.batch import check_scheduler, parallel_map
    from thirdhand.progress import progress
    from thirdhand.segment.batch import SegmentJob, output_names, recordings_in, segment_unit

    options.integer("--jobs", jobs, low=1, high=1024)
    if scheduler is not None:
        check_scheduler(scheduler)
    if output.exists() and not output.is_dir():
        raise ThirdhandError(f"--output {output}: expected a folder, it is a file")
    recordings = recordings_in(inputs)
    names = output_names(recordings)
    model_inputs = [model] if model is not None and model.exists() else []
    targets = [output / n for n in names]
    check_outputs(
        [("--output", t) for t in targets],
        force=force,
        inputs=[*inputs, *recordings, *model_inputs],
    )
    spec = None if model is None else str(model)
    if model is not None:
        _model(model)  # a bad model is one error before any unit runs
    work = [SegmentJob(str(p), spec) for p in recordings]
    failed: list[tuple[str, str]] = []
    with progress() as bar:
        task = bar.add_task("segment", total=len(work))
        units = parallel_map(segment_unit, work, jobs=jobs, scheduler=scheduler)
        for target, outcome in zip(targets, units, strict=True):
            bar.advance(task)
            if outcome.phases is None:
                failed.append((outcome.recording, outcome.error or "failed"))
                out.print(f"{outcome.recording}: FAILED: {outcome.error}")
                continue
            output.mkdir(parents=True, exist_ok=True)
            write_text(target, jsontext.dumps(outcome.phases, what=str(target)))
            scores = ", ".join(
                f"{kind} F1 {s['frame_f1']:.3f}" for kind, s in outcome.scores.items()
            )
            out.print(
                f"{outcome.recording}: {outcome.n_pairs} pairs, {outcome.n_steps} latent steps"
                + (f"; vs labels: {scores}" if scores else "")
                + f" → {target}"
            )
    if failed:
        first, why = failed[0]
        raise ThirdhandError(
            f"{len(failed)} of {len(work)} recordings failed (the others were written); "
            f"first: {first}: {why}"
        )


__all__ = ["DefaultCommandGroup", "app", "read_label_file"]
