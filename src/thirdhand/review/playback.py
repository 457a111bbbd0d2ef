"""Playback of a demonstration for the review GUI: poses at a time, parts coloured by hand.

The report's Fig. 2 shows a recorded assembly with every part coloured by the
hand that holds it. :class:`Timeline` gives every body's pose at a time (its
last valid pose at or before it, so a tracking gap freezes the part rather than
hiding it); :class:`HandContacts` says which hand (left, right or both)
interacts with each object at a time. The contacts come from the
demonstration's ground-truth interaction labels when it has them, else from
the segmentation stage (:func:`thirdhand.segment.segment_demonstration`).

Nothing here imports viser: the GUI (:mod:`thirdhand.review.app`) only asks
for poses and colours.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from thirdhand.arrays import FloatArray, IntArray
from thirdhand.demonstration import Demonstration

Side = Literal["left", "right", "both", "robot"]

#: Colour of a part held by each hand, RGB 0-255 (right red, left green, both purple).
HAND_RGB: dict[str, tuple[int, int, int]] = {
    "right": (215, 48, 39),
    "left": (26, 152, 80),
    "both": (118, 42, 131),
}
#: Colour of a part the robot holds in an execution replay.
ROBOT_RGB: tuple[int, int, int] = (0, 150, 136)
#: Colour of a part nobody holds during playback.
IDLE_RGB: tuple[int, int, int] = (170, 170, 170)


def _last_valid_index(valid: NDArray[np.bool_]) -> IntArray:
    """For each frame, the index of the last valid frame at or before it (-1: none yet)."""
    idx = np.where(valid, np.arange(valid.size), -1)
    return np.maximum.accumulate(idx).astype(np.int64)


class Timeline:
    """Every body's pose at any time of a demonstration.

    Parameters
    ----------
    demo : Demonstration
    kinds : iterable of str
        Body kinds to play back (default parts, tools and fingers).

    Attributes
    ----------
    names : list of str
        The bodies played back, in the demonstration's order.
    start, end : float
        First and last time of the recording, seconds.
    """

    def __init__(
        self, demo: Demonstration, *, kinds: Iterable[str] = ("part", "tool", "finger", "hand")
    ) -> None:
        wanted = set(kinds)
        self.demo = demo
        self.names = [b.name for b in demo.bodies if b.kind in wanted]
        self.start = float(demo.t[0])
        self.end = float(demo.t[-1])
        self._last = {n: _last_valid_index(demo.valid(n)) for n in self.names}
        self._first = {
            n: (int(np.flatnonzero(demo.valid(n))[0]) if demo.valid(n).any() else -1)
            for n in self.names
        }

    def frame_at(self, time: float) -> int:
        """Index of the last frame at or before ``time`` (clamped to the recording)."""
        k = int(np.searchsorted(self.demo.t, time, side="right")) - 1
        return min(max(k, 0), self.demo.n_frames - 1)

    def poses_at(self, time: float) -> dict[str, tuple[FloatArray, FloatArray]]:
        """Every body's pose at ``time``: its last valid pose at or before it.

        A body not yet seen takes its first valid pose; a body never tracked is
        left out.

        Returns
        -------
        dict of str to (pos, quat)
            ``pos`` shape (3,), metres, world frame; ``quat`` shape (4,), x y z w.
        """
        k = self.frame_at(time)
        out: dict[str, tuple[FloatArray, FloatArray]] = {}
        for n in self.names:
            j = int(self._last[n][k])
            if j < 0:
                j = self._first[n]
                if j < 0:
                    continue
            track = self.demo.track(n)
            out[n] = (track.pos[j].copy(), track.quat[j].copy())
        return out


@dataclass
class HandContacts:
    """Which hand interacts with each object, over time.

    Attributes
    ----------
    intervals : dict of (object, side) to list of (start, end)
        Seconds; ``side`` is ``"left"`` or ``"right"``.
    source : str
        ``"labels"``, ``"segmentation"`` or ``"execution"`` (side ``"robot"``: an
        execution replay, :func:`thirdhand.review.replay.robot_contacts`).
    """

    intervals: dict[tuple[str, str], list[tuple[float, float]]] = field(default_factory=dict)
    source: str = "labels"

    @property
    def objects(self) -> list[str]:
        """The objects some hand interacts with, sorted."""
        return sorted({o for o, _ in self.intervals})

    def at(self, time: float) -> dict[str, Side]:
        """The objects held at ``time`` and by which hand (``"both"`` when both hold it)."""
        held: dict[str, set[str]] = {}
        for (obj, side), spans in self.intervals.items():
            if any(s <= time <= e for s, e in spans):
                held.setdefault(obj, set()).add(side)
        out: dict[str, Side] = {}
        for obj, sides in held.items():
            if sides == {"robot"}:
                out[obj] = "robot"
                continue
            sides.discard("robot")
            out[obj] = "both" if len(sides) > 1 else ("left" if "left" in sides else "right")
        return out


def _add(
    out: dict[tuple[str, str], list[tuple[float, float]]],
    key: tuple[str, str],
    span: tuple[float, float],
) -> None:
    spans = out.setdefault(key, [])
    if span not in spans:
        spans.append(span)


def contacts_from_labels(demo: Demonstration) -> HandContacts | None:
    """Hand contacts from the ground-truth interaction labels (finger/hand - object pairs).

    Returns None when the demonstration has no such labels.
    """
    info = {b.name: b for b in demo.bodies}
    out: dict[tuple[str, str], list[tuple[float, float]]] = {}
    for iv in demo.labels.interactions:
        for hand_body, obj in ((iv.a, iv.b), (iv.b, iv.a)):
            h, o = info.get(hand_body), info.get(obj)
            if h is None or o is None or h.kind not in ("finger", "hand"):
                continue
            if o.kind in ("finger", "hand") or h.hand not in ("left", "right"):
                continue
            _add(out, (obj, h.hand), (float(iv.start), float(iv.end)))
    return HandContacts(out, "labels") if out else None


def contacts_from_segmentation(demo: Demonstration) -> HandContacts:
    """Hand contacts found by the segmentation stage (the shipped CRF model).

    Each hand result names its fingers; the hand's side is theirs.
    """
    from thirdhand.segment import segment_demonstration

    result = segment_demonstration(demo)
    info = {b.name: b for b in demo.bodies}
    out: dict[tuple[str, str], list[tuple[float, float]]] = {}
    for h in result.hands:
        sides = {info[f].hand for f in h.fingers if f in info}
        side = next(iter(sides)) if len(sides) == 1 else None
        if side not in ("left", "right"):
            continue
        for s, e in h.intervals:
            _add(out, (h.object, side), (float(s), float(e)))
    return HandContacts(out, "segmentation")


def hand_contacts(demo: Demonstration, *, segment: bool = True) -> HandContacts:
    """Hand contacts from the labels when present, else (if ``segment``) the segmentation."""
    labelled = contacts_from_labels(demo)
    if labelled is not None:
        return labelled
    if segment:
        return contacts_from_segmentation(demo)
    return HandContacts({}, "none")


def playback_colours(
    contacts: HandContacts, names: Iterable[str], time: float
) -> dict[str, tuple[int, int, int]]:
    """Colour of every object at ``time``: its holding hand's, else :data:`IDLE_RGB`."""
    held: Mapping[str, Side] = contacts.at(time)
    rgb = {**HAND_RGB, "robot": ROBOT_RGB}
    return {n: rgb[held[n]] if n in held else IDLE_RGB for n in names}
