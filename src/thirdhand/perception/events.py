"""Perception events in the task file, and the object in focus at a given time.

The events go in the task file's typed stage block ``stages.perception``
(:class:`~thirdhand.task.stages.PerceptionBlock`), in JSON::

    {
      "pointing":  [{"hand": "rh", "object": "leg2", "t0": 3.1, "t1": 4.0,
                     "angle_deg": 1.2, "ray": "head"}, ...],
      "attention": [{"object": "seating", "t0": 0.0, "t1": 2.5,
                     "angle_deg": 4.0, "source": "head"}, ...],
      "source": "chair.rec.parquet",
      "parameters": {"dwell": 0.4, "cone_deg": 15.0}
    }

Times are seconds on the demonstration's time axis. A later stage asks
:func:`focus_object` which object a person singled out around a moment: the
review GUI, for the object a clarification question is about; online
execution, for the part the person is about to handle.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from thirdhand.errors import TaskFileError
from thirdhand.perception.attention import AttentionInterval
from thirdhand.perception.pointing import PointingEvent
from thirdhand.task.stages import AttentionRecord, PerceptionBlock, PointingRecord
from thirdhand.taskfile import TaskFile

#: Key of the block in ``TaskFile.stages``.
STAGE = "perception"


def _attention_record(a: AttentionInterval) -> AttentionRecord:
    return AttentionRecord(
        object=a.object,
        t0=round(a.t0, 4),
        t1=round(a.t1, 4),
        angle_deg=round(a.angle_deg, 2),
        source=a.source,
    )


def perception_events(
    *,
    pointing: Sequence[PointingEvent] = (),
    attention: Sequence[AttentionInterval] = (),
    source: str | None = None,
    parameters: Mapping[str, float | int | str | bool | None] | None = None,
) -> PerceptionBlock:
    """The ``stages.perception`` block (module docstring) for these events."""
    return PerceptionBlock(
        pointing=[
            PointingRecord.model_validate(e.to_dict()) for e in sorted(pointing, key=lambda e: e.t0)
        ],
        attention=[_attention_record(a) for a in sorted(attention, key=lambda a: a.t0)],
        source=source,
        parameters=dict(parameters or {}),
    )


def add_perception_events(
    task: TaskFile,
    *,
    pointing: Sequence[PointingEvent] = (),
    attention: Sequence[AttentionInterval] = (),
    source: str | None = None,
    parameters: Mapping[str, float | int | str | bool | None] | None = None,
) -> TaskFile:
    """A copy of ``task`` whose ``stages.perception`` holds these events.

    An existing perception block is replaced; everything else is kept. Objects
    the events name must be objects of the task (pointing at nothing, ``None``,
    is allowed).

    Raises
    ------
    TaskFileError
        If an event names an object the task does not have.
    """
    known = {o.name for o in task.objects}
    named: list[tuple[str, int, str | None]] = [
        ("pointing", i, e.object) for i, e in enumerate(pointing)
    ] + [("attention", i, a.object) for i, a in enumerate(attention)]
    for kind, i, obj in named:
        if obj is not None and known and obj not in known:
            raise TaskFileError(f"stages.{STAGE}.{kind}[{i}].object: unknown object {obj!r}")
    block = perception_events(
        pointing=pointing, attention=attention, source=source, parameters=parameters
    )
    out = task.model_copy(deep=True)
    out.stages.perception = block
    return out


def focus_object(
    task_or_block: TaskFile | PerceptionBlock | None,
    t: float,
    *,
    lookback: float = 5.0,
) -> str | None:
    """The object a person singled out at time ``t``, or None.

    The latest pointing event that ended at most ``lookback`` seconds before
    ``t`` (or is going on at ``t``) wins; failing that, the attention interval
    covering ``t``.

    Parameters
    ----------
    task_or_block : TaskFile or PerceptionBlock or None
        A task with a perception block, or the block itself.
    t : float, seconds
    lookback : float, seconds
    """
    block = task_or_block
    if isinstance(block, TaskFile):
        block = block.stages.perception
    if block is None:
        return None
    best: tuple[float, str] | None = None
    for e in block.pointing:
        if e.object is None or e.t0 > t or e.t1 < t - lookback:
            continue
        if best is None or e.t1 > best[0]:
            best = (e.t1, e.object)
    if best is not None:
        return best[1]
    for a in block.attention:
        if a.t0 <= t <= a.t1:
            return a.object
    return None
