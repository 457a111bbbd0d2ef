"""Live loop on synthetic chairs and benches: recognition delay against the ground truth.

Tasks are learned (``thirdhand learn``, no primitives, no reward) from seeds 1 and 2;
the recordings replayed are seeds never used in training. Usage::

    thirdhand synth chair -o chair1.parquet --seed 1   # ... seeds 1, 2 and the test seeds
    # fast.toml: [learn] primitives = false, reward = false
    thirdhand learn chair1.parquet chair2.parquet -o chair_task.json --config fast.toml
    python scripts/live_recognition.py DIR   # {chair,bench}_task.json, {chair,bench}N.parquet

Prints, per recording, each constraint's delay (recognised − formed, seconds), whether
every step was recognised and none early, and the per-frame update latency (wall and CPU).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from thirdhand import io
from thirdhand.live.loop import LiveLoop
from thirdhand.live.source import ReplaySource
from thirdhand.task.store import load_task


def main(folder: str, seeds: tuple[int, ...] = (11, 12, 13)) -> None:
    root = Path(folder)
    delays: list[float] = []
    wall: list[float] = []
    cpu: list[float] = []
    ok_all = True
    for scene in ("chair", "bench"):
        task = load_task(root / f"{scene}_task.json")
        for seed in seeds:
            demo = io.load(root / f"{scene}{seed}.parquet")
            loop = LiveLoop(task, demo.bodies, demo.meta)
            rep = loop.run(ReplaySource(demo, 0))
            tracker = rep.tracker
            assert tracker is not None, "the task has a plan"
            got = {(r.parent, r.child): r.recognised_s for r in tracker.history}
            row: list[float] = []
            for c in sorted(demo.labels.constraints, key=lambda e: e.time):
                t = got.get((c.parent, c.child))
                row.append(np.nan if t is None else t - c.time)
            d = np.array(row)
            ok = bool(np.all(np.isfinite(d)) and np.all(d >= 0) and np.all(d <= 1.0))
            ok_all &= ok and len(tracker.history) == len(row)
            delays += [float(x) for x in d if np.isfinite(x)]
            wall += rep.latency
            cpu += rep.cpu
            print(
                f"{scene}{seed}: {len(tracker.history)}/{len(row)} steps, delays "
                f"{np.round(d, 2).tolist()} s, {'ok' if ok else 'FAIL'}; wall median "
                f"{1e3 * np.median(rep.latency):.3f} p99 {1e3 * np.percentile(rep.latency, 99):.2f}"
                f" ms; cpu median {1e3 * np.median(rep.cpu):.3f} p99 "
                f"{1e3 * np.percentile(rep.cpu, 99):.2f} max {1e3 * max(rep.cpu):.2f} ms"
            )
    print(
        f"all: {len(delays)} steps, delay median {np.median(delays):.2f} s, max "
        f"{max(delays):.2f} s, min {min(delays):.2f} s; every step within [0, 1] s: {ok_all}; "
        f"update wall median {1e3 * np.median(wall):.3f} ms p99 {1e3 * np.percentile(wall, 99):.2f}"
        f" ms; cpu median {1e3 * np.median(cpu):.3f} ms p99 {1e3 * np.percentile(cpu, 99):.2f} ms"
    )


if __name__ == "__main__":
    main(sys.argv[1])
