"""Frame accuracy of ``thirdhand primitives library T.csv … --skills K --json`` on labelled files.

Writes each recording's first-arm poses as a CSV ``t x y z qx qy qz qw`` (pose
only: no forces), runs the user's command exactly (one library fitted on all the
tracks of a file, every track parsed), rebuilds each sample's skill from
``tracks[i].cuts_s`` and ``tracks[i].labels``, and scores it against the human
labels under the best one-to-one map of skills to labels (one map for all the
file's tracks), with boundary F1 within 1 s. ``K`` is the number of labels.

Usage: ``python research/scripts/skill_library_cli_eval.py [FILE.mat …] [--parser hsmm|cuts]``
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
from typer.testing import CliRunner

from research.primitive_scores import best_label_map, match_boundaries
from thirdhand.io.figueroa import read_labelled_mat
from thirdhand.primitives.cli import app

#: The shared data beside the repository (or beside the folder of its worktree).
DATA = next(
    (
        d
        for d in (
            Path(__file__).resolve().parents[i] / "shared" / "data" / "figueroa" for i in (2, 3)
        )
        if d.is_dir()
    ),
    Path("../shared/data/figueroa"),
)
FILES = ("circular_wiping.mat", "fender_wiping.mat", "peeling_noobj.mat")


def frames_from_json(t: np.ndarray, track: dict) -> np.ndarray:
    """Skill of every sample from a track's ``cuts_s`` and ``labels``."""
    run = np.searchsorted(np.asarray(track["cuts_s"], dtype=float), t, side="right")
    return np.asarray(track["labels"], dtype=np.int64)[run]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("files", nargs="*", type=Path)
    ap.add_argument("--parser", default="hsmm")
    args = ap.parse_args()
    files = args.files or [DATA / f for f in FILES]
    runner = CliRunner()
    for f in files:
        streams = read_labelled_mat(f)
        k = len(np.unique(np.concatenate([s.labels for s in streams])))
        with tempfile.TemporaryDirectory() as tmp:
            paths = []
            for i, s in enumerate(streams):
                p = Path(tmp) / f"T{i + 1}.csv"
                a = s.arms[0]
                np.savetxt(p, np.column_stack([s.t, a.pos, a.quat]), delimiter=",")
                paths.append(str(p))
            res = runner.invoke(
                app, ["library", *paths, "--skills", str(k), "--json", "--parser", args.parser]
            )
        if res.exit_code != 0:
            print(f"{f.name}: failed: {res.output.strip()}")
            continue
        doc = json.loads(res.output)
        preds = [frames_from_json(s.t, tr) for s, tr in zip(streams, doc["tracks"], strict=True)]
        n = sum(s.n_samples for s in streams)
        acc = best_label_map(preds, [s.labels for s in streams])[1] / n
        b = None
        for s, pred in zip(streams, preds, strict=True):
            change = s.t[np.flatnonzero(np.diff(pred)) + 1]
            m = match_boundaries(s.boundaries, change, tolerance=1.0)
            b = m if b is None else b + m
        assert b is not None
        print(
            f"{f.name}: {len(streams)} tracks, K = {k}, parser {args.parser}: "
            f"frame accuracy {acc:.3f}, boundary F1 {b.f1:.2f}"
        )


if __name__ == "__main__":
    main()
