"""Experiments of the primitives stage, as functions returning their figures.

Used by ``research/scripts/primitives_*.py`` (which print them) and by the tests.
"""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from thirdhand import se3
from thirdhand.datasets.primitive_shapes import concatenate_shapes, lasa_shapes, sine_tracks
from thirdhand.primitives.primitive_library import Parse, PrimitiveLibrary
from thirdhand.primitives.quaternion_dmp import PoseDMP
from thirdhand.primitives.segmentation_dp import brute_force_marginals, segment_marginals


def _consistent_labels(
    found: Sequence[np.ndarray], true: Sequence[np.ndarray]
) -> tuple[bool, dict[int, int]]:
    """Whether one mapping skill → true class explains every parse (a bijection)."""
    mapping: dict[int, int] = {}
    for f, t in zip(found, true, strict=True):
        if len(f) != len(t):
            return False, mapping
        for a, b in zip(f, t, strict=True):
            if mapping.setdefault(int(a), int(b)) != int(b):
                return False, mapping
    return len(set(mapping.values())) == len(mapping), mapping


def sine_experiment(*, seed: int = 0, n_train: int = 10, n_test: int = 10) -> dict[str, Any]:
    """The report's 1-D experiment: down, bump (two halves always together), up.

    Returns
    -------
    dict
        ``skills_found`` (components with weight > 0.05), ``boundaries_exact``
        (test tracks whose boundaries are all within 2 samples), ``labels_consistent``,
        ``n_candidates`` and ``n_cuts`` (summed over test tracks), ``fit_s``.
    """
    train = sine_tracks(n_train, seed=seed)
    t0 = time.perf_counter()
    lib = PrimitiveLibrary(3, threshold=0.05, seed=seed).fit([(t, y) for t, y, _, _ in train])
    fit_s = time.perf_counter() - t0
    test = sine_tracks(n_test, seed=1000 + seed)
    parses = [lib.parse(t, y) for t, y, _, _ in test]
    exact = sum(
        p.bounds.size == b.size and bool(np.abs(p.bounds - b).max() <= 2)
        for p, (_, _, b, _) in zip(parses, test, strict=True)
    )
    ok, mapping = _consistent_labels([p.labels for p in parses], [lab for *_, lab in test])
    return {
        "library": lib,
        "parses": parses,
        "skills_found": int((lib.mixture_.weights_ > 0.05).sum()),
        "boundaries_exact": exact,
        "n_test": n_test,
        "labels_consistent": ok,
        "mapping": mapping,
        "n_candidates": int(sum(p.candidates.size for p in parses)),
        "n_cuts": int(sum(p.cuts.size for p in parses)),
        "fit_s": fit_s,
    }


def lasa_join_experiment(
    folder: str | os.PathLike[str],
    *,
    names: Sequence[str] = ("Worm", "GShape", "PShape"),
    threshold: float = 15.0,
    n_train: int = 8,
    n_test: int = 4,
    tolerance_s: float = 0.15,
    seed: int = 0,
) -> dict[str, Any]:
    """Concatenated LASA shapes: are the joins recovered as cuts, and are the skills the shapes?

    Training tracks use demonstrations 0–4 of each shape, test tracks 5–6; each
    track is 3–4 random shapes joined end to start, resampled at 200 Hz.

    Returns
    -------
    dict
        ``joins``, ``joins_recovered`` (within ``tolerance_s``), ``extra_cuts``,
        ``labels_consistent``, ``n_candidates``, ``fit_s``.
    """
    shapes = {n: lasa_shapes(folder, n) for n in names}
    rng = np.random.default_rng(seed)
    rate = 200.0

    def make(
        n: int, ids: Sequence[int]
    ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
        out = []
        for _ in range(n):
            seq = rng.choice(len(names), size=int(rng.integers(3, 5)))
            parts = [shapes[names[k]][int(rng.choice(ids))] for k in seq]
            t, y, joins = concatenate_shapes(parts, rate=rate)
            out.append((t, y, joins, seq))
        return out

    train, test = make(n_train, range(5)), make(n_test, (5, 6))
    lib = PrimitiveLibrary(len(names), threshold=threshold, n_weights=20, n_samples=50, seed=seed)
    t0 = time.perf_counter()
    lib.fit([(t, y) for t, y, _, _ in train])
    fit_s = time.perf_counter() - t0
    parses: list[Parse] = [lib.parse(t, y) for t, y, _, _ in test]
    tol = tolerance_s * rate
    n_joins = sum(len(j) for *_, j, _ in test)
    hit = extra = 0
    for p, (_, _, joins, _) in zip(parses, test, strict=True):
        d = np.abs(p.cuts[:, None] - joins[None, :]) if p.cuts.size else np.zeros((0, len(joins)))
        hit += int((d.min(axis=0) <= tol).sum()) if p.cuts.size else 0
        extra += int((d.min(axis=1) > tol).sum()) if p.cuts.size else 0
    ok, mapping = _consistent_labels([p.labels for p in parses], [s for *_, s in test])
    return {
        "library": lib,
        "test": test,
        "parses": parses,
        "joins": n_joins,
        "joins_recovered": hit,
        "extra_cuts": extra,
        "labels_consistent": ok,
        "mapping": {names[v]: k for k, v in mapping.items()},
        "n_candidates": int(sum(p.candidates.size for p in parses)),
        "fit_s": fit_s,
    }


def dp_check(*, sizes: Sequence[int] = (4, 8, 12), big: int = 200, seed: int = 0) -> dict[str, Any]:
    """Forward–backward marginals vs brute-force enumeration, and the time for ``big`` cuts."""
    rng = np.random.default_rng(seed)
    rows = []
    for m in sizes:
        s = rng.normal(0.0, 3.0, (m + 2, m + 2))
        t0 = time.perf_counter()
        u, lz = segment_marginals(s)
        t_dp = time.perf_counter() - t0
        t0 = time.perf_counter()
        ub, lzb = brute_force_marginals(s)
        t_bf = time.perf_counter() - t0
        rows.append(
            {
                "M": m,
                "max_abs_diff": float(np.abs(u - ub).max()),
                "logz_diff": abs(lz - lzb),
                "dp_s": t_dp,
                "brute_s": t_bf,
            }
        )
    s = rng.normal(0.0, 3.0, (big + 2, big + 2))
    t0 = time.perf_counter()
    segment_marginals(s)
    return {"rows": rows, "big_M": big, "big_s": time.perf_counter() - t0}


def library_scaling(*, n_tracks: int = 36, n_init: int = 8, seed: int = 0) -> dict[str, Any]:
    """One long 1-D track (concatenated sine tracks) with about 200 candidate cuts.

    Returns the number of candidate cuts, the fit time (``n_init`` restarts), the
    parse time and the number of cuts kept.
    """
    parts = sine_tracks(n_tracks, seed=seed)
    y = np.concatenate([p[1] for p in parts])
    t = np.arange(y.shape[0]) / 100.0
    lib = PrimitiveLibrary(3, threshold=0.05, n_init=n_init, seed=seed)
    t0 = time.perf_counter()
    lib.fit([(t, y)])
    fit_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    p = lib.parse(t, y)
    return {
        "n_samples": int(y.shape[0]),
        "n_candidates": int(lib.candidates_[0].size),
        "fit_s": fit_s,
        "n_init": n_init,
        "parse_s": time.perf_counter() - t0,
        "n_cuts": int(p.cuts.size),
        "true_cuts": int(sum(len(q[3]) for q in parts) - 1),
    }


def orientation_comparison(*, n_weights: int = 30, seed: int = 0) -> dict[str, Any]:
    """Seven-DMP (component-wise, renormalised) vs quaternion DMP (Ude et al. 2014).

    On a smooth 6-DoF demonstration: imitation error, and for new goal
    orientations 30°, 90° and 170° away from the demonstrated one: error at
    ``1.5 tau`` and the smallest norm of the un-normalised seven-DMP quaternion
    (how close the component-wise interpolation comes to the singular zero);
    for start orientations 90° and 170° away: final error, largest rotation
    between consecutive samples (a jump where the norm collapses), smallest norm.
    """
    t = np.linspace(0.0, 2.0, 241)
    s = t / t[-1]
    blend = 10 * s**3 - 15 * s**4 + 6 * s**5
    pos = np.stack([0.3 * blend, 0.1 * np.sin(np.pi * blend), -0.2 * blend], axis=1)
    rv = np.stack([1.2 * blend, 0.4 * np.sin(np.pi * blend), -0.6 * blend], axis=1)
    quat = Rotation.from_rotvec(rv).as_quat()
    out: dict[str, Any] = {"imitation": {}, "new_goal": [], "new_start": []}
    models = {
        "quaternion": PoseDMP(n_weights, orientation="quaternion").fit(t, pos, quat),
        "seven": PoseDMP(n_weights, orientation="seven").fit(t, pos, quat),
    }
    for name, m in models.items():
        _, p, q = m.rollout()
        out["imitation"][name] = {
            "pos_mm": 1000 * float(np.abs(p - pos).max()),
            "rot_deg": float(np.degrees(se3.quat_angle(q, quat).max())),
        }
    rng = np.random.default_rng(seed)
    for angle in (30.0, 90.0, 170.0):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        goal = se3.quat_multiply(Rotation.from_rotvec(np.radians(angle) * axis).as_quat(), quat[-1])
        row: dict[str, Any] = {"goal_change_deg": angle}
        for name, m in models.items():
            _, _, q = m.rollout(goal_quat=goal, run_time=3.0)
            row[f"{name}_final_deg"] = float(np.degrees(se3.quat_angle(q[-1], goal)))
            if name == "seven":
                o = m.orientation_
                g = goal if float(goal @ o.start_) >= 0 else -goal
                _, raw, _ = o.rollout(goal=g, run_time=3.0)
                row["seven_min_norm"] = float(np.linalg.norm(raw, axis=1).min())
        out["new_goal"].append(row)
    for angle in (90.0, 170.0):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        start = se3.quat_multiply(Rotation.from_rotvec(np.radians(angle) * axis).as_quat(), quat[0])
        row = {"start_change_deg": angle}
        for name, m in models.items():
            _, _, q = m.rollout(start_quat=start, run_time=3.0)
            row[f"{name}_final_deg"] = float(np.degrees(se3.quat_angle(q[-1], quat[-1])))
            steps = np.degrees(se3.quat_angle(q[1:], q[:-1]))
            row[f"{name}_max_step_deg"] = float(steps.max())
            if name == "seven":
                o = m.orientation_
                st = start if float(start @ o.start_) >= 0 else -start
                _, raw, _ = o.rollout(start=st, run_time=3.0)
                row["seven_min_norm"] = float(np.linalg.norm(raw, axis=1).min())
        out["new_start"].append(row)
    return out
