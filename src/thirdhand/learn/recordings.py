"""The per-recording stages of learning, and the checks on the recordings given.

:func:`recording_stages` is the unit ``learn --jobs/--scheduler`` runs in a process
or on a cluster: one recording's interaction phases
(:func:`~thirdhand.segment.segment_demonstration`) and constraints
(:func:`~thirdhand.constraints.detect.detect_constraints`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from thirdhand.demonstration import Demonstration
from thirdhand.errors import ThirdhandError
from thirdhand.learn.results import RecordingStages

if TYPE_CHECKING:
    from thirdhand.segment.model import SegmentModel


@dataclass(frozen=True)
class RecordingUnit:
    """One independent unit of ``learn --jobs/--scheduler``: one recording's own stages.

    Attributes
    ----------
    demo : Demonstration
    name : str
        The recording's name (its file name).
    segment : bool
        Run the interaction segmentation when ``known.phases`` is None.
    model : SegmentModel or None
        The segmentation model (None: the shipped one).
    known : RecordingStages
        What is already computed.
    """

    demo: Demonstration
    name: str
    segment: bool = True
    model: SegmentModel | None = None
    known: RecordingStages = RecordingStages()  # noqa: RUF009 (frozen, so shared safely)


def recording_stages(unit: RecordingUnit) -> RecordingStages:
    """Segment one recording (unless told not to, or given) and detect its constraints.

    Deterministic, so the task file is the same serially, in processes and on a
    cluster (:func:`thirdhand.batch.parallel_map`).
    """
    from thirdhand.constraints.detect import detect_constraints
    from thirdhand.segment import segment_demonstration

    phases = unit.known.phases
    if phases is None and unit.segment:
        phases = segment_demonstration(unit.demo, unit.model)
    detection = unit.known.detection
    if detection is None:
        detection = detect_constraints(unit.demo, phases=phases, demo_name=unit.name)
    return RecordingStages(phases, detection)


def check_one_task(demos: Sequence[Demonstration], paths: Sequence[Path]) -> None:
    """Refuse recordings of different tasks: groups of recordings that share no part.

    Recordings of one task show (some of) the same parts; a recording whose parts
    appear in no other recording of the group is of another task, and learning
    from both gives an empty or mixed-up task.

    Raises
    ------
    ThirdhandError
        Naming the groups and their parts.
    """
    parts = [{b.name for b in d.bodies if b.kind == "part"} for d in demos]
    group = list(range(len(demos)))

    def root(i: int) -> int:
        while group[i] != i:
            i = group[i]
        return i

    for i in range(len(demos)):
        for j in range(i):
            if parts[i] & parts[j]:
                group[root(i)] = root(j)
    groups: dict[int, list[int]] = {}
    for i in range(len(demos)):
        groups.setdefault(root(i), []).append(i)
    if len(groups) > 1:
        listed = []
        for members in groups.values():
            names = sorted(set().union(*(parts[i] for i in members)))
            files = ", ".join(str(paths[i]) for i in members)
            listed.append(f"{files} (parts: {', '.join(names) or 'none'})")
        desc = "; ".join(listed)
        raise ThirdhandError(
            f"the recordings show different tasks: no part is shared between {desc}; "
            "learn each task from its own recordings"
        )
