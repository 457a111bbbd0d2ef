"""Which step next and which part: partial order, interchangeable parts, hard slots first.

The executor does not have to follow the learned sequence. A step may run once
its parent is in place and every step the plan says it must follow is done
(:func:`predecessors`); with one demonstration the learned order is total but
says nothing about which orders are necessary, so by default (``order="auto"``)
only a plan learned from several demonstrations binds the order beyond "parent
first". Among the steps that may run, the hardest slot goes first
(:func:`slot_difficulty`: far from the arm's first joint and low, where the arm
reaches in past the parts already placed); a step that fails is moved to the
front and the plan made again (:class:`~thirdhand.execute.executor.Executor`).

Identical parts (:func:`identical_parts`: same mesh, same bounding box, each the
child of some constraint and the parent of none, e.g. the four legs of a chair)
are interchangeable: any of them may go into any of their slots; the one whose
step succeeds is bound to the slot.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from thirdhand.arrays import FloatArray
from thirdhand.task.constraint import Constraint
from thirdhand.task.model import TaskFile, TaskStep

#: Values of ``ExecutionOptions.order``.
ORDERS = ("auto", "plan", "parents")


def plan_binds_order(task: TaskFile, order: str) -> bool:
    """Whether the learned sequence constrains the order (beyond parents first).

    ``"plan"``: yes; ``"parents"``: no; ``"auto"``: when the plan was learned from
    two or more demonstrations (``stages.plan.n_demos``).
    """
    if order not in ORDERS:
        from thirdhand.execute.scene import SceneError

        raise SceneError(f"order {order!r}: expected one of {', '.join(ORDERS)}")
    if order != "auto":
        return order == "plan"
    n = task.stages.plan.n_demos if task.stages.plan is not None else 1
    return isinstance(n, int) and n >= 2


def predecessors(
    steps: Sequence[tuple[int, TaskStep, Constraint]], *, use_plan: bool
) -> dict[str, set[str]]:
    """For each step's constraint id, the constraint ids that must be done before it.

    Always: the step whose child is this step's parent. With ``use_plan``, also the
    plan's order (``TaskStep.after``; None means after the previous step), closed
    transitively.

    Parameters
    ----------
    steps : sequence of (plan index, TaskStep, Constraint)
        The executable steps, in plan order.
    use_plan : bool
    """
    by_index = {i: c.id for i, _, c in steps}
    by_child = {c.child: c.id for _, _, c in steps}
    out: dict[str, set[str]] = {}
    for k, (_, s, c) in enumerate(steps):
        pre: set[str] = set()
        if c.parent in by_child:
            pre.add(by_child[c.parent])
        if use_plan:
            after = s.after if s.after is not None else ([steps[k - 1][0]] if k else [])
            pre |= {by_index[j] for j in after if j in by_index}
        out[c.id] = pre - {c.id}
    # transitive closure, in plan order repeatedly until stable
    changed = True
    while changed:
        changed = False
        for cid, pre in out.items():
            more = set().union(*(out[p] for p in pre)) - pre - {cid} if pre else set()
            if more:
                pre |= more
                changed = True
    return out


def identical_parts(task: TaskFile) -> dict[str, list[str]]:
    """For each part, the parts identical to it (itself included), in task order.

    Identical: the same mesh file name and bounding box (to 1 mm), each the child
    of a constraint and the parent of none. Other parts map to themselves only.
    """
    children = {c.child for c in task.constraints}
    parents = {c.parent for c in task.constraints}
    groups: dict[tuple[object, ...], list[str]] = {}
    out: dict[str, list[str]] = {}
    for o in task.objects:
        if o.name not in children:
            continue
        if o.name in parents or o.bbox_min is None or o.bbox_max is None:
            out[o.name] = [o.name]
            continue
        mesh = None if o.mesh is None else str(o.mesh).replace("\\", "/").rsplit("/", 1)[-1]
        key = (mesh, *np.round(np.asarray(o.bbox_min), 3), *np.round(np.asarray(o.bbox_max), 3))
        groups.setdefault(key, []).append(o.name)
    for names in groups.values():
        for n in names:
            out[n] = list(names)
    return out


def slot_difficulty(goal: FloatArray, arm_xy: tuple[float, float], table_z: float) -> float:
    """How hard a slot is to reach once its neighbours are in: far from the arm and low.

    The horizontal distance of the goal from the arm's first joint minus its height
    above the table, metres (larger is harder; the hardest goes first).
    """
    d = float(np.hypot(goal[0, 3] - arm_xy[0], goal[1, 3] - arm_xy[1]))
    return d - float(goal[2, 3] - table_z)
