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
samples of the recording before the onset step in which the child is within
``approach_radius`` of its constrained position, one per 0.05 s; not the step
means, which on an interaction phase's long latent steps average a fast turn
away), the incremental rotations of the child in the parent are
expressed in the child's frame; if their dominant axis carries at least 80 % of
the rotation and the child turned about it by more than ``full_turn`` (90° by
default) in total, that rotation is free over ``[−π, π]``. The axis is snapped to
the child's nearest frame axis when within 15° (the constraint frame is then the
identity and the DOF is ``rx``, ``ry`` or ``rz``); otherwise the constraint frame
turns ``x`` onto the axis and the DOF is ``rx``. Translations during insertion
are not free DOFs of the assembled constraint: the part is locked once in.
A constraint with a free rotation is ``revolute``, otherwise ``fixed``.

Modules: the result and option types live in :mod:`~thirdhand.constraints.detect_types`,
latent steps in :mod:`~thirdhand.constraints.detect_steps`, constrained runs and their
evidence in :mod:`~thirdhand.constraints.detect_runs`, joints and free DOFs in
:mod:`~thirdhand.constraints.detect_dofs`, the assembly tree in
:mod:`~thirdhand.constraints.detect_parents`; all public names are importable from here.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from thirdhand import se3
from thirdhand.constraints.detect_dofs import _joint_start, _min_joint_motion
from thirdhand.constraints.detect_parents import _assign_parents
from thirdhand.constraints.detect_runs import (
    _further_poses,
    _merge_same_pose,
    _Run,
    _supported,
    first_seen,
)
from thirdhand.constraints.detect_steps import (
    _last_valid_pose,
    _path_length,
    _runs,
    step_edges,
    step_poses,
)
from thirdhand.constraints.detect_types import (
    ConstraintInstance,
    DetectionResult,
    DetectOptions,
    PairTracks,
)
from thirdhand.constraints.hmm import fit_hmm
from thirdhand.constraints.types import ConstraintFitError
from thirdhand.demonstration import Demonstration

if TYPE_CHECKING:
    from thirdhand.segment.pipeline import SegmentationResult


def detect_constraints(
    demo: Demonstration,
    *,
    phases: SegmentationResult | None = None,
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
        got = f"got {len(names)}" + (f" ({', '.join(names)})" if names else "")
        if parts is None:
            got += f"; the recording's bodies: {_describe_bodies(demo)}"
            if len(demo.body_names) == 1:
                got += "; one track of an articulated object: `thirdhand constraints fit`"
        raise ConstraintFitError(f"constraint detection needs at least two parts, {got}")
    if phases is not None and len(phases.edges) >= 2:
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
    tracks = PairTracks(times, pairs, world, rel_p, rel_q, phases, demo=demo, edges=edges)
    posterior, params, th_p, th_q = fit_hmm(rel_p, rel_q, th_p, th_q, n_iter=opt.n_iter)
    layers = [(k, posterior[k], th_p[k]) for k in range(len(pairs))]
    step = float(np.median(np.diff(edges)))
    layers += _further_poses(tracks, posterior, params, opt, step)
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
            if _supported(tracks, k, lo, hi, opt):
                conf = float(np.nanmean(post[lo:hi]))
                start = _joint_start(rel_p[k], rel_q[k], lo, hi, params) if joint else None
                # made at the latest when first seen made (hidden steps before it carry
                # the chain's state, not evidence)
                lo_j = first_seen(rel_p[k], rel_q[k], lo, hi) if start is None else start
                candidates.append(_Run(float(edges[lo_j]), k, lo_j, hi, conf, joint, held))
    candidates.sort(key=lambda c: (c.start, c.k))
    motion = {n: _path_length(*world[n]) for n in names}
    instances, root = _assign_parents(
        tracks, candidates, th_p, t_end, motion, opt, (params.sigma_pos, params.sigma_rot)
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


def _describe_bodies(demo: Demonstration, most: int = 6) -> str:
    """``"001 (part, position only), lh (hand)"``: the bodies and why they are not parts."""
    out = []
    for b in demo.bodies[:most]:
        what = b.kind if b.oriented else f"{b.kind}, position only"
        out.append(f"{b.name} ({what})")
    more = len(demo.bodies) - most
    return ", ".join(out) + (f" and {more} more" if more > 0 else "") if out else "none"


def _default_parts(demo: Demonstration) -> list[str]:
    parts = demo.bodies_of_kind("part")
    if len(parts) >= 2:
        return parts
    return [b.name for b in demo.bodies if b.kind not in ("finger", "hand", "head") and b.oriented]


__all__ = [
    "ConstraintInstance",
    "DetectOptions",
    "DetectionResult",
    "detect_constraints",
    "step_edges",
    "step_poses",
]
