"""Stamps to time axis: sorted sample series, the merged frame axis, interpolation."""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numba
import numpy as np

from thirdhand import se3
from thirdhand.arrays import BoolArray, FloatArray, IntArray
from thirdhand.errors import FormatError
from thirdhand.io.rosbag.collect import _Track
from thirdhand.io.rosbag.constants import _NS


@dataclass
class _Series:
    """Observations of one stream sorted by stamp, duplicates removed.

    Attributes
    ----------
    stamps : ndarray of int64, shape (n,), nanoseconds since the Unix epoch
    pose : ndarray, shape (n, 7), x y z (metres) then qx qy qz qw, parent frame
    visible : ndarray of bool, shape (n,)
    frame : str
        The parent frame (``header.frame_id`` of the first message), may be empty.
    """

    stamps: IntArray
    pose: FloatArray
    visible: BoolArray
    frame: str = ""


def _fmt_stamp(ns: int) -> str:
    return f"{ns // _NS}.{ns % _NS:09d} s"


def _series(track: _Track, src: Path, what: str) -> _Series:
    """Sort by stamp, drop exact repeats, reject conflicting repeats and zero quaternions."""
    stamps = np.asarray(track.stamps, dtype=np.int64)
    pose = np.asarray(track.values, dtype=np.float64).reshape(-1, 7)
    visible = np.asarray(track.visible, dtype=bool)
    index = np.asarray(track.index, dtype=np.int64)
    order = np.argsort(stamps, kind="stable")
    stamps, pose, visible, index = stamps[order], pose[order], visible[order], index[order]
    same = np.flatnonzero(np.diff(stamps) == 0)
    if same.size:
        a, b = pose[same], pose[same + 1]
        differ = ~np.all((a == b) | (np.isnan(a) & np.isnan(b)), axis=1)
        differ |= visible[same] != visible[same + 1]
        if np.any(differ):
            i = int(same[differ][0])
            raise FormatError(
                src,
                f"{what}: two different poses with the same stamp {_fmt_stamp(int(stamps[i]))}",
                where=f"topic {track.topic} messages {index[i]} and {index[i + 1]}",
            )
        keep = np.ones(stamps.size, dtype=bool)
        keep[same + 1] = False
        stamps, pose, visible, index = stamps[keep], pose[keep], visible[keep], index[keep]
    finite = np.all(np.isfinite(pose), axis=1)
    zero = np.flatnonzero(visible & finite & (np.linalg.norm(pose[:, 3:], axis=1) < 1e-12))
    if zero.size:
        i = int(zero[0])
        raise FormatError(
            src,
            f"{what}: zero-norm quaternion at stamp {_fmt_stamp(int(stamps[i]))}",
            where=f"topic {track.topic} message {index[i]}",
        )
    return _Series(stamps, pose, visible & finite, track.frame)


@numba.njit(cache=True, nogil=True)
def _greedy_frames(stamps: IntArray, owner: IntArray, n_owners: int, tol_ns: int) -> IntArray:
    """Frame of each sorted stamp: a frame opens at the first stamp not yet placed
    and takes the following stamps within ``tol_ns`` of it, one per owner."""
    frame = np.empty(stamps.size, dtype=np.int64)
    last = np.full(n_owners, -1, dtype=np.int64)
    f = -1
    anchor = 0
    for i in range(stamps.size):
        if f < 0 or stamps[i] - anchor > tol_ns or last[owner[i]] == f:
            f += 1
            anchor = stamps[i]
        frame[i] = f
        last[owner[i]] = f
    return frame


def _frame_axis(streams: Sequence[IntArray], tol_ns: int) -> tuple[IntArray, list[IntArray]]:
    """Merge the stamps of several streams into one frame axis.

    Parameters
    ----------
    streams : sequence of int64 arrays, each shape (n_i,), sorted, unique, nanoseconds
    tol_ns : int
        Largest spread of stamps merged into one frame, nanoseconds.

    Returns
    -------
    frames : ndarray of int64, shape (n_frames,), nanoseconds, strictly increasing
        The earliest stamp of each frame.
    index : list of int64 arrays, shape (n_i,)
        Frame of each stamp of each stream.
    """
    if not streams:
        return np.zeros(0, np.int64), []
    stamps = np.concatenate(streams).astype(np.int64)
    owner = np.repeat(np.arange(len(streams), dtype=np.int64), [s.size for s in streams])
    order = np.argsort(stamps, kind="stable")
    sorted_stamps = stamps[order]
    frame = _greedy_frames(sorted_stamps, owner[order], len(streams), int(tol_ns))
    first = np.flatnonzero(np.diff(frame, prepend=-1))
    idx = np.empty(stamps.size, dtype=np.int64)
    idx[order] = frame
    bounds = np.cumsum([0] + [x.size for x in streams])
    return sorted_stamps[first], [idx[a:b] for a, b in itertools.pairwise(bounds)]


def _interpolate(series: _Series, t_ns: IntArray) -> tuple[FloatArray, FloatArray, BoolArray]:
    """Linear / slerp interpolation of a sample series, no extrapolation; exact at samples."""
    s = series.stamps
    n = s.size
    hi = np.searchsorted(s, t_ns, side="left")
    hic = np.minimum(hi, n - 1)
    lo = np.maximum(hi - 1, 0)
    exact = (hi < n) & (s[hic] == t_ns)
    inside = (hi > 0) & (hi < n)
    span = (s[hic] - s[lo]).astype(np.float64)
    w = np.where(inside, (t_ns - s[lo]) / np.where(span > 0, span, 1.0), 0.0)
    p0, p1 = series.pose[lo, :3], series.pose[hic, :3]
    p = p0 + w[:, None] * (p1 - p0)
    q0 = series.pose[lo, 3:] / np.linalg.norm(series.pose[lo, 3:], axis=1, keepdims=True)
    q1 = series.pose[hic, 3:] / np.linalg.norm(series.pose[hic, 3:], axis=1, keepdims=True)
    q = se3.quat_slerp(q0, q1, w)
    p[exact] = series.pose[hic[exact], :3]
    q[exact] = series.pose[hic[exact], 3:]
    ok = np.where(exact, series.visible[hic], inside & series.visible[lo] & series.visible[hic])
    return p, q, ok
