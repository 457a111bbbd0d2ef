"""A human recording as one LeRobot episode: every tracked body's pose per frame.

``observation.state`` holds, per body, its position (metres, the recording's
world frame) and orientation (unit quaternion x, y, z, w, sign-continuous),
named ``<body>.x``, ``<body>.y``, ``<body>.z``, ``<body>.qx``, ``<body>.qy``,
``<body>.qz``, ``<body>.qw``, resampled at the dataset's frame rate from the
recording's first frame (linear interpolation and slerp, never across a
tracking gap longer than ``max_gap``). A frame where a body is not tracked
holds its nearest tracked pose, and ``observation.tracked`` (1 or 0 per body,
named ``<body>``) says which frames were tracked. The recording's interaction
labels, if any, become the per-frame text ``annotation.interactions``: the
pairs ``a+b`` interacting at that frame, joined by ``"; "`` (empty when none).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from thirdhand.demonstration import Demonstration
from thirdhand.errors import DemonstrationError, OptionError
from thirdhand.lerobot.episode import Episode

STATE = "observation.state"
TRACKED = "observation.tracked"
INTERACTIONS = "annotation.interactions"
POSE_COLUMNS = ("x", "y", "z", "qx", "qy", "qz", "qw")


@dataclass(frozen=True)
class HumanEpisode:
    """A recording as an episode, and the bodies left out (never tracked)."""

    episode: Episode
    dropped: tuple[str, ...]


def _hold_nearest(values: NDArray[np.float64], valid: NDArray[np.bool_]) -> NDArray[np.float64]:
    """Fill invalid rows with the nearest valid row (the earlier one on a tie)."""
    idx = np.flatnonzero(valid)
    pos = np.searchsorted(idx, np.arange(valid.size))
    before = idx[np.clip(pos - 1, 0, idx.size - 1)]
    after = idx[np.clip(pos, 0, idx.size - 1)]
    rows = np.arange(valid.size)
    take = np.where(np.abs(rows - before) <= np.abs(after - rows), before, after)
    return values[take]


def recording_episode(
    demo: Demonstration, *, fps: int, task: str, max_gap: float = 0.1
) -> HumanEpisode:
    """The recording ``demo`` as one episode at ``fps`` frames per second.

    Parameters
    ----------
    demo : Demonstration
        The recording.
    fps : int
        Frames per second of the episode.
    task : str
        The task text.
    max_gap : float
        Longest tracking gap interpolated across, seconds (see
        :meth:`~thirdhand.demonstration.Demonstration.resample`).

    Raises
    ------
    OptionError
        ``fps`` is not a positive whole number, or no body is ever tracked.
    """
    if isinstance(fps, bool) or not isinstance(fps, int | np.integer) or fps <= 0:
        raise OptionError(f"--fps must be a positive whole number, got {fps!r}")
    try:
        res = demo.with_continuous_quaternions().resample(float(fps), max_gap=max_gap)
    except DemonstrationError as exc:
        raise OptionError(f"cannot resample the recording at {fps} Hz: {exc}") from None
    kept = [b for b in res.body_names if res.valid(b).any()]
    dropped = tuple(b for b in res.body_names if b not in kept)
    if not kept:
        raise OptionError("no body of the recording is ever tracked; nothing to write")
    state, tracked, names = [], [], []
    for b in kept:
        valid = res.valid(b)
        pose = np.concatenate([res.pos(b), res.quat(b)], axis=1)
        state.append(_hold_nearest(pose, valid))
        tracked.append(valid.astype(np.float32))
        names += [f"{b}.{c}" for c in POSE_COLUMNS]
    features: dict[str, NDArray[np.float32]] = {
        STATE: np.concatenate(state, axis=1).astype(np.float32),
        TRACKED: np.stack(tracked, axis=1),
    }
    columns = {STATE: tuple(names), TRACKED: tuple(kept)}
    annotations = {}
    if res.labels.interactions:
        t = res.t
        per_frame: list[list[str]] = [[] for _ in t]
        for iv in res.labels.interactions:
            for k in np.flatnonzero((t >= iv.start) & (t <= iv.end)):
                per_frame[int(k)].append(f"{iv.a}+{iv.b}")
        annotations[INTERACTIONS] = tuple("; ".join(sorted(p)) for p in per_frame)
    episode = Episode(
        fps=int(fps), task=task, features=features, names=columns, annotations=annotations
    )
    return HumanEpisode(episode=episode, dropped=dropped)
