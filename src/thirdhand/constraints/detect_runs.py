"""Constrained runs of a pair: merging, their mean pose, further poses, evidence."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from thirdhand import se3
from thirdhand.arrays import BoolArray, FloatArray
from thirdhand.constraints.detect_dofs import _on_joint
from thirdhand.constraints.detect_steps import _motion, _runs
from thirdhand.constraints.detect_types import DetectOptions, PairTracks
from thirdhand.constraints.hmm import HMMParams, fit_hmm

if TYPE_CHECKING:
    from thirdhand.segment.pipeline import SegmentationResult


def _merge_same_pose(
    runs: list[tuple[int, int]],
    p: FloatArray,
    q: FloatArray,
    held: BoolArray,
    fallback: FloatArray,
    tol: tuple[float, float],
    min_motion: tuple[float, float],
) -> list[tuple[int, int, bool]]:
    """Join consecutive runs of one pair that are the same constraint.

    Two runs at the same pose (within ``tol``, metres and radians) are one
    constraint when the interruption is brief (at most a quarter of the shorter
    run: a real part nudged while it is tightened) or, between them, the part
    did not go anywhere: most steps lack
    evidence (a camera lost the tag) or the median deviation stays within ``tol``
    (jitter out of the constrained state); or when the child moved along a joint
    in between (a drawer opened and closed: the third element is then True).
    A part taken off and put back in the same slot is two constraints.
    """
    out: list[tuple[int, int, bool]] = []
    ok = np.all(np.isfinite(p), axis=1) & np.all(np.isfinite(q), axis=1)
    for lo, hi in runs:
        if out:
            a, b, joint = out[-1]
            p0, q0 = _run_pose(p[a:b], q[a:b], fallback, held[a:b])
            p1, q1 = _run_pose(p[lo:hi], q[lo:hi], fallback, held[lo:hi])
            if np.linalg.norm(p1 - p0) <= tol[0] and float(se3.quat_angle(q0, q1)) <= tol[1]:
                gap = np.arange(b, lo)
                seen = gap[ok[gap]]
                brief = gap.size <= 0.25 * min(b - a, hi - lo)
                if (
                    brief
                    or seen.size < 0.5 * gap.size
                    or (
                        np.median(np.linalg.norm(p[seen] - p0, axis=1)) <= tol[0]
                        and np.median(se3.quat_angle(q[seen], q0)) <= tol[1]
                    )
                ):
                    out[-1] = (a, hi, joint)
                    continue
                if b - a >= 3 and _on_joint(p[a:hi], q[a:hi], min_motion) is not None:
                    out[-1] = (a, hi, True)
                    continue
        out.append((lo, hi, False))
    return out


def _held(phases: SegmentationResult, body: str, t0: float, t1: float) -> bool:
    """Whether a hand of the segmentation holds ``body`` at some time in ``[t0, t1]``."""
    for h in phases.hands:
        if h.object != body:
            continue
        for s, e in h.intervals:
            if s <= t1 and e >= t0:
                return True
    return False


def _further_poses(
    tracks: PairTracks,
    posterior: FloatArray,
    params: HMMParams,
    opt: DetectOptions,
    step: float,
) -> list[tuple[int, FloatArray, FloatArray]]:
    """Constraint poses of a pair other than its last one (assembled, taken apart, redone).

    The first EM pass starts each pair's constraint pose at the end of the
    recording. Up to ``max_poses - 1`` more passes look, among the steps no pose
    explains yet, for the longest stretch over which the pair's relative pose
    stays still (steps within 4 σ √2 of each other) for ``min_duration`` while
    one of the parts moves in the world (co-motion: the stricter evidence; two
    parts resting side by side do not qualify); EM then learns that pose on the
    unexplained steps, with the shared parameters kept.

    Returns
    -------
    list of (pair index, posterior (n_steps,), pose position (3,))
    """
    rel_p, rel_q, pairs, world = tracks.rel_p, tracks.rel_q, tracks.pairs, tracks.world
    out: list[tuple[int, FloatArray, FloatArray]] = []
    explained = posterior > 0.5
    step_p = 4.0 * math.sqrt(2.0) * params.sigma_pos
    step_r = 4.0 * math.sqrt(2.0) * params.sigma_rot
    min_steps = max(2, round(max(opt.min_duration, 1.0) / step))
    for _ in range(opt.max_poses - 1):
        ks, ps, qs, tps, tqs = [], [], [], [], []
        for k, (a, b) in enumerate(pairs):
            p = np.where(explained[k][:, None], np.nan, rel_p[k])
            q = np.where(explained[k][:, None], np.nan, rel_q[k])
            dp = np.linalg.norm(np.diff(p, axis=0), axis=1)
            dr = se3.quat_angle(q[1:], q[:-1])
            still = np.concatenate([[False], (dp < step_p) & (dr < step_r)])
            best = None
            for lo, hi in _runs(still):
                if hi - lo < min_steps or (best is not None and hi - lo <= best[1] - best[0]):
                    continue
                moved = any(
                    m[0] > opt.co_motion[0] or m[1] > opt.co_motion[1]
                    for m in (_motion(*world[n], lo, hi) for n in (a, b))
                )
                if moved:
                    best = (lo, hi)
            if best is not None:
                tp, tq = _run_pose(p[best[0] : best[1]], q[best[0] : best[1]], np.zeros(3))
                ks.append(k)
                ps.append(p)
                qs.append(q)
                tps.append(tp)
                tqs.append(tq)
        if not ks:
            break
        # One EM over every pair with a further pose (the chain runs on all at once).
        post, _, tp2, _ = fit_hmm(
            np.stack(ps),
            np.stack(qs),
            np.stack(tps),
            np.stack(tqs),
            params=dataclasses.replace(params),
            n_iter=opt.n_iter,
            update_shared=False,
        )
        for j, k in enumerate(ks):
            pk = np.where(explained[k], 0.0, post[j])
            if np.any(pk > 0.5):
                explained[k] |= pk > 0.5
                out.append((k, pk, tp2[j]))
    return out


@dataclass
class _Run:
    """A candidate constraint: a pair's constrained span."""

    start: float
    k: int
    lo: int
    hi: int
    conf: float
    joint: bool
    held: BoolArray


def first_seen(p: FloatArray, q: FloatArray, lo: int, hi: int) -> int:
    """First step in ``[lo, hi)`` where the pair's relative pose is known; ``lo`` if none."""
    ok = np.all(np.isfinite(p[lo:hi]), axis=1) & np.all(np.isfinite(q[lo:hi]), axis=1)
    seen = np.flatnonzero(ok)
    return lo + int(seen[0]) if seen.size else lo


def _approach_start(p: FloatArray, q: FloatArray, lo: int, w: int) -> int:
    """First step of the approach window before step ``lo``: ``w`` steps in which the pair was seen.

    Steps where either part was not tracked (``p`` or ``q`` not finite) do not
    count: the window reaches back over them. A part is hidden exactly when it
    is being put in place (a hand over an AR tag during an insertion), so a
    window of wall-clock time would often hold no observation of the approach
    at all. On a fully tracked pair it is the ``w`` steps before ``lo``.
    """
    ok = np.all(np.isfinite(p[:lo]), axis=1) & np.all(np.isfinite(q[:lo]), axis=1)
    seen = np.flatnonzero(ok)
    if seen.size < w:
        return 0
    return int(min(lo - w, seen[-w]))


def _supported(tracks: PairTracks, k: int, lo: int, hi: int, opt: DetectOptions) -> bool:
    """Whether pair ``k``'s constrained run ``[lo, hi)`` has co-motion or approach evidence."""
    a, b = tracks.pairs[k]
    rel_p, rel_q, times, phases = tracks.rel_p, tracks.rel_q, tracks.times, tracks.phases
    for body in (a, b):
        dp, dr = _motion(*tracks.world[body], lo, hi)
        if dp > opt.co_motion[0] or dr > opt.co_motion[1]:
            return True
    w = max(1, round(opt.approach_window / tracks.step))
    before = _approach_start(rel_p[k], rel_q[k], lo, w)
    if before == lo:
        return False
    # up to the first step the pair is seen in the run (the chain carries the state
    # back over steps where a part was hidden, so ``lo`` itself may be unseen)
    dp, dr = _motion(rel_p[k], rel_q[k], before, first_seen(rel_p[k], rel_q[k], lo, hi) + 1)
    if not (dp > opt.approach_motion[0] or dr > opt.approach_motion[1]):
        return False
    pa = rel_p[k, lo:hi]
    dist = np.nanmedian(np.linalg.norm(pa, axis=1)) if np.any(np.isfinite(pa)) else np.inf
    if dist < opt.contact_distance:
        return True
    # Farther apart: only when the segmentation saw a hand bring one of them there.
    if phases is not None and phases.hands:
        t0, t1 = times[before], times[min(hi, lo + w) - 1]
        return _held(phases, a, t0, t1) or _held(phases, b, t0, t1)
    return False


def _run_pose(
    p: FloatArray, q: FloatArray, fallback: FloatArray, mask: BoolArray | None = None
) -> tuple[FloatArray, FloatArray]:
    """Pose the parts hold over the valid (and ``mask``-ed) steps of a run.

    The component-wise median of the positions and of the sign-aligned
    quaternions (renormalised), not their mean: a person handling an assembled
    pair pushes it out of place for seconds, and the mean follows (a real
    toolbox's joined boards: 3.4 mm and 1° from the pose they hold, from 16 s of
    handling at the end of a 47-s run). Within a run the poses differ by a few
    noise levels, where the component-wise median of the quaternions is the
    rotation median to second order.
    """
    ok = np.all(np.isfinite(p), axis=1) & np.all(np.isfinite(q), axis=1)
    if mask is not None and np.any(ok & mask):
        ok &= mask
    if not np.any(ok):
        return fallback.copy(), np.array([0.0, 0.0, 0.0, 1.0])
    qq = q[ok]
    qq = qq * np.sign(np.sum(qq * qq[0], axis=1))[:, None]
    m = np.median(qq, axis=0)
    return np.median(p[ok], axis=0), m / np.linalg.norm(m)
