"""What the review shows: the selection, the keyframe and the chosen step, as one record.

:class:`ReviewView` is a frozen snapshot; every change of what is shown is a pure
function here that takes the task and a view and returns the new view (or raises
:class:`~thirdhand.errors.ThirdhandError` with the one line the person reads).
The app (:class:`~thirdhand.review.app.ReviewApp`) keeps the current view and
draws it; nothing here touches viser.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass, replace
from typing import Any, Literal

from thirdhand.errors import ThirdhandError
from thirdhand.review import dofs as dofs_mod
from thirdhand.review.primitive_edit import PrimitivePath, key_for, primitive_path
from thirdhand.task.constraint import Constraint
from thirdhand.taskfile import TaskFile

Mode = Literal["task", "playback"]


@dataclass(frozen=True)
class ReviewView:
    """What the 3D view and the panels show.

    Attributes
    ----------
    selected : str or None
        The selected object.
    step : int or None
        The plan step whose keyframe is shown (index into the plan), None: the assembled task.
    chosen_step : int or None
        The plan step chosen in the Step list and the plan timeline (what Move acts on),
        None: the first.
    mode : {"task", "playback"}
        The task at its constraint poses, or a recording played back.
    key_point : int
        The learned motion's key point the Motion panel moves (0-based).
    """

    selected: str | None = None
    step: int | None = None
    chosen_step: int | None = None
    mode: Mode = "task"
    key_point: int = 0


def constraint_of(task: TaskFile, child: str | None) -> Constraint | None:
    """The constraint whose child is ``child`` (None if none)."""
    if child is None:
        return None
    return next((c for c in task.constraints if c.child == child), None)


def selected_constraint(task: TaskFile, view: ReviewView) -> Constraint | None:
    """The selected object's constraint (None: nothing selected, or it has none)."""
    return constraint_of(task, view.selected)


def selected_parent(task: TaskFile, view: ReviewView) -> str | None:
    """The selected object's parent (None: nothing selected, or it has no constraint)."""
    c = selected_constraint(task, view)
    return None if c is None else c.parent


def require_constraint(task: TaskFile, view: ReviewView) -> Constraint:
    """The selected object's constraint; a refusal when there is none."""
    c = selected_constraint(task, view)
    if c is None:
        raise ThirdhandError("select an object with a constraint first")
    return c


def primitive_key(task: TaskFile, view: ReviewView) -> str | None:
    """The key of the selected constraint's learned motion (None: it has none)."""
    c = selected_constraint(task, view)
    if c is None:
        return None
    return key_for(task.stages.primitives, c.parent, c.child)


def motion_path(task: TaskFile, view: ReviewView) -> PrimitivePath | None:
    """The selected constraint's learned motion as a path with key points (parent frame)."""
    key = primitive_key(task, view)
    return None if key is None else primitive_path(task.stages.primitives, key)


def require_motion_path(task: TaskFile, view: ReviewView) -> PrimitivePath:
    """The selected constraint's learned motion; a refusal when it has none."""
    path = motion_path(task, view)
    if path is None:
        raise ThirdhandError("select a part whose constraint has a learned motion first")
    return path


def shown_poses(task: TaskFile, view: ReviewView) -> dict[str, Any]:
    """Every object's world pose at the keyframe shown (:func:`dofs.world_poses`)."""
    if not task.plan:
        return {}
    return dofs_mod.world_poses(task, view.step)


def select(view: ReviewView, name: str | None, names: Collection[str]) -> ReviewView:
    """Select ``name`` (None: nothing) among the drawn ``names``; the view shows the task."""
    if name is not None and name not in names:
        raise ThirdhandError(f"unknown object {name!r}")
    return replace(view, selected=name, mode="task")


def drop_unknown(view: ReviewView, names: Collection[str]) -> ReviewView:
    """The view without a selection that is no longer drawn."""
    if view.selected is not None and view.selected not in names:
        return replace(view, selected=None)
    return view


def show_step(task: TaskFile, view: ReviewView, index: int | None) -> ReviewView:
    """Show the keyframe of plan step ``index`` (None: the assembled task)."""
    n = len(task.plan)
    if index is not None and not 0 <= index < n:
        raise ThirdhandError(f"no plan step {index}; the plan has {n}")
    return replace(view, step=index, mode="task")


def choose_step(task: TaskFile, view: ReviewView, index: int) -> ReviewView:
    """Choose plan step ``index`` (a timeline marker): what Move acts on. The app then
    shows its keyframe (:func:`show_step`)."""
    n = len(task.plan)
    if not 0 <= index < n:
        raise ThirdhandError(f"no plan step {index + 1}; the plan has {n}")
    return replace(view, chosen_step=index)


def step_target(task: TaskFile, index: int, delta: int) -> int:
    """Where plan step ``index`` goes when moved up (``delta`` -1) or down (+1)."""
    new = index + delta
    n = len(task.plan)
    if not 0 <= new < n:
        where = "first" if delta < 0 else "last"
        raise ThirdhandError(f"step {index + 1} is already the {where} of {n}")
    return new


def check_step_move(task: TaskFile, index: int, new_index: int) -> None:
    """Refuse a move of plan step ``index`` to ``new_index`` out of range or in place."""
    n = len(task.plan)
    for what, v in (("step", index), ("position", new_index)):
        if not 0 <= v < n:
            raise ThirdhandError(f"no {what} {v + 1}: the plan has {n} steps")
    if index == new_index:
        raise ThirdhandError(f"step {index + 1} is already at position {new_index + 1}")


def after_step_move(view: ReviewView, index: int, new_index: int) -> ReviewView:
    """The chosen and shown step follow a step moved from ``index`` to ``new_index``."""
    step = new_index if view.step == index else view.step
    return replace(view, step=step, chosen_step=new_index)


def moving_step(task: TaskFile, view: ReviewView) -> int:
    """The step the timeline's Move acts on: the chosen one (the first if none)."""
    if not task.plan:
        raise ThirdhandError("the plan has no step to move")
    return 0 if view.chosen_step is None else view.chosen_step


def choose_key_point(task: TaskFile, view: ReviewView, index: int) -> ReviewView:
    """Choose the key point (0-based) of the selected motion the Motion panel moves."""
    path = require_motion_path(task, view)
    n = len(path.key_times)
    if not 0 <= index < n:
        raise ThirdhandError(f"no key point {index + 1}; the motion has {n}")
    return replace(view, key_point=index)


def clamp_key_point(view: ReviewView, path: PrimitivePath) -> ReviewView:
    """The view with its key point inside ``path``'s key points."""
    return replace(view, key_point=min(view.key_point, len(path.key_times) - 1))


def after_reload(task: TaskFile, view: ReviewView) -> ReviewView:
    """The view over a task reloaded from disk: a keyframe past its plan is dropped."""
    if view.step is not None and view.step >= len(task.plan):
        return replace(view, step=None)
    return view


__all__ = [
    "Mode",
    "ReviewView",
    "after_reload",
    "after_step_move",
    "check_step_move",
    "choose_key_point",
    "choose_step",
    "clamp_key_point",
    "constraint_of",
    "drop_unknown",
    "motion_path",
    "moving_step",
    "primitive_key",
    "require_constraint",
    "require_motion_path",
    "select",
    "selected_constraint",
    "selected_parent",
    "show_step",
    "shown_poses",
    "step_target",
]
