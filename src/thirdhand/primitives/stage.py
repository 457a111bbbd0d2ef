"""The primitives stage: one pose DMP and one ProMP per constraint, from demonstrations.

Everything is in the parent part's frame: the start is wherever the child is
relative to the parent, the goal is the constraint pose, so a primitive
transfers when the parent is elsewhere (:func:`rollout_in_world`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.demonstration import ConstraintEvent, Demonstration
from thirdhand.primitives.align import average
from thirdhand.primitives.checks import PrimitiveError
from thirdhand.primitives.promp import ProMP
from thirdhand.primitives.quaternion_dmp import PoseDMP
from thirdhand.primitives.segments import ConstraintSegment, group_segments, split_segments
from thirdhand.primitives.serialize import pose_dmp_to_dict, promp_to_dict

if TYPE_CHECKING:
    from thirdhand.primitives.skill_library import SkillLibrary
    from thirdhand.task.stages import PrimitiveRecord, PrimitivesBlock


SCHEMA = "thirdhand.primitives/1"

#: Default DMP weights per second of motion.
WEIGHTS_PER_SECOND = 15.0


@dataclass
class ConstraintPrimitive:
    """Learnt motion for one constraint (child pose in the parent frame).

    Attributes
    ----------
    key, parent, child, type : str
    goal_pos : ndarray, shape (3,), metres, parent frame
    goal_quat : ndarray, shape (4,), x y z w, parent frame
    dmp : PoseDMP
        Learnt on the aligned average of the segments.
    promp : ProMP
        Over ``[x, y, z, qx, qy, qz, qw]`` (quaternions sign-aligned to the goal).
    n_examples : int
    imitation_pos_m, imitation_rot_deg : float
        Largest error of the DMP's rollout against what it was fit to (the
        averaged segment, smoothed).
    raw_pos_m, raw_rot_deg : float
        Largest error against the unsmoothed average (includes tracker noise).
    """

    key: str
    parent: str
    child: str
    type: str
    goal_pos: FloatArray
    goal_quat: FloatArray
    dmp: PoseDMP
    promp: ProMP
    n_examples: int
    imitation_pos_m: float
    imitation_rot_deg: float
    raw_pos_m: float
    raw_rot_deg: float

    def to_dict(self) -> dict[str, Any]:
        """JSON-able parameters (a task file's ``stages.primitives.constraints[key]``)."""
        return {
            "parent": self.parent,
            "child": self.child,
            "type": self.type,
            "frame": "parent",
            "goal": {"pos": self.goal_pos.tolist(), "quat": self.goal_quat.tolist()},
            "n_examples": self.n_examples,
            "imitation_error": {"pos_m": self.imitation_pos_m, "rot_deg": self.imitation_rot_deg},
            "raw_error": {"pos_m": self.raw_pos_m, "rot_deg": self.raw_rot_deg},
            "dmp": pose_dmp_to_dict(self.dmp),
            "promp": promp_to_dict(self.promp),
        }

    def record(self) -> PrimitiveRecord:
        """The typed task-file record (:class:`~thirdhand.task.stages.PrimitiveRecord`)."""
        from thirdhand.task.stages import PrimitiveRecord

        return PrimitiveRecord.model_validate(self.to_dict())


def _goal(segments: Sequence[ConstraintSegment]) -> tuple[FloatArray, FloatArray]:
    pos = np.mean([s.event.pos for s in segments], axis=0)
    qs = np.array([s.event.quat for s in segments], dtype=np.float64)
    qs[qs @ qs[0] < 0.0] *= -1.0
    q = qs.mean(axis=0)
    return pos, q / np.linalg.norm(q)


def fit_constraint_primitive(
    segments: Sequence[ConstraintSegment],
    *,
    n_weights: int | None = None,
    promp_weights: int = 10,
    align: Literal["phase", "dtw"] = "phase",
    orientation: Literal["quaternion", "seven"] = "quaternion",
    smooth: float | None = 0.15,
) -> ConstraintPrimitive:
    """Average the segments of one constraint and learn a pose DMP and a ProMP.

    Parameters
    ----------
    segments : sequence of ConstraintSegment
        Examples of the same constraint (same parent, child frame semantics).
    n_weights : int, optional
        RBFs per DMP dimension; default ``WEIGHTS_PER_SECOND`` per second of the
        averaged motion, at least 30 (assembly motions of 10 s with re-grasps
        need over 100 for millimetre imitation).
    promp_weights : int
        RBFs per ProMP dimension.
    align : {"phase", "dtw"}
        How the examples are aligned before averaging.
    orientation : {"quaternion", "seven"}
        Orientation DMP (see :class:`PoseDMP`).
    smooth : float or None
        Savitzky–Golay window (cubic), seconds, applied to the average before the
        DMP fit: the DMP needs accelerations, and differentiating tracker noise
        twice (1 mm at 120 Hz is ~35 m/s²) would otherwise drown the forcing term.
        None fits the raw average. The imitation error is measured against the
        unsmoothed average.
    """
    if not segments:
        raise PrimitiveError("constraint primitive: no segment given")
    goal_pos, goal_quat = _goal(segments)
    tracks = []
    for s in segments:
        q = se3.quat_make_continuous(s.quat)
        if float(q[-1] @ goal_quat) < 0.0:
            q = -q
        tracks.append((s.t, np.concatenate([s.pos, q], axis=1)))
    t, y = average(tracks, method=align, quaternion_columns=slice(3, 7))
    if n_weights is None:
        n_weights = max(30, round(WEIGHTS_PER_SECOND * float(t[-1])))
    y_fit = y if smooth is None else smooth_track(t, y, smooth, quaternion_columns=slice(3, 7))
    dmp = PoseDMP(n_weights, orientation=orientation).fit(
        t, y_fit[:, :3], y_fit[:, 3:], name=segments[0].key
    )
    _, p, q = dmp.rollout()
    promp = ProMP(promp_weights).fit(tracks)
    ev = segments[0].event
    return ConstraintPrimitive(
        key=segments[0].key,
        parent=ev.parent,
        child=ev.child,
        type=ev.type,
        goal_pos=goal_pos,
        goal_quat=goal_quat,
        dmp=dmp,
        promp=promp,
        n_examples=len(segments),
        imitation_pos_m=float(np.abs(p - y_fit[:, :3]).max()),
        imitation_rot_deg=float(np.degrees(se3.quat_angle(q, y_fit[:, 3:]).max())),
        raw_pos_m=float(np.abs(p - y[:, :3]).max()),
        raw_rot_deg=float(np.degrees(se3.quat_angle(q, y[:, 3:]).max())),
    )


def smooth_track(
    t: FloatArray, y: FloatArray, window_s: float, *, quaternion_columns: slice | None = None
) -> FloatArray:
    """Cubic Savitzky–Golay smoothing over ``window_s`` seconds, shape of ``y`` (n, dims).

    Quaternion columns are renormalised afterwards. Tracks shorter than the
    window are smoothed over their whole (odd) length, or returned as they are.
    """
    from scipy.signal import savgol_filter

    dt = float((t[-1] - t[0]) / (t.size - 1))
    win = round(window_s / dt) | 1
    win = min(win, t.size if t.size % 2 else t.size - 1)
    if win < 5:
        return y.copy()
    out = savgol_filter(y, win, 3, axis=0, mode="interp")
    if quaternion_columns is not None:
        q = out[:, quaternion_columns]
        out[:, quaternion_columns] = q / np.linalg.norm(q, axis=1, keepdims=True)
    return np.asarray(out, dtype=np.float64)


def primitives_stage(
    demos: Sequence[Demonstration],
    *,
    n_weights: int | None = None,
    promp_weights: int = 10,
    align: Literal["phase", "dtw"] = "phase",
    keyframe_times: Sequence[Sequence[float]] | None = None,
    events: Sequence[Sequence[ConstraintEvent]] | None = None,
    skills: int | None = None,
    names: Sequence[str] | None = None,
    seed: int = 0,
    skill_library: SkillLibrary | None = None,
) -> PrimitivesBlock:
    """Learn per-constraint primitives from demonstrations: the task file's primitives block.

    Parameters
    ----------
    demos : sequence of Demonstration
        With constraint events in their labels, unless ``events`` is given.
    keyframe_times : sequence of sequences of float, optional
        Per demonstration, keyframe times (default: the constraint events).
    events : sequence of sequences of ConstraintEvent, optional
        Per demonstration, the constraints to learn motions for (e.g. the learned
        ones, :func:`thirdhand.learn.stages.learned_events`); default each
        demonstration's labels.
    skills : int, optional
        Also learn a library of this many skills over all the constraint motions
        and explain each motion as a sequence of them
        (:func:`~thirdhand.primitives.explain.explain_constraint_motions`): the
        block's ``skill_library`` and each constraint's ``skills``. None: no library.
    names : sequence of str, optional
        A name per demonstration, the ``source`` of its explained motions
        (default each demonstration's ``meta["source"]``).
    seed : int
        Seeds the skill library's restarts.
    skill_library : SkillLibrary, optional
        A library fitted before (a task file's, rebuilt by
        :func:`~thirdhand.primitives.skill_library.skill_library_from_record`): it explains
        the motions instead of a new one (``skills`` is then ignored).

    Returns
    -------
    PrimitivesBlock
        A :class:`~thirdhand.task.stages.PrimitiveRecord` per constraint key
        (:meth:`ConstraintPrimitive.record`), and the skill library when asked for
        (and there is a motion to learn it from). A constraint with no tracked
        approach motion (made at the very start, or while a tag was hidden) has no
        primitive: ``skipped`` says why, one line each.
    """
    from thirdhand.task.stages import PrimitivesBlock

    if not demos:
        raise PrimitiveError("primitives stage: no demonstration given")
    if names is not None and len(names) != len(demos):
        raise PrimitiveError(
            f"primitives stage: {len(names)} names for {len(demos)} demonstrations"
        )
    if events is not None and len(events) != len(demos):
        raise PrimitiveError(
            f"primitives stage: {len(events)} event lists for {len(demos)} demonstrations"
        )
    segs: list[ConstraintSegment] = []
    skipped: list[str] = []
    for i, d in enumerate(demos):
        kf = None if keyframe_times is None else keyframe_times[i]
        ev = None if events is None else events[i]
        found, short = split_segments(d, keyframe_times=kf, events=ev)
        if names is not None:
            found = [replace(sg, source=names[i]) for sg in found]
            short = [f"{names[i]}: {m.split(': ', 1)[1]}" for m in short]
        segs.extend(found)
        skipped.extend(short)
    out: dict[str, Any] = {
        "schema": SCHEMA,
        "frame": "child pose in the parent part's frame",
        "constraints": {},
    }
    if skipped:
        out["skipped"] = skipped
    for key, group in group_segments(segs).items():
        prim = fit_constraint_primitive(
            group, n_weights=n_weights, promp_weights=promp_weights, align=align
        )
        out["constraints"][key] = prim.to_dict()
    if segs and (skills is not None or skill_library is not None):
        from thirdhand.primitives.explain import explain_constraint_motions

        explained = explain_constraint_motions(
            segs, n_skills=skills, seed=seed, library=skill_library
        )
        out["skill_library"] = explained.library_block()
        for key, examples in explained.steps_by_key().items():
            out["constraints"][key]["skills"] = examples
    return PrimitivesBlock.model_validate(out)


def rollout_in_world(
    dmp: PoseDMP,
    *,
    parent_pos: ArrayLike,
    parent_quat: ArrayLike,
    start_pos: ArrayLike,
    start_quat: ArrayLike,
    goal_pos: ArrayLike | None = None,
    goal_quat: ArrayLike | None = None,
    run_time: float | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Roll a parent-frame primitive out for a parent and a child start given in the world.

    Parameters
    ----------
    parent_pos, start_pos : array_like, shape (3,), metres, world frame
    parent_quat, start_quat : array_like, shape (4,), x y z w, world frame
    goal_pos, goal_quat : array_like, optional
        Constraint pose in the parent frame (default: the DMP's goal).

    Returns
    -------
    s : ndarray, shape (n,), seconds
    pos : ndarray, shape (n, 3), metres, world frame
    quat : ndarray, shape (n, 4), x y z w, world frame
    """
    p_rel, q_rel = se3.relative_pose(parent_pos, parent_quat, start_pos, start_quat)
    s, p, q = dmp.rollout(
        start_pos=p_rel,
        start_quat=q_rel,
        goal_pos=goal_pos,
        goal_quat=goal_quat,
        run_time=run_time,
        at_rest=True,
    )
    pw, qw = se3.pose_compose(parent_pos, parent_quat, p, q)
    return s, pw, qw


def generalisation_check(
    dmp: PoseDMP,
    *,
    goal_pos: ArrayLike,
    goal_quat: ArrayLike,
    offsets: ArrayLike,
    run_factor: float = 1.5,
) -> tuple[FloatArray, FloatArray]:
    """Fig. 4 of the report: start from shifted positions, check the constraint pose is reached.

    Parameters
    ----------
    offsets : array_like, shape (k, 3)
        Shifts of the start position, metres, parent frame.
    run_factor : float
        Integrate for ``run_factor × tau``.

    Returns
    -------
    pos_err : ndarray, shape (k,)
        Final position error, metres.
    rot_err : ndarray, shape (k,)
        Final orientation error, radians.
    """
    off = np.atleast_2d(np.asarray(offsets, dtype=np.float64))
    g_p = np.asarray(goal_pos, dtype=np.float64)
    g_q = np.asarray(goal_quat, dtype=np.float64)
    run = run_factor * dmp.position_.tau_
    # the start orientation is the demonstrated one for every shifted start: roll it once
    _, _, q = dmp.rollout(goal_pos=g_p, goal_quat=g_q, run_time=run)
    rot = float(se3.quat_angle(q[-1], g_q))
    ends = np.array(
        [
            dmp.position_.rollout(start=dmp.position_.start_ + o, goal=g_p, run_time=run)[1][-1]
            for o in off
        ]
    )
    return np.linalg.norm(ends - g_p, axis=1), np.full(len(off), rot)
