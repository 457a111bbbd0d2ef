"""Learning a task from recordings: ``thirdhand learn`` and :func:`learn_task`.

- :mod:`~thirdhand.learn.run`: :func:`learn_task`, the stage verbs in order;
- :mod:`~thirdhand.learn.recordings`: the per-recording stages, and reading recordings;
- :mod:`~thirdhand.learn.stages`: primitives, reward, grasps and scene of a learned plan;
- :mod:`~thirdhand.learn.build`: the task file, built once from the results;
- :mod:`~thirdhand.learn.results`: the typed results passed between them;
- :mod:`~thirdhand.learn.settings`: ``[learn]`` of ``--config``;
- :mod:`~thirdhand.learn.cli`: the command; :mod:`~thirdhand.learn.report`: its HTML report.

Names are imported on first use, so importing the package costs nothing.
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS = {
    "learn_task": "thirdhand.learn.run",
    "Learned": "thirdhand.learn.results",
    "LearnedTask": "thirdhand.learn.results",
    "RecordingStages": "thirdhand.learn.results",
    "RewardResult": "thirdhand.learn.results",
    "LearnSettings": "thirdhand.learn.settings",
    "learned_events": "thirdhand.learn.stages",
    "reward_targets": "thirdhand.learn.stages",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'thirdhand.learn' has no attribute {name!r}")
