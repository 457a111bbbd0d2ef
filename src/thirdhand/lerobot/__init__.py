"""Datasets in LeRobot's on-disk format (v3.0): episodes written and read back without LeRobot.

- :class:`Episode`: one episode's per-frame features, videos and annotations.
- :func:`write_dataset` / :class:`DatasetWriter`: a new dataset folder, never half-written.
- :func:`read_dataset`: every episode back, read the way LeRobot reads it.
- :func:`recording_episode`: a human recording as one episode.

Names resolve lazily, so importing the package costs nothing until one is used.
"""

from __future__ import annotations

import importlib
from typing import Any

_NAMES = {
    "Episode": "thirdhand.lerobot.episode",
    "DatasetSettings": "thirdhand.lerobot.writer",
    "DatasetSummary": "thirdhand.lerobot.writer",
    "DatasetWriter": "thirdhand.lerobot.writer",
    "write_dataset": "thirdhand.lerobot.writer",
    "LeRobotDataset": "thirdhand.lerobot.reader",
    "ReadEpisode": "thirdhand.lerobot.reader",
    "read_dataset": "thirdhand.lerobot.reader",
    "recording_episode": "thirdhand.lerobot.human",
}

__all__ = sorted(_NAMES)


def __getattr__(name: str) -> Any:
    if name not in _NAMES:
        raise AttributeError(f"module 'thirdhand.lerobot' has no attribute {name!r}")
    return getattr(importlib.import_module(_NAMES[name]), name)
