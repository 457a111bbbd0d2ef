"""The primitive-library parser beside ``ruptures`` and plain ZCV cuts on labelled recordings.

With ``--details``, on every labelled ``.mat`` file given (default: the shared
wiping and peeling recordings), in one run and on the same channels and subsampling:

- **parser**: :func:`research.primitive_labels.evaluate_streams`, leave
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
(K = number of human labels, :func:`~research.primitive_labels.cluster_segments`),
then the same Hungarian map. Printed: frame accuracy under a map per recording
(``acc``; each held-out recording has its own library) and under one map for
all (``acc1``), boundary P/R/F1 at the tolerance, and each method's time with
its ratio to the parser's (the parser's time includes fitting, leave one out).

First, the **product table** (what ``thirdhand primitives library`` runs): on every
shared labelled file (circular wiping, fender wiping, peeling), leave one
recording out, K = the number of human labels, on the pose channels of the first
arm only (speed, angular rate, height, vertical and axial speeds;
:mod:`thirdhand.primitives.pose_channels`)
and with the force and torque magnitudes added: the skill library (HSMM,
:class:`~thirdhand.primitives.skill_library.SkillLibrary`) vs the seed parser
(positions, candidate cuts + ProMP skills) vs KernelCPD (rbf) and ZCV cuts, both
labelled by k-means on the same channels. Then, with ``--details``, the earlier
per-file tables of the evaluation recipes.

Usage: ``python benchmarks/primitives_vs_ruptures.py [FILE.mat …] [--tolerance 1] [--details]``
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
import ruptures as rpt

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository root: `research`

from research.primitive_labels import (
    ParserConfig,
    cluster_segments,
    evaluate_streams,
)
from research.primitive_scores import (
    BoundaryScore,
    best_label_map,
    match_boundaries,
)
from thirdhand.io.figueroa import LabelledStream, read_labelled_mat
from thirdhand.primitives.pose_channels import PoseTrack
from thirdhand.primitives.segment_features import candidate_cuts, smoothed_speed

DATA = next(
    (
        d
        for d in (
            Path(__file__).resolve().parents[i] / "shared" / "data" / "figueroa" for i in (2, 3)
        )
        if d.is_dir()
    ),
    Path(os.environ.get("THIRDHAND_DATA", "../shared/data")) / "figueroa",
)
#: The shared labelled files of the product table.
PRODUCT_FILES = ("circular_wiping.mat", "fender_wiping.mat", "peeling_noobj.mat")
#: Per file: the parser's channels (chosen in research/notes/primitives.md).
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
    from research.primitive_channels import stream_channels

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


def _pose_tracks(streams: list[LabelledStream]) -> list[PoseTrack]:
    return [
        PoseTrack(
            s.t, s.arms[0].pos, s.arms[0].quat, s.arms[0].force, s.arms[0].torque, name=s.name
        )
        for s in streams
    ]


def _frames(s: LabelledStream, t: np.ndarray, lab: np.ndarray) -> np.ndarray:
    idx = np.clip(np.rint(np.interp(s.t, t, np.arange(t.size))).astype(np.int64), 0, t.size - 1)
    return lab[idx]


def _loo_scores(
    streams: list[LabelledStream], preds: list[np.ndarray], tol: float
) -> tuple[float, BoundaryScore]:
    n = sum(s.n_samples for s in streams)
    acc = sum(best_label_map([p], [s.labels])[1] for p, s in zip(preds, streams, strict=True)) / n
    total: BoundaryScore | None = None
    for s, p in zip(streams, preds, strict=True):
        b = match_boundaries(s.boundaries, s.t[np.flatnonzero(np.diff(p)) + 1], tolerance=tol)
        total = b if total is None else total + b
    assert total is not None
    return acc, total


def product_table(files: list[Path], tol: float) -> None:
    """Skill library vs seed parser vs KernelCPD vs ZCV, pose only and with forces."""
    from thirdhand.primitives.pose_channels import default_channels, pose_channels
    from thirdhand.primitives.primitive_library import PrimitiveLibrary
    from thirdhand.primitives.skill_library import SkillLibrary, SkillParserOptions

    print(
        f"== product table: leave one recording out, K = number of labels, boundary F1 "
        f"within {tol:g} s; acc under each held-out recording's best skill->label map"
    )
    print(f"  {'file':<20} {'channels':<13} {'method':<28} {'acc':>6} {'F1':>5} {'time s':>7}")
    for path in files:
        streams = read_labelled_mat(path)
        tracks = _pose_tracks(streams)
        k = len(np.unique(np.concatenate([s.labels for s in streams])))
        # the product's channels (what `primitives library` uses), and the pose ones alone
        full = default_channels(tracks[0])
        sets = [("pose", tuple(n for n in full if n not in ("logforce", "logtorque")))]
        if any(np.ptp(s.arms[0].force) > 0 for s in streams):
            sets.append(("pose+forces", full))
        for set_name, names in sets:
            rows = []
            opts = SkillParserOptions(n_skills=k, channels=names)
            t0 = time.perf_counter()
            preds = []
            for i, tr in enumerate(tracks):
                train = [tracks[j] for j in range(len(tracks)) if j != i]
                preds.append(SkillLibrary(opts).fit(train).parse(tr).labels)
            rows.append(
                (
                    "skill library (HSMM)",
                    *_loo_scores(streams, preds, tol),
                    time.perf_counter() - t0,
                )
            )
            feats = [pose_channels(tr, names, rate_hz=20.0, window=8) for tr in tracks]
            if set_name == "pose":
                # the seed parser: positions at 20 Hz, speed-minimum cuts, ProMP skills
                t0 = time.perf_counter()
                sub = [(tr.t[::5], tr.pos[::5] / 0.02) for tr in tracks]
                preds = []
                for i, (t, y) in enumerate(sub):
                    train = [sub[j] for j in range(len(sub)) if j != i] or [sub[i]]
                    peaks = [
                        smoothed_speed(yy, float(np.median(np.diff(tt))), 5).max()
                        for tt, yy in train
                    ]
                    lib = PrimitiveLibrary(
                        k, threshold=0.05 * float(np.median(peaks)), n_init=4
                    ).fit(train)
                    preds.append(_frames(streams[i], t, lib.parse(t, y).frame_labels()))
                rows.append(
                    (
                        "seed parser (cuts + ProMPs)",
                        *_loo_scores(streams, preds, tol),
                        time.perf_counter() - t0,
                    )
                )
            for name, algo in (
                ("KernelCPD rbf + k-means", "kernel"),
                ("ZCV cuts + k-means", "zcv"),
            ):
                t0 = time.perf_counter()
                xs = [x for _, x in feats]
                if algo == "kernel":
                    cuts = _ruptures(xs, "kernel", streams)
                else:
                    pos = [tr.pos[::5] / 0.02 for tr in tracks]
                    thr = 0.05 * float(np.median([smoothed_speed(p, 0.05, 5).max() for p in pos]))
                    cuts = []
                    for p, x in zip(pos, xs, strict=True):
                        c = candidate_cuts(p, dt=0.05, threshold=thr, window=5, min_gap=4)
                        cuts.append(c[(c > 0) & (c < x.shape[0] - 1)].astype(np.int64))
                bounds = [
                    np.concatenate([[0], c, [x.shape[0] - 1]]).astype(np.int64)
                    for c, x in zip(cuts, xs, strict=True)
                ]
                labs = cluster_segments(xs, bounds, k)
                preds = [
                    _frames(s, tg, lab)
                    for s, (tg, _), lab in zip(streams, feats, labs, strict=True)
                ]
                rows.append((name, *_loo_scores(streams, preds, tol), time.perf_counter() - t0))
            for name, acc, b, dt in rows:
                print(
                    f"  {path.name:<20} {set_name:<13} {name:<28} {acc:>6.3f} {b.f1:>5.2f} "
                    f"{dt:>7.1f}",
                    flush=True,
                )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("files", nargs="*", type=Path)
    ap.add_argument("--tolerance", type=float, default=1.0)
    ap.add_argument("--details", action="store_true", help="Also the evaluation recipes' tables.")
    args = ap.parse_args()
    product_table(args.files or [DATA / f for f in PRODUCT_FILES], args.tolerance)
    if not args.details:
        return
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
