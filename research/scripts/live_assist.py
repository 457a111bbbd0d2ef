"""The robot assist on a synthetic chair: was the fetched part at the hand-over pose in time?

Usage::

    python research/scripts/live_assist.py chair11.parquet chair_task.json
    python research/scripts/live_assist.py chair_task.json chair1[1-5].parquet   # several, a total

For each assist it prints the part, when it was ready at the hand-over pose, when
the person's hand reached for a part of that kind (the recording's ground-truth
holds, ``meta["holds"]``) and the configurations in collision; then how many steps
had a part of the robot's ready before the hand reached. A step is counted per part the
person took: the arm's leg, fetched for one leg slot, serves whichever leg the person
mounts next, so two in-time assists with the same step id are two steps (before
2026-12-04 they counted once).
"""

from __future__ import annotations

import sys

import numpy as np

from thirdhand import io
from thirdhand.live.assist import AssistOptions
from thirdhand.live.loop import LiveLoop, LiveOptions
from thirdhand.live.source import ReplaySource
from thirdhand.task.store import load_task


def main(recording: str, task_path: str) -> tuple[int, int, int, int]:
    """Run one recording; print its assists; return (steps in time, steps, in collision,
    configurations checked)."""
    demo = io.load(recording)
    task = load_task(task_path)
    loop = LiveLoop(task, demo.bodies, demo.meta, options=LiveOptions(assist=AssistOptions()))
    doc = loop.run(ReplaySource(demo, 0)).to_dict()
    holds = demo.meta.get("holds", [])
    collisions = checked = 0
    # One step per part the person took: with interchangeable parts an assist fetched for
    # one slot serves whichever of its kind the person mounts next, so two assists of
    # the same step id are two steps.
    in_time: set[str] = set()
    for a in doc["assists"]:
        taken = [p for p in a["taken"].split(", ") if p]
        reach = min([h[2] for h in holds if h[1] in taken and h[2] >= a["start"] - 0.5] or [np.nan])
        ok = a["ready"] is not None and np.isfinite(reach) and a["ready"] <= reach
        if ok:
            in_time.add(a["taken"])
        collisions += a["collisions"]
        checked += a["checked"]
        print(
            f"step {a['step']} {a['part']}: start {a['start']:.2f} ready {a['ready']} "
            f"reach {reach:.2f} -> {'in time' if ok else a['outcome']} ({a['status']}); "
            f"{a['collisions']}/{a['checked']} in collision {a['colliding_pairs']}"
        )
    print(
        f"{len(in_time)} of {len(task.plan)} steps with a part ready before the hand reached; "
        f"{collisions} of {checked} configurations in collision; planning "
        f"{doc['assist_ms']['max']} ms at most"
    )
    return len(in_time), len(task.plan), collisions, checked


if __name__ == "__main__":
    if sys.argv[1].endswith(".json"):  # a task, then recordings
        total = np.zeros(4, dtype=int)
        for rec in sys.argv[2:]:
            print(f"== {rec}")
            total += main(rec, sys.argv[1])
        print(
            f"all {len(sys.argv) - 2}: {total[0]} of {total[1]} steps in time; "
            f"{total[2]} of {total[3]} configurations in collision"
        )
    else:
        main(sys.argv[1], sys.argv[2])
