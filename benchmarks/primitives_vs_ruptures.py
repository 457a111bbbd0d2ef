"""The primitive-library parser beside ``ruptures`` and plain ZCV cuts on labelled recordings.

On every labelled ``.mat`` file given (default: the shared wiping and peeling
recordings), in one run and on the same channels and subsampling:

- **parser**: :func:`thirdhand.primitives.label_eval.evaluate_streams`, leave
  one recording out, consecutive segments of one skill merged;
- **seed parser**: positions only, speed-minimum cuts only, K = number of
  human labels, every kept cut a boundary (the seed, as a new user ran it);
- **ZCV only**: every candidate cut (speed minimum) is a boundary;
- **PELT (l2)** and **KernelCPD (rbf)** from ``ruptures`` on standardised
  channels, penalty ``β = 3 · d · log n`` (l2) and ``β = log n`` (rbf, whose
  cost is at most 1 per sample), fixed beforehand, not tuned on labels;
- **KernelCPD, true count**: told the number of true boundaries (an oracle on
  the count, to show what the cost alone can place);
- **HSMM**: the hidden semi-Markov model over per-sample level channels
  (:mod:`thirdhand.primitives.hsmm`), fitted without labels, leave one
  recording out, and KernelCPD on its channels beside it;
- **HSMM with entry and exit**: the same with an entry state only at the start
  and an exit state only at the end of a recording around the K states of the
  work (``ends``; wiping: K by the one-SE rule over 1…6, peeling: K = 3);
- **HSMM, label-trained** (supervised, not comparable with the rows above): the
  same model fitted on the other recordings' human labels.

Change-point methods get phase labels by k-means on the segments' mean channels
(K = number of human labels, :func:`~thirdhand.primitives.label_eval.cluster_segments`),
then the same Hungarian map. Printed: frame accuracy under a map per recording
(``acc``; each held-out recording has its own library) and under one map for
all (``acc1``), boundary P/R/F1 at the tolerance, and each method's time with
its ratio to the parser's (the parser's time includes fitting, leave one out).

Usage: ``python benchmarks/primitives_vs_ruptures.py [FILE.mat …] [--tolerance 1]``
"""

from __future__ import annotations

import argparse
import os
import time
from dataclasses import replace
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
import ruptures as rpt

from thirdhand.io.figueroa import LabelledStream, read_labelled_mat
from thirdhand.primitives.evaluation import (
    BoundaryScore,
    best_label_map,
    match_boundaries,
)
from thirdhand.primitives.label_eval import (
    ParserConfig,
    cluster_segments,
    evaluate_streams,
)
from thirdhand.primitives.segment_features import candidate_cuts, smoothed_speed

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "figueroa"
#: Per file: the parser's channels (chosen in docs/primitives.md).
CONFIGS = {
    # K selected by the one-SE rule (the default), not given
    "circular_wiping.mat": ParserConfig(
        shape=("pos",), levels=("force",), n_skills=None, n_phases=3
    ),
    "peeling_noobj.mat": ParserConfig(
        shape=("pos",),
        levels=("force", "torque", "speed", "angular"),
        arms=(0, 1),
        n_skills=4,
        switch_penalty=30.0,
    ),
}
#: Per file: the HSMM's channels and number of states.
HSMM_CONFIGS = {
    "circular_wiping.mat": ParserConfig(model="hsmm", levels=("force",), zero_ft=True, n_skills=3),
    "peeling_noobj.mat": ParserConfig(
        model="hsmm",
        levels=("force", "torque", "speed", "angular", "relpos"),
        arms=(0, 1),
        zero_ft=True,
        n_skills=3,
    ),
}

#: Per file: the HSMM with entry and exit states (``ends``).
HSMM_ENDS_CONFIGS = {
    "circular_wiping.mat": replace(
        HSMM_CONFIGS["circular_wiping.mat"], ends=True, n_skills=None, k_range=(1, 2, 3, 4, 5, 6)
    ),
    "peeling_noobj.mat": replace(HSMM_CONFIGS["peeling_noobj.mat"], ends=True),
}

#: Per file: the same with the log-magnitude level channels (the best on both files).
HSMM_LOG_CONFIGS = {
    "circular_wiping.mat": replace(HSMM_ENDS_CONFIGS["circular_wiping.mat"], levels=("logforce",)),
    "peeling_noobj.mat": replace(
        HSMM_ENDS_CONFIGS["peeling_noobj.mat"],
        levels=("logforce", "logtorque", "logspeed", "logangular", "relpos"),
    ),
}


def _features(streams: list[LabelledStream], cfg: ParserConfig) -> list[np.ndarray]:
    from thirdhand.primitives.channels import stream_channels

    out = []
    for s in streams:
        y, lev = stream_channels(
            s,
            shape=cfg.shape,
            levels=cfg.levels,
            arms=cfg.arms,
            window=cfg.window * cfg.subsample,
            zero_ft=cfg.zero_ft,
        )
        x = lev if cfg.model == "hsmm" else np.hstack([y, lev])
        out.append(x[:: cfg.subsample])
    return out


def _score(
    streams: list[LabelledStream],
    cfg: ParserConfig,
    feats: list[np.ndarray],
    cuts: list[np.ndarray],
    tol: float,
) -> tuple[float, float, BoundaryScore]:
    bounds = [
        np.concatenate([[0], c, [f.shape[0] - 1]]).astype(np.int64)
        for c, f in zip(cuts, feats, strict=True)
    ]
    n_lab = len(np.unique(np.concatenate([s.labels for s in streams])))
    labs = cluster_segments(feats, bounds, n_lab)
    full = []
    total: BoundaryScore | None = None
    for s, lab, c in zip(streams, labs, cuts, strict=True):
        t = s.t[:: cfg.subsample]
        idx = np.clip(np.searchsorted(t, s.t, side="right") - 1, 0, t.size - 1)
        full.append(lab[idx])
        b = match_boundaries(s.boundaries, t[c], tolerance=tol)
        total = b if total is None else total + b
    _, ok, n = best_label_map(full, [s.labels for s in streams])
    per = sum(best_label_map([f], [s.labels])[1] for f, s in zip(full, streams, strict=True))
    assert total is not None
    return per / n, ok / n, total


def _zcv(streams: list[LabelledStream], cfg: ParserConfig) -> list[np.ndarray]:
    pos = []
    for s in streams:
        arms = range(len(s.arms)) if cfg.arms is None else cfg.arms
        pos.append(np.hstack([s.arms[a].pos / 0.02 for a in arms])[:: cfg.subsample])
    dt = float(np.median(np.diff(streams[0].t))) * cfg.subsample
    thr = 0.05 * float(np.median([smoothed_speed(p, dt, cfg.window).max() for p in pos]))
    return [candidate_cuts(p, dt=dt, threshold=thr, window=cfg.window, min_gap=4) for p in pos]


def _ruptures(
    feats: list[np.ndarray], algo: str, streams: list[LabelledStream]
) -> list[np.ndarray]:
    allx = np.vstack(feats)
    mu, sd = allx.mean(axis=0), allx.std(axis=0)
    sd[sd == 0] = 1.0
    out = []
    for f, s in zip(feats, streams, strict=True):
        z = (f - mu) / sd
        n, d = z.shape
        if algo == "pelt":
            est = rpt.Pelt(model="l2", min_size=4, jump=1).fit(z)
        else:
            est = rpt.KernelCPD(kernel="rbf", min_size=4).fit(z)
        if algo == "oracle":
            bk = est.predict(n_bkps=max(int(s.boundaries.size), 1))
        else:
            # l2 cost grows with d (unit variance per channel); the rbf cost is at most 1 per sample
            bk = est.predict(pen=(3.0 * d if algo == "pelt" else 1.0) * np.log(n))
        out.append(np.array([b for b in bk if 0 < b < n - 1], dtype=np.int64))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("files", nargs="*", type=Path)
    ap.add_argument("--tolerance", type=float, default=1.0)
    args = ap.parse_args()
    files = args.files or [DATA / "circular_wiping.mat", DATA / "peeling_noobj.mat"]
    for path in files:
        streams = read_labelled_mat(path)
        cfg = CONFIGS.get(path.name, ParserConfig())
        feats = _features(streams, cfg)
        rows: list[tuple[str, float, float, BoundaryScore, float]] = []
        t0 = time.perf_counter()
        res = evaluate_streams(streams, cfg, tolerance=args.tolerance)
        t_parser = time.perf_counter() - t0
        rows.append(("parser", res.accuracy, res.global_accuracy, res.boundaries, t_parser))
        n_labels = len(np.unique(np.concatenate([s.labels for s in streams])))
        seed_cfg = replace(
            cfg,
            shape=("pos",),
            levels=(),
            grid=None,
            n_phases=None,
            n_skills=n_labels,
            switch_penalty=0.0,
        )
        t0 = time.perf_counter()
        seed = evaluate_streams(streams, seed_cfg, tolerance=args.tolerance)
        rows.append(
            (
                "seed parser (pos, ZCV, every cut)",
                seed.accuracy,
                seed.global_accuracy,
                seed.raw_boundaries,
                time.perf_counter() - t0,
            )
        )
        for name, algo in (
            ("ZCV only (+ k-means labels)", "zcv"),
            ("PELT l2 (+ k-means labels)", "pelt"),
            ("KernelCPD rbf (+ k-means)", "kernel"),
            ("KernelCPD rbf, true count", "oracle"),
        ):
            t0 = time.perf_counter()
            if algo == "zcv":
                cuts = _zcv(streams, cfg)
            else:
                cuts = _ruptures(feats, algo, streams)
            dt = time.perf_counter() - t0
            acc, gacc, b = _score(streams, cfg, feats, cuts, args.tolerance)
            rows.append((name, acc, gacc, b, dt))
        hcfg = HSMM_CONFIGS.get(path.name, replace(cfg, model="hsmm", n_skills=3))
        t0 = time.perf_counter()
        hs = evaluate_streams(streams, hcfg, tolerance=args.tolerance)
        rows.append(
            (
                "HSMM (no labels)",
                hs.accuracy,
                hs.global_accuracy,
                hs.boundaries,
                time.perf_counter() - t0,
            )
        )
        ecfg = HSMM_ENDS_CONFIGS.get(path.name, replace(hcfg, ends=True))
        lcfg = HSMM_LOG_CONFIGS.get(path.name, replace(ecfg, levels=("logforce",)))
        for label, c in (
            ("HSMM entry/exit (no labels)", ecfg),
            ("HSMM entry/exit, log levels", lcfg),
        ):
            t0 = time.perf_counter()
            he = evaluate_streams(streams, c, tolerance=args.tolerance)
            k_ends = "/".join(str(r.n_skills) for r in he.streams)
            rows.append(
                (
                    f"{label}, K={k_ends}",
                    he.accuracy,
                    he.global_accuracy,
                    he.boundaries,
                    time.perf_counter() - t0,
                )
            )
        hfeats = _features(streams, hcfg)
        t0 = time.perf_counter()
        cuts = _ruptures(hfeats, "kernel", streams)
        dt = time.perf_counter() - t0
        acc, gacc, b = _score(streams, hcfg, hfeats, cuts, args.tolerance)
        rows.append(("KernelCPD rbf on the HSMM's channels", acc, gacc, b, dt))
        t0 = time.perf_counter()
        sup = evaluate_streams(streams, replace(hcfg, label_trained=True), tolerance=args.tolerance)
        rows.append(
            (
                "SUPERVISED: HSMM label-trained",
                sup.accuracy,
                sup.global_accuracy,
                sup.boundaries,
                time.perf_counter() - t0,
            )
        )
        n_true = rows[0][3].n_true
        k_used = "/".join(str(r.n_skills) for r in res.streams)
        print(
            f"== {path.name}: {len(streams)} recordings, {n_true} true boundaries, "
            f"tolerance {args.tolerance:g} s, channels shape={','.join(cfg.shape)} "
            f"levels={','.join(cfg.levels) or '-'} arms={cfg.arms or 'all'}, K={k_used} "
            f"({'given' if cfg.n_skills else cfg.select}), "
            f"phases={cfg.n_phases or '-'}, switch penalty {cfg.switch_penalty:g}; HSMM levels="
            f"{','.join(hcfg.levels)}{' zero-ft' if hcfg.zero_ft else ''}, K={hcfg.n_skills}"
        )
        head = f"{'acc':>6} {'acc1':>6} {'P':>5} {'R':>5} {'F1':>5} {'pred':>5}"
        head += f" {'time s':>8} {'x parser':>8}"
        print(f"  {'method':<36} {head}")
        for name, acc, gacc, b, dt in rows:
            print(
                f"  {name:<36} {acc:>6.3f} {gacc:>6.3f} {b.precision:>5.2f} {b.recall:>5.2f} "
                f"{b.f1:>5.2f} "
                f"{b.n_pred:>5} {dt:>8.2f} {dt / t_parser:>8.2f}"
            )


if __name__ == "__main__":
    main()
