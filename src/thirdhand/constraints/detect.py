"""Constraints over time: when a constraint between two parts is created and removed.

For every pair of parts, a two-state HMM (:mod:`thirdhand.constraints.hmm`) over
*free* / *constrained*, whose constrained observation model is the fixed
constraint at a pose learned by EM, labels each latent step. A run of
constrained steps is a constraint instance when there is evidence that it is one,
relying on the motion of at least one of the two parts:

- *co-motion*: during the run one of the parts moves in the world (by more than
  ``co_motion``) while the other follows it; or
- *approach*: the run starts as the child's motion relative to the parent stops
  (there was relative motion just before) and the parts are within
  ``contact_distance`` of each other, or farther apart but the segmentation
  phases (when given) show a hand holding one of them around that moment. The
  CRF's hand phases are a weak cue on noisy data (they miss short grasps), so
  they widen the evidence rather than veto it.

Two parts that lie still on the table have a constant relative pose but neither
kind of evidence. Pairs connected only through earlier constraints (two legs of
the same seat) are recognised with a union–find over the instances in time
order: a new instance joins two rigid groups, and the parent is the member of
the other group nearest to the child. The root of the assembly is the part with
most direct constraints; every edge is oriented away from it.

Free degrees of freedom. A leg screwed into a seat stays free to spin about its
axis, but once screwed in it does not move, so the spin is only seen *before*
the constraint is established. Rule: in the approach window (the contiguous
steps before the onset in which the child is within ``approach_radius`` of its
constrained position), the incremental rotations of the child in the parent are
expressed in the child's frame; if their dominant axis carries at least 80 % of
the rotation and the child turned about it by more than ``full_turn`` (90° by
default) in total, that rotation is free over ``[−π, π]``. The axis is snapped to
the child's nearest frame axis when within 15° (the constraint frame is then the
identity and the DOF is ``rx``, ``ry`` or ``rz``); otherwise the constraint frame
turns ``x`` onto the axis and the DOF is ``rx``. Translations during insertion
are not free DOFs of the assembled constraint: the part is locked once in.
A constraint with a free rotation is ``revolute``, otherwise ``fixed``.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from thirdhand import se3
from thirdhand.constraints.hmm import HMMParams, fit_hmm
from thirdhand.constraints.select import fit_constraint
from thirdhand.constraints.types import DOF_NAMES, Constraint, ConstraintFitError
from thirdhand.demonstration import Demonstration

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


@dataclass
class ConstraintInstance:
    """A constraint detected in one demonstration.

    Attributes
    ----------
    parent, child : str
        Body names; the pose is the child's in the parent's frame.
    type : str
        ``fixed`` or ``revolute`` (a free spin), see the module notes.
    start : float
        Seconds: when the constraint is established.
    end : float or None
        Seconds: when it is removed; None if it lasts to the end of the recording.
    pos : ndarray, shape (3,)
        Child position in the parent, metres (EM estimate over the constrained steps).
    quat : ndarray, shape (4,)
        Child orientation in the parent, x y z w.
    frame_pos, frame_quat : ndarray, shape (3,) and (4,)
        The constraint frame as a pose in the child frame (identity unless a free
        axis is not one of the child's axes).
    ranges : ndarray, shape (6, 2)
        ``[min, max]`` of tx ty tz (m), rx ry rz (rad) in the constraint frame.
    confidence : float
        Mean posterior of the constrained state over the instance's steps, in [0, 1].
    spin : float
        Total rotation about the dominant axis in the approach window, radians.
    demo : str or None
        Name of the demonstration it comes from.
    symbol : str or None
        Filled by :mod:`thirdhand.plan.symbols`.
    """

    parent: str
    child: str
    type: str
    start: float
    end: float | None
    pos: FloatArray
    quat: FloatArray
    frame_pos: FloatArray = field(default_factory=lambda: np.zeros(3))
    frame_quat: FloatArray = field(default_factory=lambda: np.array([0.0, 0.0, 0.0, 1.0]))
    ranges: FloatArray = field(default_factory=lambda: np.zeros((6, 2)))
    confidence: float = 1.0
    spin: float = 0.0
    demo: str | None = None
    symbol: str | None = None

    @property
    def free_dofs(self) -> list[str]:
        """Names of the DOFs whose range is not ``[0, 0]``."""
        return [n for n, (lo, hi) in zip(DOF_NAMES, self.ranges, strict=True) if lo != hi]

    def to_dict(self) -> dict[str, Any]:
        """JSON-able form."""
        return {
            "parent": self.parent,
            "child": self.child,
            "type": self.type,
            "start": self.start,
            "end": self.end,
            "pos": self.pos.tolist(),
            "quat": self.quat.tolist(),
            "frame": {"pos": self.frame_pos.tolist(), "quat": self.frame_quat.tolist()},
            "ranges": {n: r.tolist() for n, r in zip(DOF_NAMES, self.ranges, strict=True)},
            "confidence": self.confidence,
            "spin_deg": math.degrees(self.spin),
            "symbol": self.symbol,
        }


@dataclass
class DetectionResult:
    """Constraint states of every part pair over time, and the instances found.

    Attributes
    ----------
    times : ndarray, shape (n_steps,), seconds
        Centres of the latent steps.
    pairs : list of (str, str)
        Part pairs ``(a, b)``; the HMM tracks ``b`` in ``a``.
    posterior : ndarray, shape (n_pairs, n_steps)
        ``p(constrained)``.
    instances : list of ConstraintInstance
        Direct constraints, in order of creation.
    root : str or None
        The base of the assembly.
    params : HMMParams
        The EM-learned HMM parameters.
    """

    times: FloatArray
    pairs: list[tuple[str, str]]
    posterior: FloatArray
    instances: list[ConstraintInstance]
    root: str | None
    params: HMMParams

    def pair_posterior(self, a: str, b: str) -> FloatArray:
        """``p(constrained)`` of the unordered pair {a, b}, shape (n_steps,)."""
        for k, (x, y) in enumerate(self.pairs):
            if {x, y} == {a, b}:
                return self.posterior[k]
        raise ConstraintFitError(f"pair ({a!r}, {b!r}) was not tracked")


@dataclass(frozen=True)
class DetectOptions:
    """Settings of :func:`detect_constraints`.

    Attributes
    ----------
    step : float
        Latent step, seconds (ignored when segmentation phases give the steps).
    min_duration : float
        Shortest constrained run kept, seconds (a run reaching the end of the
        recording is always kept).
    same_pose : tuple of (float, float)
        Consecutive constrained runs of a pair whose poses agree within these
        bounds (metres, radians) are one constraint.
    simultaneity : float
        Runs of several pairs starting within this many seconds of each other are
        candidates for one new constraint (the child joins a rigid group of parts:
        every pair with a member starts together).
    near_ratio : float
        Parent choice: among the parts of a group within ``near_ratio`` times the
        nearest part's distance (plus 1 cm) of the child, the one with most direct
        constraints so far (the hub: a chair's back goes onto the seat, not onto
        the leg next to it; a screw onto its board, not onto the box's base).
    co_motion : tuple of (float, float)
        World motion of a part during a run that counts as co-motion, metres and
        radians.
    approach_motion : tuple of (float, float)
        Relative motion in the ``approach_window`` before a run that counts as an
        approach, metres and radians.
    approach_window : float
        Seconds before a run's start searched for relative motion.
    contact_distance : float
        Largest distance between the origins of two parts an approach may join, metres.
    approach_radius : float
        Distance of the child from its constrained position within which its
        rotations count towards a free spin, metres.
    full_turn : float
        Rotation about one axis, radians, beyond which that rotation is free over
        ``[−π, π]``.
    n_iter : int
        EM iterations.
    max_poses : int
        Most constraint poses per pair (an assembly repeated after taking it apart
        puts a leg in another slot).
    """

    step: float = 0.1
    min_duration: float = 0.5
    simultaneity: float = 1.0
    same_pose: tuple[float, float] = (0.02, math.radians(10.0))
    near_ratio: float = 1.5
    co_motion: tuple[float, float] = (0.03, math.radians(10.0))
    approach_motion: tuple[float, float] = (0.01, math.radians(5.0))
    approach_window: float = 3.0
    contact_distance: float = 0.5
    approach_radius: float = 0.05
    full_turn: float = math.radians(90.0)
    n_iter: int = 8
    max_poses: int = 3


def step_edges(t: FloatArray, step: float) -> FloatArray:
    """Edges of latent steps of ``step`` seconds covering ``t``, shape (n_steps + 1,)."""
    n = max(1, math.ceil((t[-1] - t[0]) / step - 1e-9))
    return np.asarray(t[0] + step * np.arange(n + 1), dtype=np.float64)


def step_poses(
    demo: Demonstration, body: str, edges: FloatArray, *, min_fraction: float = 0.5
) -> tuple[FloatArray, FloatArray]:
    """Mean pose of a body per latent step, world frame.

    Returns
    -------
    pos : ndarray, shape (n_steps, 3), metres; NaN where fewer than ``min_fraction``
        of the step's frames are valid (a mean of a few samples is too noisy to
        compare with the others).
    quat : ndarray, shape (n_steps, 4), x y z w, sign-continuous; NaN likewise.
    """
    n = edges.size - 1
    idx = np.clip(np.searchsorted(edges, demo.t, side="right") - 1, 0, n - 1)
    valid = demo.valid(body)
    frames = np.bincount(idx, minlength=n).astype(np.float64)
    min_samples = np.maximum(1.0, np.ceil(min_fraction * frames))
    counts = np.bincount(idx[valid], minlength=n).astype(np.float64)
    pos = np.zeros((n, 3))
    quat = np.zeros((n, 4))
    q = se3.quat_make_continuous(demo.quat(body), valid)
    for k in range(3):
        pos[:, k] = np.bincount(idx[valid], weights=demo.pos(body)[valid, k], minlength=n)
    for k in range(4):
        quat[:, k] = np.bincount(idx[valid], weights=q[valid, k], minlength=n)
    ok = counts >= min_samples
    pos = np.where(ok[:, None], pos / np.maximum(counts, 1)[:, None], np.nan)
    norm = np.linalg.norm(quat, axis=1)
    quat = np.where((ok & (norm > 1e-12))[:, None], quat / np.maximum(norm, 1e-12)[:, None], np.nan)
    return pos, quat


def _runs(mask: BoolArray) -> list[tuple[int, int]]:
    """Half-open index runs ``[lo, hi)`` where ``mask`` is true."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist(), strict=True))


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


def _on_joint(
    p: FloatArray, q: FloatArray, min_motion: tuple[float, float], share: float = 0.9
) -> Constraint | None:
    """The prismatic or revolute joint a span moves along, or None.

    The fixed, prismatic and revolute models are fitted; a joint must win, move
    by more than ``min_motion`` (metres or radians; see :func:`_min_joint_motion`)
    and turn by less than 300° (a hinge does not turn all the way round), and
    hold ``share`` of the valid steps within ``max(4 rms, 3 mm)`` and
    ``max(4 rms, 2°)`` of its path (the robust fit alone would accept a part
    carried away and back as outliers).
    """
    ok = np.all(np.isfinite(p), axis=1) & np.all(np.isfinite(q), axis=1)
    if ok.sum() < 10:
        return None
    try:
        c = fit_constraint(p[ok], q[ok], models=("fixed", "prismatic", "revolute"))
    except ConstraintFitError:
        return None
    span = c.ranges[:, 1] - c.ranges[:, 0]
    if c.type not in ("prismatic", "revolute") or not (
        span[:3].max() > min_motion[0] or span[3:].max() > min_motion[1]
    ):
        return None
    if span[3:].max() > math.radians(300.0):
        return None  # turned all the way round: a part being screwed in, not a hinge
    dp, dr = _joint_residuals(p[ok], q[ok], c)
    rms_rot = 0.0 if c.rms_rot is None else c.rms_rot
    good = (dp <= max(4 * c.rms_pos, 0.003)) & (dr <= max(4 * rms_rot, math.radians(2.0)))
    return c if good.mean() >= share else None


def _min_joint_motion(params: HMMParams) -> tuple[float, float]:
    """Smallest motion along a joint that makes it a joint: 2 cm or 15°, or ten times
    the learned noise when larger (a camera's wobble of a few degrees is not a hinge)."""
    return max(0.02, 10 * params.sigma_pos), max(math.radians(15.0), 10 * params.sigma_rot)


def _last_valid_pose(pos: FloatArray, quat: FloatArray) -> tuple[FloatArray, FloatArray]:
    ok = np.flatnonzero(np.all(np.isfinite(pos), axis=1) & np.all(np.isfinite(quat), axis=1))
    if ok.size == 0:
        return np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0])
    tail = ok[-5:]
    qm = quat[tail].sum(axis=0)
    return pos[tail].mean(axis=0), qm / np.linalg.norm(qm)


def _motion(pos: FloatArray, quat: FloatArray, lo: int, hi: int) -> tuple[float, float]:
    """Largest displacement (m) and rotation (rad) from the first valid pose in ``[lo, hi)``."""
    p, q = pos[lo:hi], quat[lo:hi]
    ok = np.all(np.isfinite(p), axis=1) & np.all(np.isfinite(q), axis=1)
    if ok.sum() < 2:
        return 0.0, 0.0
    p, q = p[ok], q[ok]
    dp = float(np.max(np.linalg.norm(p - p[0], axis=1)))
    dr = float(np.max(se3.quat_angle(q, q[0])))
    return dp, dr


def _held(phases: Any, body: str, t0: float, t1: float) -> bool:
    """Whether a hand of the segmentation holds ``body`` at some time in ``[t0, t1]``."""
    for h in getattr(phases, "hands", []):
        if h.object != body:
            continue
        for s, e in h.intervals:
            if s <= t1 and e >= t0:
                return True
    return False


def detect_constraints(
    demo: Demonstration,
    *,
    phases: Any = None,
    parts: Sequence[str] | None = None,
    options: DetectOptions | None = None,
    demo_name: str | None = None,
) -> DetectionResult:
    """Detect the constraints a person created between the parts of a demonstration.

    Parameters
    ----------
    demo : Demonstration
    phases : thirdhand.segment.SegmentationResult, optional
        Interaction phases of the same recording: their latent steps are used,
        and a hand holding the child around a run's start supports an approach.
    parts : sequence of str, optional
        Bodies considered (default: every body of kind ``part``, or every oriented
        body that is not a finger, hand or head when there is none).
    options : DetectOptions, optional
    demo_name : str, optional
        Stored in each instance.

    Returns
    -------
    DetectionResult

    Raises
    ------
    ConstraintFitError
        With fewer than two parts, or an unknown part name.
    """
    opt = DetectOptions() if options is None else options
    names = list(parts) if parts is not None else _default_parts(demo)
    for n in names:
        if n not in demo:
            raise ConstraintFitError(
                f"no body {n!r} in the recording; bodies are {', '.join(demo.body_names)}"
            )
    if len(names) < 2:
        raise ConstraintFitError(
            f"constraint detection needs at least two parts, got {len(names)} ({', '.join(names)})"
        )
    if phases is not None and len(getattr(phases, "edges", ())) >= 2:
        edges = np.asarray(phases.edges, dtype=np.float64)
    else:
        edges = step_edges(demo.t, opt.step)
    times = 0.5 * (edges[:-1] + edges[1:])
    world = {n: step_poses(demo, n, edges) for n in names}
    pairs = list(itertools.combinations(names, 2))
    rel_p = np.empty((len(pairs), times.size, 3))
    rel_q = np.empty((len(pairs), times.size, 4))
    th_p = np.empty((len(pairs), 3))
    th_q = np.empty((len(pairs), 4))
    for k, (a, b) in enumerate(pairs):
        p, q = se3.relative_pose(world[a][0], world[a][1], world[b][0], world[b][1])
        bad = ~(np.all(np.isfinite(p), axis=1) & np.all(np.isfinite(q), axis=1))
        p[bad] = np.nan
        q[bad] = np.nan
        rel_p[k], rel_q[k] = p, q
        th_p[k], th_q[k] = _last_valid_pose(p, q)
    posterior, params, th_p, th_q = fit_hmm(rel_p, rel_q, th_p, th_q, n_iter=opt.n_iter)
    layers = [(k, posterior[k], th_p[k]) for k in range(len(pairs))]
    step = float(np.median(np.diff(edges)))
    layers += _further_poses(posterior, rel_p, rel_q, pairs, world, params, opt, step)
    t_end = float(demo.t[-1])
    candidates: list[_Run] = []
    for k, post, theta in layers:
        a, b = pairs[k]
        held = post > 0.5
        runs = _runs(held)
        for lo, hi, joint in _merge_same_pose(
            runs, rel_p[k], rel_q[k], held, theta, opt.same_pose, _min_joint_motion(params)
        ):
            reaches_end = hi >= times.size - 1 or not np.any(
                np.all(np.isfinite(rel_p[k, hi:]), axis=1)
            )
            if times[hi - 1] - times[lo] < opt.min_duration and not reaches_end:
                continue
            if _supported(k, lo, hi, a, b, pairs, world, rel_p, rel_q, times, phases, opt):
                conf = float(np.nanmean(post[lo:hi]))
                start = _joint_start(rel_p[k], rel_q[k], lo, hi, params) if joint else None
                lo_j = lo if start is None else start
                candidates.append(_Run(float(edges[lo_j]), k, lo_j, hi, conf, joint, held))
    candidates.sort(key=lambda c: (c.start, c.k))
    motion = {n: _path_length(*world[n]) for n in names}
    instances, root = _assign_parents(
        candidates, pairs, th_p, rel_p, rel_q, times, t_end, motion, opt
    )
    for inst in instances:
        inst.demo = demo_name
    for k, post, _ in layers[len(pairs) :]:
        posterior[k] = np.fmax(posterior[k], post)
    return DetectionResult(
        times=times,
        pairs=pairs,
        posterior=posterior,
        instances=instances,
        root=root,
        params=params,
    )


def _further_poses(
    posterior: FloatArray,
    rel_p: FloatArray,
    rel_q: FloatArray,
    pairs: list[tuple[str, str]],
    world: dict[str, tuple[FloatArray, FloatArray]],
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


def _path_length(pos: FloatArray, quat: FloatArray) -> float:
    """Distance a body travels in the world, metres (over valid consecutive steps)."""
    d = np.linalg.norm(np.diff(pos, axis=0), axis=1)
    return float(np.nansum(d))


def _joint_residuals(p: FloatArray, q: FloatArray, c: Constraint) -> tuple[FloatArray, FloatArray]:
    """Distance (m) and angle (rad) of each pose from a prismatic or revolute joint's path."""
    axis = np.asarray(c.axis, dtype=np.float64)
    final_q = np.asarray(c.quat, dtype=np.float64)
    # Orientation: the rotation from the final orientation, less its part about the axis
    # (a slide keeps the orientation; a hinge turns about the axis only).
    dq = se3.quat_multiply(q, se3.quat_conjugate(final_q))
    dq = dq * np.where(dq[:, 3:4] < 0, -1.0, 1.0)
    sin = np.linalg.norm(dq[:, :3], axis=1)
    ang = 2.0 * np.arctan2(sin, dq[:, 3])
    rv = np.where(sin[:, None] > 1e-12, dq[:, :3] / np.maximum(sin, 1e-12)[:, None], 0.0)
    rv = rv * ang[:, None]
    if c.type == "prismatic":
        d = p - c.pos
        off = d - (d @ axis)[:, None] * axis
        return np.linalg.norm(off, axis=1), np.linalg.norm(rv, axis=1)
    d = p - c.origin
    radial = np.linalg.norm(d - (d @ axis)[:, None] * axis, axis=1)
    r0 = 0.0 if c.radius is None else c.radius
    along = (p - c.pos) @ axis
    off_axis = rv - (rv @ axis)[:, None] * axis
    return np.abs(radial - r0) + np.abs(along), np.linalg.norm(off_axis, axis=1)


def _joint_start(p: FloatArray, q: FloatArray, lo: int, hi: int, params: HMMParams) -> int | None:
    """Start of an articulated constraint (a drawer in its rails, a lid on its pins).

    The constraint started as soon as the child's pose joined the joint's path:
    walking back from the span's start while the pose stays within
    ``max(5σ, 3 mm)`` and ``max(5σ, 2°)`` of it (short tracking gaps allowed).
    """
    c = _on_joint(p[lo:hi], q[lo:hi], _min_joint_motion(params))
    if c is None:
        return None
    tol_p = max(5 * params.sigma_pos, 0.003)
    tol_r = max(5 * params.sigma_rot, math.radians(2.0))
    dp, dr = _joint_residuals(p[:lo], q[:lo], c)
    on = (dp <= tol_p) & (dr <= tol_r)
    missing = ~(np.isfinite(dp) & np.isfinite(dr))
    i = lo - 1
    gap = 0
    while i >= 0 and (on[i] or (missing[i] and gap < 5)):
        gap = 0 if on[i] else gap + 1
        i -= 1
    return i + 1 + gap


def _default_parts(demo: Demonstration) -> list[str]:
    parts = demo.bodies_of_kind("part")
    if len(parts) >= 2:
        return parts
    return [b.name for b in demo.bodies if b.kind not in ("finger", "hand", "head") and b.oriented]


def _supported(
    k: int,
    lo: int,
    hi: int,
    a: str,
    b: str,
    pairs: list[tuple[str, str]],
    world: dict[str, tuple[FloatArray, FloatArray]],
    rel_p: FloatArray,
    rel_q: FloatArray,
    times: FloatArray,
    phases: Any,
    opt: DetectOptions,
) -> bool:
    """Whether a constrained run has co-motion or approach evidence (module notes)."""
    for body in (a, b):
        dp, dr = _motion(*world[body], lo, hi)
        if dp > opt.co_motion[0] or dr > opt.co_motion[1]:
            return True
    step = float(times[1] - times[0]) if times.size > 1 else 0.1
    w = max(1, round(opt.approach_window / step))
    before = max(0, lo - w)
    if before == lo:
        return False
    dp, dr = _motion(rel_p[k], rel_q[k], before, lo + 1)
    if not (dp > opt.approach_motion[0] or dr > opt.approach_motion[1]):
        return False
    pa = rel_p[k, lo:hi]
    dist = np.nanmedian(np.linalg.norm(pa, axis=1)) if np.any(np.isfinite(pa)) else np.inf
    if dist < opt.contact_distance:
        return True
    # Farther apart: only when the segmentation saw a hand bring one of them there.
    if phases is not None and getattr(phases, "hands", None):
        t0, t1 = times[before], times[min(hi, lo + w) - 1]
        return _held(phases, a, t0, t1) or _held(phases, b, t0, t1)
    return False


def _assign_parents(
    candidates: list[_Run],
    pairs: list[tuple[str, str]],
    th_p: FloatArray,
    rel_p: FloatArray,
    rel_q: FloatArray,
    times: FloatArray,
    t_end: float,
    motion: dict[str, float],
    opt: DetectOptions,
) -> tuple[list[ConstraintInstance], str | None]:
    """Keep, in time order, the runs that join two rigid groups of parts.

    The groups at a moment are the connected components of the direct constraints
    active then (started, not yet removed), so a part taken off and put back joins
    again. The root is the part with most direct constraints at the end of the
    recording (then most overall; a short spurious constraint, made and removed,
    must not make a leg the base); among equals, the one that travelled least in
    the world (the base stays put while parts are brought to it).
    """
    n_steps = times.size
    direct: list[_Run] = []
    degree: dict[str, int] = {}

    def groups(t: float) -> dict[str, int]:
        parent: dict[str, str] = {}

        def root_of(n: str) -> str:
            while parent.get(n, n) != n:
                n = parent[n]
            return n

        for c in direct:
            active = c.start <= t + 1e-9 and (c.hi >= n_steps - 1 or times[c.hi - 1] > t)
            if active:
                a, b = pairs[c.k]
                ra, rb = root_of(a), root_of(b)
                if ra != rb:
                    parent[rb] = ra
        names = {n for pr in pairs for n in pr}
        roots = sorted({root_of(n) for n in names})
        return {n: roots.index(root_of(n)) for n in names}

    # Runs starting within ``simultaneity`` seconds of each other are decided together.
    batches: list[list[_Run]] = []
    for c in candidates:
        if batches and c.start - batches[-1][0].start <= opt.simultaneity:
            batches[-1].append(c)
        else:
            batches.append([c])
    for batch in batches:
        t0 = max(c.start for c in batch)
        group = groups(t0)
        # The hub counts the constraints active now (a removed spurious one does not).
        active_degree: dict[str, int] = {}
        for d in direct:
            if d.hi >= n_steps - 1 or times[d.hi - 1] > t0:
                for n in pairs[d.k]:
                    active_degree[n] = active_degree.get(n, 0) + 1
        # Among runs joining the same two groups: the hub among the near parts.
        options: dict[tuple[int, int], list[tuple[float, int, _Run]]] = {}
        for c in batch:
            a, b = pairs[c.k]
            ga, gb = group[a], group[b]
            if ga != gb:
                hub = max(active_degree.get(a, 0), active_degree.get(b, 0))
                dist = float(np.linalg.norm(th_p[c.k]))
                options.setdefault((min(ga, gb), max(ga, gb)), []).append((dist, hub, c))
        best: dict[tuple[int, int], _Run] = {}
        for key, opts in options.items():
            near = min(o[0] for o in opts) * opt.near_ratio + 0.01
            pick = min((o for o in opts if o[0] <= near), key=lambda o: (-o[1], o[0], o[2].k))
            best[key] = pick[2]
        for _, c in sorted(best.items()):
            a, b = pairs[c.k]
            group = groups(t0)
            if group[a] == group[b]:
                continue
            direct.append(c)
            for n in (a, b):
                degree[n] = degree.get(n, 0) + 1
    if not direct:
        return [], None
    final: dict[str, int] = {}
    for c in direct:
        if c.hi >= n_steps - 1:
            for n in pairs[c.k]:
                final[n] = final.get(n, 0) + 1
    root = min(sorted(degree), key=lambda n: (-final.get(n, 0), -degree[n], motion.get(n, 0.0)))
    parent_of = _orient([pairs[c.k] for c in direct], root)
    out = []
    for c in direct:
        a, b = pairs[c.k]
        child = b if parent_of.get(b) == a else a
        parent = a if child == b else b
        out.append(_instance(c, parent, child, pairs, th_p, rel_p, rel_q, times, t_end, opt))
    return out, root


def _orient(edges: list[tuple[str, str]], root: str) -> dict[str, str]:
    """Parent of each part in the tree of direct constraints, by breadth-first search."""
    adj: dict[str, list[str]] = {}
    for a, b in edges:
        adj.setdefault(a, []).append(b)
        adj.setdefault(b, []).append(a)
    parent: dict[str, str] = {}
    seen = {root}
    frontier = [root]
    while frontier:
        nxt = []
        for n in frontier:
            for m in sorted(adj.get(n, [])):
                if m not in seen:
                    seen.add(m)
                    parent[m] = n
                    nxt.append(m)
        frontier = nxt
    # Components without the root: each edge oriented as the pair is named.
    for a, b in edges:
        if a not in seen and b not in seen:
            parent[b] = a
            seen |= {a, b}
    return parent


def _instance(
    c: _Run,
    parent: str,
    child: str,
    pairs: list[tuple[str, str]],
    th_p: FloatArray,
    rel_p: FloatArray,
    rel_q: FloatArray,
    times: FloatArray,
    t_end: float,
    opt: DetectOptions,
) -> ConstraintInstance:
    k, lo, hi = c.k, c.lo, c.hi
    a, _ = pairs[k]
    p_run, q_run = rel_p[k], rel_q[k]
    pos, quat = _run_pose(p_run[lo:hi], q_run[lo:hi], th_p[k], c.held[lo:hi])
    if parent != a:
        pos, quat = se3.pose_invert(pos, quat)
        p_run, q_run = se3.pose_invert(rel_p[k], rel_q[k])
    step = float(times[1] - times[0]) if times.size > 1 else 0.1
    start = float(times[lo] - 0.5 * step)
    end = None if hi >= times.size - 1 else float(times[hi - 1] + 0.5 * step)
    frame_p = np.zeros(3)
    joint = _joint_dofs(p_run[lo:hi], q_run[lo:hi]) if c.joint else None
    if joint is not None:
        typ, frame_p, frame_q, ranges = joint
        spin = 0.0
    else:
        frame_q, ranges, spin = _free_spin(p_run, q_run, lo, pos, quat, opt)
        typ = "revolute" if np.any(ranges[3:, 1] > ranges[3:, 0]) else "fixed"
    return ConstraintInstance(
        parent=parent,
        child=child,
        type=typ,
        start=max(start, float(times[0])),
        end=None if end is None or end >= t_end else end,
        pos=pos,
        quat=quat,
        frame_pos=frame_p,
        frame_quat=frame_q,
        ranges=ranges,
        confidence=c.conf,
        spin=spin,
    )


def _joint_dofs(
    p: FloatArray, q: FloatArray
) -> tuple[str, FloatArray, FloatArray, FloatArray] | None:
    """Type, constraint frame (position and quaternion in the child frame) and ranges of
    an articulated span, fitted in the parent's frame.

    The frame is snapped to the child's axes when the joint axis is within 15° of
    one of them (a drawer sliding along its own x): its orientation is then the
    identity and the range sits on that axis (negated for an opposite axis). A
    hinge keeps its axis point as the frame's position.
    """
    try:
        fit = fit_constraint(p, q, models=("fixed", "prismatic", "revolute"))
    except ConstraintFitError:
        return None
    if fit.type not in ("prismatic", "revolute") or fit.quat is None:
        return None
    fp, fq = fit.frame_in_child()
    dof = 0 if fit.type == "prismatic" else 3
    lo, hi = (float(v) for v in fit.ranges[dof])
    axis = se3.quat_rotate(fq, np.array([1.0, 0.0, 0.0]))
    k = int(np.argmax(np.abs(axis)))
    ranges = np.zeros((6, 2))
    if abs(axis[k]) >= math.cos(math.radians(15.0)):
        sign = 1.0 if axis[k] > 0 else -1.0
        ranges[dof + k] = sorted((sign * lo, sign * hi))
        origin = np.zeros(3) if fit.type == "prismatic" else np.asarray(fp, dtype=np.float64)
        return fit.type, origin, np.array([0.0, 0.0, 0.0, 1.0]), ranges
    ranges[dof] = (lo, hi)
    return fit.type, np.asarray(fp, dtype=np.float64), np.asarray(fq, dtype=np.float64), ranges


def _run_pose(
    p: FloatArray, q: FloatArray, fallback: FloatArray, mask: BoolArray | None = None
) -> tuple[FloatArray, FloatArray]:
    """Mean pose of the valid (and ``mask``-ed) steps of a run (chordal quaternion mean)."""
    ok = np.all(np.isfinite(p), axis=1) & np.all(np.isfinite(q), axis=1)
    if mask is not None and np.any(ok & mask):
        ok &= mask
    if not np.any(ok):
        return fallback.copy(), np.array([0.0, 0.0, 0.0, 1.0])
    qq = q[ok]
    qq = qq * np.sign(np.sum(qq * qq[0], axis=1))[:, None]
    m = qq.sum(axis=0)
    return p[ok].mean(axis=0), m / np.linalg.norm(m)


def _free_spin(
    p: FloatArray,
    q: FloatArray,
    lo: int,
    pos: FloatArray,
    quat: FloatArray,
    opt: DetectOptions,
) -> tuple[FloatArray, FloatArray, float]:
    """Constraint frame (quaternion in the child frame), DOF ranges and spin (module notes)."""
    ranges = np.zeros((6, 2))
    identity = np.array([0.0, 0.0, 0.0, 1.0])
    near = np.linalg.norm(p[:lo] - pos, axis=1) < opt.approach_radius
    near &= np.all(np.isfinite(q[:lo]), axis=1)
    # The contiguous approach window ending at the onset (short tracking gaps allowed).
    i = lo - 1
    gap = 0
    while i >= 0 and (near[i] or (gap < 5 and not np.isfinite(p[i, 0]))):
        gap = 0 if near[i] else gap + 1
        i -= 1
    idx = np.flatnonzero(near[i + 1 : lo]) + i + 1
    if idx.size < 3:
        return identity, ranges, 0.0
    qw = se3.quat_make_continuous(q[idx])
    # Incremental rotations in the child frame: log(q_{t-1}^-1 q_t).
    dq = se3.quat_multiply(se3.quat_conjugate(qw[:-1]), qw[1:])
    dq = dq * np.where(dq[:, 3:4] < 0, -1.0, 1.0)
    ang = 2.0 * np.arctan2(np.linalg.norm(dq[:, :3], axis=1), dq[:, 3])
    sin = np.linalg.norm(dq[:, :3], axis=1)
    rv = np.where(sin[:, None] > 1e-12, dq[:, :3] / np.maximum(sin, 1e-12)[:, None], 0.0)
    rv = rv * ang[:, None]
    energy = float(np.sum(rv**2))
    if energy <= 0.0:
        return identity, ranges, 0.0
    _, s, vt = np.linalg.svd(rv, full_matrices=False)
    axis = vt[0]
    share = float(s[0] ** 2 / energy)
    turned = np.cumsum(rv @ axis)
    spin = float(turned.max() - min(0.0, turned.min()))
    if share < 0.8 or spin <= opt.full_turn:
        return identity, ranges, spin
    k = int(np.argmax(np.abs(axis)))
    if abs(axis[k]) >= math.cos(math.radians(15.0)):
        ranges[3 + k] = (-math.pi, math.pi)
        return identity, ranges, spin
    ranges[3] = (-math.pi, math.pi)
    a = axis / np.linalg.norm(axis)
    helper = np.array([0.0, 0.0, 1.0]) if abs(a[2]) < 0.9 else np.array([0.0, 1.0, 0.0])
    y = np.cross(helper, a)
    y /= np.linalg.norm(y)
    frame = se3.quat_from_matrix(np.stack([a, y, np.cross(a, y)], axis=1))
    return frame, ranges, spin
