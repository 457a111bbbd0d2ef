"""Robot training data: a task's plan simulated from many start layouts, as a LeRobot dataset.

Imported only by ``thirdhand generate`` (the ``sim`` extra). The modules:
:mod:`~thirdhand.generate.settings` (the settings record),
:mod:`~thirdhand.generate.record` (the frame sink that records the state, the
commands, the parts' poses and two cameras),
:mod:`~thirdhand.generate.episodes` (one seeded episode: planned, simulated,
recorded, judged), :mod:`~thirdhand.generate.dataset` (many seeds into one
dataset, in seed order) and :mod:`~thirdhand.generate.cli` (the command).

Names resolve lazily, so importing the package costs nothing until one is used.
"""

from __future__ import annotations

import importlib
from typing import Any

from thirdhand.simulate.video import choose_backend

# MuJoCo picks its OpenGL back end when it is first imported, and every module here
# renders: set MUJOCO_GL (egl unless the user chose) before a submodule imports MuJoCo.
choose_backend()

_NAMES = {
    "GenerateSettings": "thirdhand.generate.settings",
    "Recording": "thirdhand.generate.record",
    "FrameRecorder": "thirdhand.generate.record",
    "EpisodeJob": "thirdhand.generate.episodes",
    "EpisodeOutcome": "thirdhand.generate.episodes",
    "run_episode": "thirdhand.generate.episodes",
    "GenerateSummary": "thirdhand.generate.dataset",
    "generate_dataset": "thirdhand.generate.dataset",
    "jobs_for": "thirdhand.generate.dataset",
}

__all__ = sorted(_NAMES)


def __getattr__(name: str) -> Any:
    if name not in _NAMES:
        raise AttributeError(f"module 'thirdhand.generate' has no attribute {name!r}")
    return getattr(importlib.import_module(_NAMES[name]), name)
