"""Head pose throughput on a real video: MediaPipe's face mesh alone vs thirdhand's pipeline.

Both run on one core (the process is pinned to CPU 0, XNNPACK and OpenCV to
one thread) over the same decoded frames held in memory, so decoding is not
timed. The peer is the landmark model by itself (``FaceMesh.process``); thirdhand
adds the colour conversion, the landmark arrays, ``solvePnP`` in tracking mode,
the reprojection error and the eye boxes. The ratio says what the pose costs on
top of the landmarks.

    .venv/bin/python benchmarks/headpose.py [VIDEO] [--repeat N]
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

DEFAULT = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "faces"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "video", nargs="?", type=Path, default=DEFAULT / "WolfgangLanger_Pexels.mp4"
    )
    parser.add_argument("--repeat", type=int, default=3, help="Best of N passes.")
    args = parser.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})

    import cv2
    import numpy as np

    from thirdhand.perception._deps import mediapipe
    from thirdhand.perception.headpose import camera_matrix, eye_boxes, solve_head_pose
    from thirdhand.perception.landmarks import FaceMeshTracker
    from thirdhand.perception.video import read_frames, video_info

    cv2.setNumThreads(1)
    mp = mediapipe()
    info = video_info(args.video)
    frames = [f for _, _, f in read_frames(args.video)]
    k = camera_matrix(info.width, info.height)

    def peer() -> int:
        rgb = [cv2.cvtColor(f, cv2.COLOR_BGR2RGB) for f in frames]  # not timed below
        with mp.solutions.face_mesh.FaceMesh(refine_landmarks=True) as mesh:
            start = time.perf_counter()
            n = sum(1 for im in rgb if mesh.process(im).multi_face_landmarks)
            peer.elapsed = time.perf_counter() - start  # type: ignore[attr-defined]
        return n

    def ours() -> int:
        n = 0
        previous = None
        with FaceMeshTracker() as tracker:
            start = time.perf_counter()
            for f in frames:
                faces = tracker.detect(f)
                if not faces:
                    previous = None
                    continue
                previous = solve_head_pose(faces[0].points, k, guess=previous)
                eye_boxes(faces[0].points)
                n += 1
            ours.elapsed = time.perf_counter() - start  # type: ignore[attr-defined]
        return n

    best = {"mediapipe face mesh alone": np.inf, "thirdhand landmarks + pose": np.inf}
    found = {}
    for _ in range(args.repeat):
        for name, fn in zip(best, (peer, ours), strict=True):
            found[name] = fn()
            best[name] = min(best[name], fn.elapsed)  # type: ignore[attr-defined]
    print(f"{args.video.name}: {len(frames)} frames {info.width}x{info.height}, one core, "
          f"best of {args.repeat}")  # fmt: skip
    for name, sec in best.items():
        print(f"  {name:28s} {len(frames) / sec:8.1f} fps  (face in {found[name]} frames)")
    a, b = best.values()
    print(f"  ratio thirdhand / mediapipe alone: {a / b:.2f} of its speed")


if __name__ == "__main__":
    main()
