"""Lazy imports of the optional ``perception`` extra (MediaPipe and OpenCV).

The rest of thirdhand never needs them, so they are imported on first use and a
missing one is a :class:`~thirdhand.errors.ThirdhandError` telling how to install it.
"""

from __future__ import annotations

import contextlib
import importlib
import os
import sys
from collections.abc import Iterator
from types import ModuleType
from typing import Any

from thirdhand.errors import ThirdhandError

_HINT = "install the perception extra: pip install 'thirdhand[perception]'"


def _load(name: str, what: str) -> ModuleType:
    try:
        return importlib.import_module(name)
    except ImportError as exc:
        raise ThirdhandError(f"{what} needs the Python package {name!r} ({exc}); {_HINT}") from None


def cv2() -> Any:
    """The ``cv2`` module (OpenCV), or a ThirdhandError saying how to install it."""
    # FFmpeg prints to stderr on a corrupt file; the FormatError says it in one line.
    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")
    return _load("cv2", "reading video and solving head pose")


def mediapipe() -> Any:
    """The ``mediapipe`` module with its bundled face-mesh model, quietened.

    MediaPipe's C++ logging goes to stderr unless told otherwise; the
    environment variables are only set when the user has not set them.
    """
    os.environ.setdefault("GLOG_minloglevel", "2")
    os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")
    mp = _load("mediapipe", "face landmarks")
    if not hasattr(mp, "solutions") or not hasattr(mp.solutions, "face_mesh"):
        raise ThirdhandError(
            f"mediapipe {getattr(mp, '__version__', '?')} ships no face-mesh model "
            "(mediapipe.solutions.face_mesh; versions 0.10.14-0.10.21 do); " + _HINT
        )
    return mp


@contextlib.contextmanager
def quiet_native_stderr() -> Iterator[None]:
    """Send file descriptor 2 to the null device for the block; Python's stderr keeps working.

    MediaPipe's C++ side (TFLite, absl) logs to descriptor 2 from its own threads,
    before any logging set-up the environment variables could reach ("Created
    TensorFlow Lite XNNPACK delegate", "All log messages before
    absl::InitializeLog()"); the CLI's stderr is for one error line. Meanwhile
    ``sys.stderr`` writes to a copy of the original descriptor, so Python's own
    messages (warnings, a traceback) still reach the terminal.
    """
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError, AttributeError):
        yield
        return
    python_stderr = sys.stderr
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, 2)
    finally:
        os.close(null)
    sys.stderr = os.fdopen(os.dup(saved), "w", buffering=1, encoding="utf-8", errors="replace")
    try:
        yield
    finally:
        replacement = sys.stderr
        sys.stderr = python_stderr
        replacement.close()
        os.dup2(saved, 2)
        os.close(saved)
