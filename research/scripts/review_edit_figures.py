"""Figures of the review GUI's primitive editing and phase labelling (``research/notes/review.md``).

Primitive editing, for each learned motion of TASK: the refit error of the
unmoved path, then each key point moved +2 cm and +5 cm in z: how close the
refitted motion passes the new point, how far the other key points and the end
moved, and the time of a move. Phase labelling, for RECORDING: the
hand/finger–object pairs, the active questions (most uncertain first) and the
time asked about.

    thirdhand learn ../shared/data/3rdhand/toolbox_coop_4 -o tb.json
    python research/scripts/review_edit_figures.py tb.json ../shared/data/3rdhand/toolbox_coop_4

Prints only; writes nothing.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from thirdhand import io
from thirdhand.primitives.serialize import pose_dmp_from_record
from thirdhand.review.phase_labels import PhaseLabelling
from thirdhand.review.primitive_edit import move_key_point, primitive_path, refit_position
from thirdhand.segment import segment_demonstration
from thirdhand.taskfile import load_task


def primitive_figures(task_path: str) -> None:
    block = load_task(task_path).stages.primitives
    if block is None:
        print(f"{task_path}: no primitives block")
        return
    for key, entry in block.constraints.items():
        path = primitive_path(block, key)
        dmp = pose_dmp_from_record(entry)
        again = refit_position(dmp.position_, path.s, path.pos)
        err0 = float(np.abs(again.rollout()[1] - path.pos).max())
        print(
            f"{key}: {entry.child} on {entry.parent}, {path.s[-1]:.2f} s, "
            f"{dmp.position_.n_weights} weights; refit of the unmoved path {1e3 * err0:.3f} mm"
        )
        for k in range(len(path.key_times)):
            for dz in (0.02, 0.05):
                target = path.key_points[k] + np.array([0.0, 0.0, dz])
                t0 = time.perf_counter()
                moved = primitive_path(move_key_point(block, key, k, target), key)
                took = time.perf_counter() - t0
                reach = np.linalg.norm(moved.key_points[k] - target)
                others = max(
                    (
                        float(np.linalg.norm(moved.key_points[j] - path.key_points[j]))
                        for j in range(len(path.key_times))
                        if j != k
                    ),
                    default=0.0,
                )
                end = np.linalg.norm(moved.pos[-1] - path.pos[-1])
                print(
                    f"  key {k + 1} +{100 * dz:.0f} cm z: reached within {1e3 * reach:.3f} mm, "
                    f"others moved {1e3 * others:.3f} mm, end moved {1e3 * end:.3f} mm, "
                    f"{1e3 * took:.0f} ms"
                )


def labelling_figures(recording: str) -> None:
    demo = io.load(recording)
    t0 = time.perf_counter()
    result = segment_demonstration(demo)
    s = PhaseLabelling.from_segmentation(demo, result)
    took = time.perf_counter() - t0
    span = float(result.edges[-1] - result.edges[0])
    asked = sum(q.end - q.start for q in s.questions)
    print(
        f"{recording}: {len(s.pairs)} hand/finger-object pairs, {len(s.questions)} questions, "
        f"{asked:.1f} s asked about of {len(s.pairs) * span:.0f} pair-seconds "
        f"({asked / (len(s.pairs) * span):.1%}); segmentation + questions {took:.1f} s"
    )
    for q in s.questions[:3]:
        print(
            f"  {q.a} - {q.b}: {q.start - result.edges[0]:.2f}-{q.end - result.edges[0]:.2f} s "
            f"from the start, p {q.probability:.2f}, score {q.score:.3f}"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("task", help="a task file with a primitives block (thirdhand learn)")
    parser.add_argument("recording", help="a recording to label (any format thirdhand reads)")
    args = parser.parse_args()
    primitive_figures(args.task)
    labelling_figures(args.recording)


if __name__ == "__main__":
    main()
