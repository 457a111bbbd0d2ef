"""Make the reference dataset of this folder with LeRobot's own writer (not run in CI).

The dataset under ``dataset/`` was written once by ``lerobot`` 0.4.4 so that
``tests/test_lerobot_reference.py`` can compare thirdhand's writer with it: the
same frames (:func:`reference_episodes`), written by both, must give the same
``meta/info.json`` keys, features and templates, the same parquet schemas and the
same statistics.

LeRobot stays out of the project's environment (it pins torch and other packages
below the project's versions). A throwaway virtual environment made it::

    python3.11 -m venv /tmp/lerobot-venv
    /tmp/lerobot-venv/bin/pip install torch==2.13.0          # the CPU wheel on disk
    /tmp/lerobot-venv/bin/pip install --no-deps lerobot==0.4.4
    /tmp/lerobot-venv/bin/pip install "datasets>=4,<5" "huggingface-hub>=0.34.2,<0.36" \
        "av>=15,<16" jsonlines "packaging>=24.2,<26" draccus==0.10.0 pillow pandas \
        pyarrow einops deepdiff termcolor "imageio[ffmpeg]"
    /tmp/lerobot-venv/bin/pip install --no-deps "accelerate>=1.10,<2" safetensors
    PYTHONPATH=/tmp/tv-stub HF_HUB_OFFLINE=1 \
        /tmp/lerobot-venv/bin/python tests/data/lerobot_reference/make.py

(``--no-deps``: lerobot 0.4.4 asks for torch < 2.11, which pip would fetch as a
multi-gigabyte CUDA build; the dataset writer runs with the CPU torch on disk.
PyPI's torchvision does not load beside that torch ("operator torchvision::nms
does not exist"), and LeRobot's dataset modules import it at module level
without calling it when writing: ``/tmp/tv-stub`` holds an import stand-in, a
package ``torchvision`` whose ``transforms`` has a ``ToTensor`` class and
whose ``transforms.v2`` has a ``Transform`` class and a ``functional``
module, nothing more. Reading the frames back with LeRobot would need the real
torchvision or torchcodec, so ``main`` reads back only the metadata and rows.)
The video is encoded with ``vcodec="h264"`` (LeRobot's default is AV1), the codec
thirdhand writes.
"""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
FPS = 10
TASKS = ("put the leg into the seat", "turn the leg")
LENGTHS = (10, 12)
HEIGHT, WIDTH = 48, 64
STATE_NAMES = ("joint1", "joint2", "gripper_width")
ACTION_NAMES = ("joint1", "gripper_width")
CAMERA = "observation.images.front"


def reference_episodes() -> list[dict[str, object]]:
    """The frames of both episodes: state (T, 3) and action (T, 2) float32, video (T, H, W, 3)."""
    rng = np.random.default_rng(7)
    episodes = []
    yy, xx = np.mgrid[0:HEIGHT, 0:WIDTH]
    for e, n in enumerate(LENGTHS):
        t = np.arange(n) / FPS
        state = np.stack(
            [np.sin(t + e), np.cos(2 * t) * (e + 1), 0.04 * rng.random(n)], axis=1
        ).astype(np.float32)
        action = np.stack([np.sin(t + e + 0.1), 0.04 * rng.random(n)], axis=1).astype(np.float32)
        video = np.empty((n, HEIGHT, WIDTH, 3), dtype=np.uint8)
        for i in range(n):
            video[i, ..., 0] = (4 * xx + 10 * i) % 256
            video[i, ..., 1] = (5 * yy + 40 * e) % 256
            video[i, ..., 2] = 128 + 60 * np.sin((xx + yy + 3 * i) / 9.0)
        episodes.append({"task": TASKS[e], "state": state, "action": action, "video": video})
    return episodes


def features() -> dict[str, dict[str, object]]:
    """The features as given to ``LeRobotDataset.create``."""
    return {
        "observation.state": {"dtype": "float32", "shape": (3,), "names": list(STATE_NAMES)},
        "action": {"dtype": "float32", "shape": (2,), "names": list(ACTION_NAMES)},
        CAMERA: {
            "dtype": "video",
            "shape": (HEIGHT, WIDTH, 3),
            "names": ["height", "width", "channels"],
        },
    }


def main() -> None:
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    root = HERE / "dataset"
    if root.exists():
        shutil.rmtree(root)
    ds = LeRobotDataset.create(
        repo_id="thirdhand/reference",
        fps=FPS,
        features=features(),
        root=root,
        robot_type="panda",
        use_videos=True,
        vcodec="h264",
    )
    for ep in reference_episodes():
        for i in range(len(ep["state"])):  # type: ignore[arg-type]
            ds.add_frame(
                {
                    "observation.state": ep["state"][i],  # type: ignore[index]
                    "action": ep["action"][i],  # type: ignore[index]
                    CAMERA: ep["video"][i],  # type: ignore[index]
                    "task": ep["task"],
                }
            )
        ds.save_episode()
    ds.finalize()
    back = LeRobotDataset("thirdhand/reference", root=root)  # metadata and rows only
    print(back, len(back), file=sys.stderr)


if __name__ == "__main__":
    main()
