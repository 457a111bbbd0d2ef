"""The ground-truth task of a synthetic scene, and the geometry of its objects.

``truth_task(make_scene("chair"))`` is the task file a perfect learner would
write: one constraint per constraint event of the first assembly cycle, at its
exact pose and free DOFs, the plan in the demonstrated order with a keyframe per
step, and every part's mesh, scale, mesh pose and bounding box. The review GUI's
scripted user and the executor's experiments use it as the reference that a
learned task is corrected towards.
"""

from __future__ import annotations

import numpy as np

from thirdhand.demonstration import DOF_NAMES, ConstraintEvent, Demonstration
from thirdhand.task.meshes import object_geometry
from thirdhand.task.model import TaskFile

_KINDS = ("part", "tool", "finger", "hand", "head")
_DOFS = DOF_NAMES


def _keyframe(demo: Demonstration, time: float) -> dict[str, dict[str, list[float]]]:
    """Every body's last valid pose at or before ``time`` (world frame)."""
    k = int(np.searchsorted(demo.t, time, side="right")) - 1
    k = min(max(k, 0), demo.n_frames - 1)
    poses: dict[str, dict[str, list[float]]] = {}
    for b in demo.bodies:
        tr = demo.track(b.name)
        ok = np.flatnonzero(tr.valid[: k + 1])
        if not ok.size:
            ok = np.flatnonzero(tr.valid)
            if not ok.size:
                continue
        j = int(ok[-1])
        poses[b.name] = {
            "pos": [float(v) for v in tr.pos[j]],
            "quat": [float(v) for v in tr.quat[j]],
        }
    return poses


def _first_cycle(events: tuple[ConstraintEvent, ...]) -> list[ConstraintEvent]:
    seen: set[tuple[str, str]] = set()
    out = []
    for ev in sorted(events, key=lambda e: e.time):
        key = (ev.parent, ev.child)
        if ev.removed or key in seen:
            continue
        seen.add(key)
        out.append(ev)
    return out


def truth_task(demo: Demonstration, *, name: str = "truth") -> TaskFile:
    """The task file of a synthetic demonstration's ground truth.

    Parameters
    ----------
    demo : Demonstration
        A synthetic scene (:func:`thirdhand.synth.make_scene`) with constraint and
        plan labels.
    name : str
        Recorded as the constraints' ``demo``.

    Returns
    -------
    TaskFile
        Objects (with geometry), one constraint per first-cycle constraint event
        (id = its symbol), the plan in the demonstrated order with keyframes.
    """
    geometry = object_geometry(demo)
    objects = [
        {
            "name": b.name,
            "kind": b.kind if b.kind in _KINDS else "other",
            **geometry.get(b.name, {}),
        }
        for b in demo.bodies
    ]
    events = _first_cycle(demo.labels.constraints)
    constraints = []
    ids: dict[tuple[str, str], str] = {}
    for i, ev in enumerate(events):
        cid = ev.symbol if ev.symbol and ev.symbol not in ids.values() else f"c{i}"
        ids[(ev.parent, ev.child)] = cid
        constraints.append(
            {
                "id": cid,
                "parent": ev.parent,
                "child": ev.child,
                "type": ev.type,
                "pos": list(ev.pos),
                "quat": list(ev.quat),
                "free_dofs": ev.free_dofs,
                "symbol": ev.symbol or cid,
                "time": ev.time,
                "demo": name,
            }
        )
    plan = []
    steps = sorted(demo.labels.plan, key=lambda s: (s.time is None, s.time or 0.0))
    seen: set[tuple[str, str]] = set()
    for s in steps:
        key = (s.parent, s.child)
        if key in seen or key not in ids:
            continue
        seen.add(key)
        cid = ids[key]
        time = (
            s.time
            if s.time is not None
            else next(e.time for e in events if e.parent == s.parent and e.child == s.child)
        )
        plan.append(
            {
                "parent": s.parent,
                "child": s.child,
                "symbol": s.symbol or cid,
                "constraint": cid,
                "time": time,
                "keyframe": _keyframe(demo, time),
            }
        )
    if not plan:  # no plan labels: the constraint events in time order
        for ev in events:
            cid = ids[(ev.parent, ev.child)]
            plan.append(
                {
                    "parent": ev.parent,
                    "child": ev.child,
                    "symbol": ev.symbol or cid,
                    "constraint": cid,
                    "time": ev.time,
                    "keyframe": _keyframe(demo, ev.time),
                }
            )
    return TaskFile.new(
        objects=objects,
        constraints=constraints,
        plan=plan,
        stages={"truth": {"scene": demo.meta.get("scene"), "seed": demo.meta.get("seed")}},
        parameters={"source": "thirdhand.synth ground truth"},
    )
