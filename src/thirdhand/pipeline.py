"""The main job: a synthetic chair assembly through every stage that exists.

Each stage reads the previous stage's output and writes its own files into the
output folder; the returned summary lists what was written and the key figures.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from thirdhand import io
from thirdhand.demonstration import Demonstration
from thirdhand.fileops import backup_existing


def run_demo(output: str | os.PathLike[str], *, seed: int = 0) -> dict[str, Any]:
    """Generate the default chair demonstration and run every stage on it.

    Parameters
    ----------
    output : path-like
        Folder for the outputs; created if needed. Files in it are replaced, each
        previous version kept as ``<name>.bak``.
    seed : int
        Seed of the synthetic demonstration.

    Returns
    -------
    dict
        ``lines``: human-readable summary lines; ``files``: written paths; and one
        block of figures per stage.
    """
    from thirdhand.synth import SensorModel, make_scene

    out = Path(output)
    out.mkdir(parents=True, exist_ok=True)
    summary: dict[str, Any] = {"lines": [], "files": [], "seed": seed}

    demo = make_scene("chair", seed=seed, sensor=SensorModel())
    demo_path = out / "demonstration.parquet"
    backup_existing(demo_path)
    io.save(demo, demo_path)
    summary["files"].append(str(demo_path))
    summary["demonstration"] = _demo_figures(demo)
    summary["lines"].append(
        f"demonstration: {len(demo)} bodies, {demo.n_frames} frames, "
        f"{demo.duration:.1f} s at {demo.rate:.0f} Hz, "
        f"{len(demo.labels.interactions)} labelled interactions, "
        f"{len(demo.labels.constraints)} constraints → {demo_path}"
    )
    _run_segmentation(demo, out, summary)
    return summary


def _demo_figures(demo: Demonstration) -> dict[str, Any]:
    return {
        "bodies": demo.body_names,
        "n_frames": demo.n_frames,
        "duration_s": demo.duration,
        "rate_hz": demo.rate,
        "missing": {n: demo.missing_fraction(n) for n in demo.body_names},
        "plan": [f"action({s.parent}, {s.child}, {s.symbol})" for s in demo.labels.plan],
    }


def _run_segmentation(demo: Demonstration, out: Path, summary: dict[str, Any]) -> None:
    try:
        from thirdhand.segment.pipeline import run_stage
    except ImportError:
        return
    run_stage(demo, out, summary)
