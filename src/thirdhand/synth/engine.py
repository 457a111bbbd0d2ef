"""Piecewise pose timelines of many bodies, evaluated vectorised over a frame grid.

Each body's motion is a sequence of :class:`Segment` objects; a segment starts at
a time and lasts until the next one starts. Its motion gives the pose either in
the world frame or in the frame of a parent body (a grasped part rides on the
hand's object, a screwed leg on the seat), so a chain of bodies moves together
exactly. Evaluation walks the parent chain once per body and segment, never per
frame.
"""

from __future__ import annotations

import bisect
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.errors import ThirdhandError

Motion = Callable[[FloatArray], tuple[FloatArray, FloatArray]]


@dataclass(frozen=True)
class Segment:
    """One piece of a body's motion.

    Attributes
    ----------
    start : float
        Seconds on the global time axis; the segment lasts until the next one starts.
    motion : callable
        ``motion(t_local) -> (pos (n, 3), quat (n, 4))``, metres and x y z w, in the
        world frame or in ``parent``'s frame.
    parent : str or None
        Body the pose is relative to; None for the world frame.
    t_offset, t_sign : float
        Global time ``t`` is mapped to the motion's own time ``t_offset + t_sign * t``
        (a shifted or time-reversed copy of a motion).
    """

    start: float
    motion: Motion
    parent: str | None = None
    t_offset: float = 0.0
    t_sign: float = 1.0

    def local(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Pose of the motion at global times ``t`` (n,): (n, 3) and (n, 4)."""
        return self.motion(self.t_offset + self.t_sign * t)


class Timeline:
    """Segments of every body; append in time order per body."""

    def __init__(self) -> None:
        self.segments: dict[str, list[Segment]] = {}

    def add(self, body: str, segment: Segment) -> None:
        """Append a segment; one starting at the same time as the last replaces it.

        Raises
        ------
        ThirdhandError
            If the segment starts before the body's last segment (a script bug).
        """
        segs = self.segments.setdefault(body, [])
        if segs and segment.start < segs[-1].start - 1e-12:
            raise ThirdhandError(
                f"timeline of {body!r}: segment at {segment.start:.6f} s starts before the "
                f"last one at {segs[-1].start:.6f} s"
            )
        if segs and abs(segment.start - segs[-1].start) <= 1e-12:
            segs[-1] = segment
        else:
            segs.append(segment)

    def put(self, body: str, start: float, motion: Motion, parent: str | None = None) -> None:
        """Append ``motion`` (in ``parent``'s frame, or the world) from ``start`` seconds."""
        self.add(body, Segment(start, motion, parent))

    def segment_at(self, body: str, t: float) -> Segment:
        """The segment of ``body`` active at time ``t`` (the first one before it starts)."""
        segs = self.segments.get(body)
        if not segs:
            raise ThirdhandError(f"timeline: body {body!r} has no motion")
        i = bisect.bisect_right([s.start for s in segs], t) - 1
        return segs[max(i, 0)]

    def pose_at(self, body: str, t: float, _depth: int = 0) -> tuple[FloatArray, FloatArray]:
        """World pose of ``body`` at time ``t``: position (3,) metres, quaternion (4,)."""
        if _depth > 64:
            raise ThirdhandError(f"timeline: parent chain of {body!r} loops")
        seg = self.segment_at(body, t)
        p, q = seg.local(np.array([t], dtype=np.float64))
        if seg.parent is None:
            return p[0], q[0]
        pp, pq = self.pose_at(seg.parent, t, _depth + 1)
        wp, wq = se3.pose_compose(pp, pq, p[0], q[0])
        return wp, wq

    def relative_at(self, parent: str, child: str, t: float) -> tuple[FloatArray, FloatArray]:
        """Pose of ``child`` in ``parent``'s frame at time ``t``: (3,) and (4,)."""
        pp, pq = self.pose_at(parent, t)
        cp, cq = self.pose_at(child, t)
        return se3.relative_pose(pp, pq, cp, cq)

    def evaluate(self, t: FloatArray, names: list[str]) -> dict[str, tuple[FloatArray, FloatArray]]:
        """World poses of ``names`` on the time grid ``t`` (n,): per body (n, 3) and (n, 4)."""
        out: dict[str, tuple[FloatArray, FloatArray]] = {}
        busy: set[str] = set()

        def world(name: str) -> tuple[FloatArray, FloatArray]:
            if name in out:
                return out[name]
            if name in busy:
                raise ThirdhandError(f"timeline: parent chain of {name!r} loops")
            busy.add(name)
            segs = self.segments.get(name)
            if not segs:
                raise ThirdhandError(f"timeline: body {name!r} has no motion")
            n = t.size
            pos = np.empty((n, 3))
            quat = np.empty((n, 4))
            bounds = np.searchsorted(t, [s.start for s in segs], side="left")
            bounds[0] = 0
            ends = np.append(bounds[1:], n)
            for seg, i0, i1 in zip(segs, bounds, ends, strict=True):
                if i1 <= i0:
                    continue
                p, q = seg.local(t[i0:i1])
                if seg.parent is not None:
                    pp, pq = world(seg.parent)
                    p, q = se3.pose_compose(pp[i0:i1], pq[i0:i1], p, q)
                pos[i0:i1] = p
                quat[i0:i1] = q
            busy.discard(name)
            out[name] = (pos, quat)
            return out[name]

        for name in names:
            world(name)
        return {name: out[name] for name in names}
