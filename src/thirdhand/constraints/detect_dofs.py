"""Articulated constraints and free DOFs: joints a span moves along, free spins."""

from __future__ import annotations

import math

import numpy as np

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.constraints.detect_types import DetectOptions
from thirdhand.constraints.hmm import HMMParams
from thirdhand.constraints.noise import estimate_noise
from thirdhand.constraints.robust import prepare_track
from thirdhand.constraints.select import fit_constraint
from thirdhand.constraints.types import ConstraintFitError, JointFit, NoiseModel


def _step_noise(p: FloatArray, q: FloatArray) -> NoiseModel:
    """Noise bounds of a pair's step-mean track: estimated from it, at least the mocap preset.

    The estimate (:mod:`thirdhand.constraints.noise`) reads a camera's noise off
    the track; on a noise-free or mocap recording it is tiny, and the step means
    themselves then err by more (a mean of points of an arc lies inside the arc),
    so the bounds never go below :class:`NoiseModel`'s 1 mm and 0.5°.
    """
    base = NoiseModel()
    try:
        p_ok, q_ok = prepare_track(p, q)
    except ConstraintFitError:
        return base
    return estimate_noise(p_ok, q_ok).at_least(base)


def _on_joint(
    p: FloatArray, q: FloatArray, min_motion: tuple[float, float], share: float = 0.9
) -> JointFit | None:
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
        c = fit_constraint(
            p[ok], q[ok], models=("fixed", "prismatic", "revolute"), noise=_step_noise(p[ok], q[ok])
        )
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


def _joint_residuals(p: FloatArray, q: FloatArray, c: JointFit) -> tuple[FloatArray, FloatArray]:
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


def _joint_dofs(
    p: FloatArray, q: FloatArray
) -> tuple[str, FloatArray, FloatArray, FloatArray, JointFit | None] | None:
    """Type, constraint frame (position and quaternion in the child frame), ranges and
    runner-up (the next most probable type, fitted) of an articulated span, fitted in
    the parent's frame.

    The frame is snapped to the child's axes when the joint axis is within 15° of
    one of them (a drawer sliding along its own x): its orientation is then the
    identity and the range sits on that axis (negated for an opposite axis). A
    hinge keeps its axis point as the frame's position.
    """
    try:
        ok = np.all(np.isfinite(p), axis=1) & np.all(np.isfinite(q), axis=1)
        fit = fit_constraint(
            p, q, models=("fixed", "prismatic", "revolute"), noise=_step_noise(p[ok], q[ok])
        )
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
        return fit.type, origin, np.array([0.0, 0.0, 0.0, 1.0]), ranges, fit.runner_up
    ranges[dof] = (lo, hi)
    frame_p, frame_q = np.asarray(fp, dtype=np.float64), np.asarray(fq, dtype=np.float64)
    return fit.type, frame_p, frame_q, ranges, fit.runner_up


#: Spacing of the samples a free spin is measured on, seconds (sensor noise summed over
#: every sample of a fast tracker would drown the turn's share of the rotation).
SPIN_SPACING = 0.05


def _raw_approach(
    raw: tuple[FloatArray, FloatArray, FloatArray, FloatArray],
    lo: int,
    pos: FloatArray,
    opt: DetectOptions,
) -> FloatArray:
    """Orientations (m, 4) of the approach on the recording's samples: the run of samples
    within ``approach_radius`` of ``pos`` that ends at the onset step ``lo``, one per
    :data:`SPIN_SPACING`, sign-continuous."""
    t_raw, p_raw, q_raw, edges = raw
    before = np.flatnonzero(t_raw < edges[lo])
    if before.size == 0:
        return np.zeros((0, 4))
    far = np.linalg.norm(p_raw[before] - pos, axis=1) >= opt.approach_radius
    start = int(np.flatnonzero(far)[-1]) + 1 if far.any() else 0
    run = before[start:]
    if run.size == 0:
        return np.zeros((0, 4))
    grid = np.arange(t_raw[run[0]], t_raw[run[-1]] + 1e-9, SPIN_SPACING)
    pick = np.unique(
        np.append(np.searchsorted(t_raw[run], grid), run.size - 1).clip(0, run.size - 1)
    )
    return np.asarray(se3.quat_make_continuous(q_raw[run[pick]]), dtype=np.float64)


def _step_approach(
    p: FloatArray, q: FloatArray, lo: int, pos: FloatArray, opt: DetectOptions
) -> FloatArray:
    """Orientations (m, 4) of the approach on the step means: the contiguous steps before
    the onset ``lo`` within ``approach_radius`` of ``pos`` (short tracking gaps allowed),
    sign-continuous."""
    near = np.linalg.norm(p[:lo] - pos, axis=1) < opt.approach_radius
    near &= np.all(np.isfinite(q[:lo]), axis=1)
    i = lo - 1
    gap = 0
    while i >= 0 and (near[i] or (gap < 5 and not np.isfinite(p[i, 0]))):
        gap = 0 if near[i] else gap + 1
        i -= 1
    idx = np.flatnonzero(near[i + 1 : lo]) + i + 1
    return np.asarray(se3.quat_make_continuous(q[idx]), dtype=np.float64)


def _free_spin(
    p: FloatArray,
    q: FloatArray,
    lo: int,
    pos: FloatArray,
    quat: FloatArray,
    opt: DetectOptions,
    raw: tuple[FloatArray, FloatArray, FloatArray, FloatArray] | None = None,
) -> tuple[FloatArray, FloatArray, float]:
    """Constraint frame (quaternion in the child frame), DOF ranges and spin (module notes).

    The approach is read off ``raw`` when given (the recording's valid samples of the
    same relative pose: times (n,), positions (n, 3), quaternions (n, 4), and the step
    edges (n_steps + 1,); :func:`_raw_approach`), else off the step means ``p``, ``q``,
    which can average a spinning part away.
    """
    ranges = np.zeros((6, 2))
    identity = np.array([0.0, 0.0, 0.0, 1.0])
    if raw is not None:
        qw = _raw_approach(raw, lo, pos, opt)
    else:
        qw = _step_approach(p, q, lo, pos, opt)
    if len(qw) < 3:
        return identity, ranges, 0.0
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
