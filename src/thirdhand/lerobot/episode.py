"""One episode of a LeRobot dataset in memory: per-frame features, videos and annotations."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from thirdhand.errors import OptionError

#: Columns every LeRobot dataset has; a feature of an episode may not take these names.
RESERVED = ("timestamp", "frame_index", "episode_index", "index", "task_index")


def _fail(message: str) -> OptionError:
    return OptionError(f"episode: {message}")


@dataclass(frozen=True)
class Episode:
    """The frames of one episode, sampled at a fixed rate from time 0.

    Parameters
    ----------
    fps : int
        Frames per second; frame ``i`` is at ``i / fps`` s (:attr:`timestamps`).
    task : str
        What the episode does, in words (one row of ``meta/tasks.parquet``).
    features : mapping str -> ndarray, shape (n_frames, n)
        Numeric features (``"observation.state"``, ``"action"``, …), written as
        float32; every value finite. Units and frames are the feature's (see
        the dataset's documentation).
    names : mapping str -> sequence of str
        For every feature, the name of each of its ``n`` columns.
    videos : mapping str -> ndarray of uint8, shape (n_frames, height, width, 3)
        RGB frames per camera (``"observation.images.front"``); height and width even.
    annotations : mapping str -> sequence of str, optional
        Per-frame text (``"annotation.interactions"``), one string per frame.

    Raises
    ------
    OptionError
        One line naming the feature and the problem.
    """

    fps: int
    task: str
    features: Mapping[str, NDArray[np.float32]]
    names: Mapping[str, tuple[str, ...]]
    videos: Mapping[str, NDArray[np.uint8]] = field(default_factory=dict)
    annotations: Mapping[str, tuple[str, ...]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if isinstance(self.fps, bool) or not isinstance(self.fps, int | np.integer):
            raise _fail(f"fps must be a whole number of frames per second, got {self.fps!r}")
        if self.fps <= 0:
            raise _fail(f"fps must be positive, got {self.fps}")
        if not isinstance(self.task, str) or not self.task.strip():
            raise _fail("the task text is empty")
        if not self.features:
            raise _fail("no feature: an episode needs at least one numeric feature")
        feats: dict[str, NDArray[np.float32]] = {}
        n_frames: int | None = None
        for key, raw in self.features.items():
            _check_key(key)
            arr = np.asarray(raw)
            if arr.ndim != 2 or arr.shape[1] == 0:
                raise _fail(f"feature {key!r} must have shape (n_frames, n), got {arr.shape}")
            if not np.issubdtype(arr.dtype, np.number) or np.iscomplexobj(arr):
                raise _fail(f"feature {key!r} is not numeric ({arr.dtype})")
            out = np.ascontiguousarray(arr, dtype=np.float32)
            bad = np.argwhere(~np.isfinite(out))
            if bad.size:
                f, c = (int(v) for v in bad[0])
                raise _fail(f"feature {key!r} frame {f} column {c} is not finite ({arr[f, c]})")
            n_frames = _same_length(n_frames, out.shape[0], key)
            out.setflags(write=False)
            feats[key] = out
        names: dict[str, tuple[str, ...]] = {}
        for key, arr in feats.items():
            if key not in self.names:
                raise _fail(f"feature {key!r} has no column names")
            cols = tuple(self.names[key])
            if len(cols) != arr.shape[1]:
                raise _fail(f"feature {key!r} has {arr.shape[1]} columns but {len(cols)} names")
            if len(set(cols)) != len(cols) or not all(isinstance(c, str) and c for c in cols):
                raise _fail(f"feature {key!r}: column names must be unique non-empty text")
            names[key] = cols
        extra = set(self.names) - set(feats)
        if extra:
            raise _fail(f"names given for no feature: {', '.join(sorted(extra))}")
        assert n_frames is not None
        videos: dict[str, NDArray[np.uint8]] = {}
        for key, given in self.videos.items():
            _check_key(key, taken=feats)
            frames = np.asarray(given)
            if frames.dtype != np.uint8 or frames.ndim != 4 or frames.shape[3] != 3:
                raise _fail(
                    f"video {key!r} must be uint8 of shape (n_frames, height, width, 3), "
                    f"got {frames.dtype} {frames.shape}"
                )
            h, w = frames.shape[1:3]
            if h % 2 or w % 2 or h < 2 or w < 2:
                raise _fail(f"video {key!r}: height and width must be even, got {h}x{w}")
            _same_length(n_frames, frames.shape[0], key)
            videos[key] = frames
        notes: dict[str, tuple[str, ...]] = {}
        for key, text in self.annotations.items():
            _check_key(key, taken={**feats, **videos})
            texts = tuple(text)
            if not all(isinstance(s, str) for s in texts):
                raise _fail(f"annotation {key!r} must be one string per frame")
            _same_length(n_frames, len(texts), key)
            notes[key] = texts
        object.__setattr__(self, "fps", int(self.fps))
        object.__setattr__(self, "features", feats)
        object.__setattr__(self, "names", names)
        object.__setattr__(self, "videos", videos)
        object.__setattr__(self, "annotations", notes)

    @property
    def n_frames(self) -> int:
        """Number of frames."""
        return int(next(iter(self.features.values())).shape[0])

    @property
    def timestamps(self) -> NDArray[np.float64]:
        """Time of every frame, shape (n_frames,), seconds from the episode's start."""
        return np.arange(self.n_frames, dtype=np.float64) / self.fps

    def layout(self) -> dict[str, Any]:
        """What must agree between the episodes of one dataset (keys, names, sizes)."""
        return {
            "fps": self.fps,
            "features": {k: self.names[k] for k in self.features},
            "videos": {k: tuple(v.shape[1:]) for k, v in self.videos.items()},
            "annotations": tuple(self.annotations),
        }


def _check_key(key: object, *, taken: Mapping[str, object] | None = None) -> None:
    if not isinstance(key, str) or not key:
        raise _fail(f"feature names must be non-empty text, got {key!r}")
    if "/" in key:
        raise _fail(f"feature name {key!r} contains '/' (LeRobot refuses it)")
    if key in RESERVED:
        raise _fail(f"feature name {key!r} is one of LeRobot's own columns")
    if taken is not None and key in taken:
        raise _fail(f"{key!r} names two features")


def _same_length(expected: int | None, got: int, key: str) -> int:
    if got < 1:
        raise _fail(f"{key!r} has no frame")
    if expected is not None and got != expected:
        raise _fail(f"{key!r} has {got} frames, the other features {expected}")
    return got
