"""One row of the channels table of ``research/notes/primitives.md``: a choice of level
channels on a labelled ``.mat`` file, unsupervised and (optionally) the supervised
separability diagnostics.

Unsupervised: the HSMM with entry and exit states, fitted without labels, leave one
recording out (:func:`~research.primitive_labels.evaluate_streams`, as
``python -m research primitives evaluate --model hsmm --ends --zero-ft``), K given or chosen by
the one-SE rule over 1…6. With ``--ceiling``: the label-trained HSMM fitted on every
recording's labels and tested on the same recordings (in-sample, a diagnostic of how
separable the phases are on these channels, not a result), and, for a file of two
recordings, fitted on one and tested on the other.

Run::

    python research/scripts/primitives_channels.py ../shared/data/figueroa/peeling_noobj.mat \\
        --levels logforce,logtorque,logspeed,logangular,relpos --arms 0,1 --skills 3 --ceiling
    python research/scripts/primitives_channels.py ../shared/data/figueroa/circular_wiping.mat \\
        --levels logforce
"""

from __future__ import annotations

import argparse
import os
import time
from dataclasses import replace

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

from research.primitive_labels import (
    ParserConfig,
    _make_hsmm,
    _tracks,
    evaluate_streams,
)
from thirdhand.io.figueroa import read_labelled_mat


def _label_trained_accuracy(
    cfg: ParserConfig, lev: list[np.ndarray], labels: list[np.ndarray], train: list[int], test: int
) -> float:
    model = _make_hsmm(1, cfg).fit_labelled([lev[j] for j in train], [labels[j] for j in train])
    return float(np.mean(model.predict(lev[test]) == labels[test]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mat")
    ap.add_argument("--levels", required=True, help="comma list of level channels")
    ap.add_argument("--arms", default=None, help="e.g. 0,1 (default all)")
    ap.add_argument("--skills", type=int, default=None, help="K work states (default: one SE)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--window", type=int, default=5, help="level smoothing, parse samples")
    ap.add_argument("--ceiling", action="store_true", help="also the label-trained figures")
    a = ap.parse_args()
    streams = read_labelled_mat(a.mat)
    cfg = ParserConfig(
        model="hsmm",
        ends=True,
        n_skills=a.skills,
        k_range=(1, 2, 3, 4, 5, 6),
        arms=None if a.arms is None else tuple(int(x) for x in a.arms.split(",")),
        levels=tuple(a.levels.split(",")),
        zero_ft=True,
        window=a.window,
        seed=a.seed,
    )
    t0 = time.perf_counter()
    res = evaluate_streams(streams, cfg)
    b = res.boundaries
    print(
        f"{a.levels}: acc {res.accuracy:.3f} acc1 {res.global_accuracy:.3f} P {b.precision:.2f} "
        f"R {b.recall:.2f} F1 {b.f1:.2f} predicted {b.n_pred}; per recording "
        f"{[round(r.accuracy, 3) for r in res.streams]}, K {[r.n_skills for r in res.streams]}"
        f" ({time.perf_counter() - t0:.0f} s)"
    )
    if not a.ceiling:
        return
    sup = replace(cfg, label_trained=True)
    lev = [x[2] for x in _tracks(streams, sup)]
    labels = [s.labels[:: sup.subsample] for s in streams]
    every = list(range(len(streams)))
    accs = [_label_trained_accuracy(sup, lev, labels, every, i) for i in every]
    n = [len(x) for x in labels]
    per = [round(x, 3) for x in accs]
    print(f"  SUPERVISED in-sample: {np.dot(accs, n) / sum(n):.3f} per recording {per}")
    if len(streams) == 2:
        cross = [_label_trained_accuracy(sup, lev, labels, [1 - i], i) for i in every]
        print(f"  SUPERVISED cross (tested on recording 0 / 1): {[round(x, 3) for x in cross]}")


if __name__ == "__main__":
    main()
