"""``thirdhand merge A B … -o OUT``: recordings of one session by several capture systems."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console

from thirdhand import jsontext, options
from thirdhand.config import ConfigOption, load_settings
from thirdhand.fileops import check_distinct_inputs, check_outputs
from thirdhand.merge.settings import MergeSettings

out = Console(highlight=False, soft_wrap=True)


def _transform(text: str) -> tuple[list[float], list[float]]:
    from thirdhand.merge.align import MergeError

    try:
        v = [float(x) for x in text.replace(",", " ").split()]
    except ValueError:
        raise MergeError(f"--transform {text!r}: expected 7 numbers 'x y z qx qy qz qw'") from None
    if len(v) != 7 or not all(abs(x) < 1e6 for x in v):
        raise MergeError(f"--transform {text!r}: expected 7 finite numbers 'x y z qx qy qz qw'")
    if abs(sum(x * x for x in v[3:]) ** 0.5 - 1.0) > 1e-3:
        raise MergeError(f"--transform {text!r}: the quaternion qx qy qz qw is not of unit norm")
    return v[:3], v[3:]


def _per_recording(option: str, values: list[str] | None, k: int) -> list[str | None]:
    from thirdhand.merge.align import MergeError

    if not values:
        return [None] * k
    if len(values) != k:
        raise MergeError(
            f"{option} given {len(values)} times for {k} recording(s) after the first; "
            "give it once per recording ('-' to estimate that one)"
        )
    return [None if v == "-" else v for v in values]


def merge_command(
    recordings: Annotated[
        list[Path], typer.Argument(help="Recordings of one session; the first is the reference.")
    ],
    output: Annotated[Path, typer.Option("-o", "--output", help="Merged recording (any format).")],
    via: Annotated[
        list[str] | None, typer.Option(help="Align by this shared body only (repeatable).")
    ] = None,
    same: Annotated[
        list[str] | None,
        typer.Option(help="REF=OTHER: body OTHER of a later recording is body REF (repeatable)."),
    ] = None,
    offset: Annotated[
        list[str] | None,
        typer.Option(help="Known clock offset, s, per later recording ('-' estimates it)."),
    ] = None,
    transform: Annotated[
        list[str] | None,
        typer.Option(
            help="Known world transform 'x y z qx qy qz qw' (x_ref = R x + p) per later recording."
        ),
    ] = None,
    report: Annotated[
        Path | None, typer.Option(help="Write the alignments and residuals as JSON.")
    ] = None,
    force: Annotated[
        bool, typer.Option(help="Replace existing outputs (kept as numbered .bak).")
    ] = False,
    config: ConfigOption = None,
) -> None:
    """Merge recordings of one session by different capture systems into one.

    Settings (``[merge]`` of ``--config``): ``drift``, ``smooth``, ``rate``, ``max_gap``.
    """
    from thirdhand import io
    from thirdhand.fileops import write_text
    from thirdhand.merge.align import MergeError
    from thirdhand.merge.combine import alignment_dict, merge, rename

    if len(recordings) < 2:
        raise MergeError("merge needs at least two recordings")
    check_distinct_inputs(recordings, what="recording")
    settings = load_settings(config, "merge", MergeSettings)
    k = len(recordings) - 1
    offsets = [
        None if v is None else options.finite("--offset", _float("--offset", v))
        for v in _per_recording("--offset", offset, k)
    ]
    transforms = [
        None if v is None else _transform(v) for v in _per_recording("--transform", transform, k)
    ]
    mapping: dict[str, str] = {}
    for item in same or []:
        ref_name, eq, other_name = item.partition("=")
        if not eq or not ref_name or not other_name:
            raise MergeError(f"--same {item!r}: expected REF=OTHER")
        mapping[other_name] = ref_name
    outputs = [("-o", output), ("--report", report)]
    inputs = [*recordings, config]
    check_outputs(outputs, force=force, inputs=inputs)
    demos = [io.load(p) for p in recordings]
    demos = [demos[0]] + [
        rename(d, {a: b for a, b in mapping.items() if a in d}) for d in demos[1:]
    ]
    merged, alignments = merge(
        demos,
        via=via,
        offsets=offsets,
        transforms=transforms,
        fit_drift=settings.drift,
        smooth=settings.smooth,
        rate=settings.rate,
        max_gap=settings.max_gap,
        sources=[str(p) for p in recordings],
    )
    check_outputs(outputs, force=force, inputs=inputs)
    io.save(merged, output)
    for path, al in zip(recordings[1:], alignments, strict=True):
        out.print(_summary(path, al))
    if report is not None:
        doc: dict[str, Any] = {
            "reference": str(recordings[0]),
            "alignments": {
                str(p): alignment_dict(a) for p, a in zip(recordings[1:], alignments, strict=True)
            },
        }
        write_text(report, jsontext.dumps(doc, what=str(report), indent=1))
    out.print(f"wrote {output}: {merged}")


def _float(option: str, text: str) -> float:
    from thirdhand.merge.align import MergeError

    try:
        return float(text)
    except ValueError:
        raise MergeError(f"{option} {text!r}: expected a number of seconds or '-'") from None


def _summary(path: Path, al: Any) -> str:
    lines = [
        f"{path}: t_ref = (1 {al.drift * 1e6:+.2f} ppm) t {al.offset_s:+.6f} s "
        f"({al.time_source}{', smoothed tracks' if al.smoothed else ''}); "
        f"x_ref = R x + p, p = ({', '.join(f'{v:.4f}' for v in al.translation)}) m, "
        f"R = {al.rotation_deg:.3f}° ({al.frame_source})"
    ]
    for r in al.residuals:
        ang = (
            "" if r.angle_median_deg is None else f", orientation median {r.angle_median_deg:.3f}°"
        )
        lines.append(
            f"  {r.body}: {r.inliers}/{r.pairs} pairs kept, residual rms {1000 * r.rms_m:.3f} mm, "
            f"median {1000 * r.median_m:.3f} mm, max {1000 * r.max_m:.3f} mm{ang}"
        )
    return "\n".join(lines)
