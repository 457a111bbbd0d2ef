"""Where every object is, and how a constraint's degrees of freedom move its child.

Pure geometry for the review GUI's drawing and its clarification animations:
:func:`world_poses` places every object of a task at a plan step,
:func:`dof_animation` moves a constrained child along one DOF, and
:func:`classify_dof` says whether a DOF range is locked, noise-level, limited or
a full turn (they are drawn differently).

Frames: a constraint's ``pos``/``quat`` is the child's pose in the parent frame;
its ``frame`` is the constraint frame as a pose in the child frame, and the DOF
ranges are motions of the child expressed in that constraint frame.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np

from thirdhand.se3 import pose_compose, pose_invert, quat_multiply
from thirdhand.task.constraint import Constraint
from thirdhand.task.geometry import DOF_NAMES, Pose
from thirdhand.task.model import TaskFile

DofClass = Literal["locked", "noise", "limited", "full"]

#: A translation range narrower than this (metres) is sensor noise, not a free DOF.
NOISE_TRANSLATION = 0.005
#: A rotation range narrower than this (radians, 5 degrees) is sensor noise.
NOISE_ROTATION = math.radians(5.0)
#: A rotation range at least this wide (radians) is a full turn.
FULL_ROTATION = 2.0 * math.pi - 1e-3
#: Amplitude of the demonstration swing of a locked translation (metres) ...
DEMO_TRANSLATION = 0.02
#: ... and of a locked rotation (radians, 15 degrees).
DEMO_ROTATION = math.radians(15.0)

_AXES = {"x": 0, "y": 1, "z": 2}


def _pose(pos: np.ndarray, quat: np.ndarray) -> Pose:
    q = np.asarray(quat, dtype=np.float64)
    q = q / np.linalg.norm(q)
    return Pose.model_validate(
        {"pos": [float(v) for v in pos], "quat": [float(v) for v in q]}, strict=False
    )


def compose(a: Pose, b: Pose) -> Pose:
    """``a ∘ b``: the pose of C in A from the pose ``a`` of B in A and ``b`` of C in B."""
    p, q = pose_compose(a.pos, a.quat, b.pos, b.quat)
    return _pose(p, q)


def invert(a: Pose) -> Pose:
    """The inverse of the pose of B in A: the pose of A in B."""
    p, q = pose_invert(a.pos, a.quat)
    return _pose(p, q)


def classify_dof(lo: float, hi: float, dof: str = "rx") -> DofClass:
    """What a DOF range means.

    Parameters
    ----------
    lo, hi : float
        The range, metres for a translation, radians for a rotation.
    dof : str
        One of :data:`thirdhand.taskfile.DOF_NAMES`; ``"t*"`` names are translations
        (the thresholds differ). Default: a rotation.

    Returns
    -------
    {"locked", "noise", "limited", "full"}
        ``locked``: ``lo == hi``; ``noise``: narrower than :data:`NOISE_TRANSLATION`
        or :data:`NOISE_ROTATION`; ``full``: a rotation at least
        :data:`FULL_ROTATION` wide; ``limited`` otherwise.
    """
    width = hi - lo
    if width <= 0.0:
        return "locked"
    rotation = not dof.startswith("t")
    if width < (NOISE_ROTATION if rotation else NOISE_TRANSLATION):
        return "noise"
    if rotation and width >= FULL_ROTATION:
        return "full"
    return "limited"


def dof_motion(dof: str, amount: float) -> Pose:
    """The motion ``amount`` (m or rad) along ``dof`` as a pose in the constraint frame."""
    if dof not in DOF_NAMES:
        raise ValueError(f"unknown DOF {dof!r}; expected one of {', '.join(DOF_NAMES)}")
    axis = _AXES[dof[1]]
    if dof[0] == "t":
        pos = np.zeros(3)
        pos[axis] = amount
        return _pose(pos, np.array([0.0, 0.0, 0.0, 1.0]))
    quat = np.zeros(4)
    quat[axis] = math.sin(amount / 2.0)
    quat[3] = math.cos(amount / 2.0)
    return _pose(np.zeros(3), quat)


def move_along(constraint: Constraint, dof: str, amount: float) -> Pose:
    """The child's pose in the parent frame after moving ``amount`` along ``dof``.

    ``T_parent_child' = T_parent_child ∘ F ∘ M(amount) ∘ F⁻¹`` with ``F`` the
    constraint frame (in the child frame) and ``M`` the motion in that frame.
    """
    frame = constraint.frame
    return compose(compose(compose(constraint.pose, frame), dof_motion(dof, amount)), invert(frame))


def dof_amount(lo: float, hi: float, dof: str, phase: float) -> float:
    """The displacement along a DOF at ``phase`` of its animation (m or rad).

    A full turn spins once (``2π·phase``); a range swings from the rest value
    (0 clipped into the range) to ``hi``, back, to ``lo`` and back; a locked
    DOF swings by :data:`DEMO_TRANSLATION` or :data:`DEMO_ROTATION` to show its axis.
    """
    kind = classify_dof(lo, hi, dof)
    if kind == "full":
        return 2.0 * math.pi * (phase % 1.0)
    if kind == "locked":
        amp = DEMO_TRANSLATION if dof.startswith("t") else DEMO_ROTATION
        lo, hi = lo - amp, hi + amp
    rest = min(max(0.0, lo), hi)
    s = math.sin(2.0 * math.pi * phase)
    return rest + (hi - rest) * s if s >= 0.0 else rest + (rest - lo) * s


def dof_animation(constraint: Constraint, dof: str, phase: float) -> Pose:
    """The child's pose in the parent frame, moved along one DOF at ``phase`` in [0, 1).

    Within the DOF's range (see :func:`dof_amount`), or a small demonstration
    swing for a locked DOF. Phase 0 (and 1) is the constraint's own pose, except
    for a range that excludes 0 (it starts at the nearest end).
    """
    if dof not in DOF_NAMES:
        raise ValueError(f"unknown DOF {dof!r}; expected one of {', '.join(DOF_NAMES)}")
    lo, hi = constraint.free_dofs[dof]
    return move_along(constraint, dof, dof_amount(lo, hi, dof, phase))


def _keyframe_of(task: TaskFile, index: int) -> dict[str, Pose]:
    """World poses from the keyframe of step ``index``, completed from the nearest others."""
    out: dict[str, Pose] = dict(task.plan[index].keyframe)
    order = sorted(range(len(task.plan)), key=lambda j: abs(j - index))
    for j in order:
        for name, pose in task.plan[j].keyframe.items():
            out.setdefault(name, pose)
    return out


def world_poses(task: TaskFile, step_index: int | None = None) -> dict[str, Pose]:
    """Every object's world pose at a plan step.

    Parameters
    ----------
    task : TaskFile
    step_index : int, optional
        The plan step (index into ``task.plan``); its keyframe gives the poses, and
        the constraints of that step and of every earlier step place their
        children at ``parent ∘ constraint pose``. None: the last step, with every
        constraint of the task applied.

    Returns
    -------
    dict of str to Pose
        Per object name, its pose in the world frame (metres, x y z w). Objects
        in no keyframe and not placed by a constraint are at the origin.

    Raises
    ------
    IndexError
        If ``step_index`` is out of range.
    """
    if step_index is not None and not 0 <= step_index < len(task.plan):
        raise IndexError(f"plan step {step_index} out of range (plan has {len(task.plan)} steps)")
    base: dict[str, Pose] = {}
    if task.plan:
        base = _keyframe_of(task, len(task.plan) - 1 if step_index is None else step_index)
    by_id = {c.id: c for c in task.constraints}
    if step_index is None:
        active = list(task.constraints)
    else:
        active = [by_id[s.constraint] for s in task.plan[: step_index + 1] if s.constraint in by_id]
    # The last active constraint of a child wins (a later step re-attaches it).
    placing: dict[str, Constraint] = {c.child: c for c in active}
    out: dict[str, Pose] = {}

    def resolve(name: str, trail: tuple[str, ...]) -> Pose:
        if name in out:
            return out[name]
        c = placing.get(name)
        if c is None or c.parent in trail:
            pose = base.get(name, Pose())
        else:
            pose = compose(resolve(c.parent, (*trail, name)), c.pose)
        out[name] = pose
        return pose

    for obj in task.objects:
        resolve(obj.name, ())
    return out


def relative(parent_world: Pose, child_world: Pose) -> Pose:
    """The child's pose in the parent frame from both world poses."""
    return compose(invert(parent_world), child_world)


def quat_distance(q1: tuple[float, ...], q2: tuple[float, ...]) -> float:
    """Angle of the rotation between two unit quaternions x y z w, radians in [0, π]."""
    d = quat_multiply(np.asarray(q1) * np.array([-1.0, -1.0, -1.0, 1.0]), np.asarray(q2))
    return float(2.0 * math.atan2(np.linalg.norm(d[:3]), abs(d[3])))
