"""Where the assist's mobile base may stand, and the way it drives between two places.

The arm of :mod:`thirdhand.live.assist` stands on a base that moves along the far side
of the assembly from the person (a mobile base, or an arm on a linear axis): a
straight *track* across the line from the person to the assembly's root, ``near``
metres beyond the root, ``half_m`` to either side. The base always faces the
assembly. Parts lying on the table where the track runs (the chair's back) may
block it, so the base drives from one *station* (a point of the track, every
:data:`STATION_STEP_M`) to another straight back from the table by a *retreat*,
along the track there, and in again: :meth:`BaseTrack.route`.

Frames: world, metres; only x and y vary (the base stays on the table's plane).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from thirdhand.arrays import FloatArray

#: Spacing of the stations along the track, and of the points a route is checked at, metres.
STATION_STEP_M = 0.1
#: How far back from the track a drive between two stations may go, metres, the shortest
#: first: straight along the track when nothing lies on it.
RETREATS_M = (0.0, 0.2, 0.4, 0.6, 0.8)


@dataclass(frozen=True)
class BaseTrack:
    """The straight line the base moves along.

    Attributes
    ----------
    origin : ndarray, shape (2,)
        World x, y of station 0 (straight beyond the root from the person).
    away : ndarray, shape (2,)
        Unit direction from the person to the root, horizontal.
    half_m : float
        The track reaches this far to either side of station 0, metres.
    z : float
        Height of the base (the table's top), metres.
    """

    origin: FloatArray
    away: FloatArray
    half_m: float
    z: float

    @property
    def side(self) -> FloatArray:
        """Unit direction along the track (``away`` turned a quarter to the left), shape (2,)."""
        return np.array([-self.away[1], self.away[0]])

    @property
    def quat(self) -> FloatArray:
        """The base's orientation at every station: facing the assembly (x y z w)."""
        yaw = math.atan2(-self.away[1], -self.away[0])
        return np.array([0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)])

    def stations(self) -> FloatArray:
        """Offsets of the stations along the track, shape (k,), metres, nearest 0 first."""
        n = math.floor(self.half_m / STATION_STEP_M + 1e-9)
        s = STATION_STEP_M * np.arange(-n, n + 1, dtype=np.float64)
        return s[np.argsort(np.abs(s), kind="stable")]

    def position(self, s: float, back: float = 0.0) -> FloatArray:
        """World position of the base at offset ``s`` along the track, ``back`` beyond it, (3,)."""
        xy = self.origin + s * self.side + back * self.away
        return np.array([xy[0], xy[1], self.z])

    def by_distance(self, xy: FloatArray) -> FloatArray:
        """The station offsets ordered by horizontal distance from ``xy`` (2,), nearest first."""
        s = self.stations()
        d = np.array([float(np.linalg.norm(self.position(v)[:2] - xy[:2])) for v in s])
        return s[np.argsort(d, kind="stable")]

    def route(self, s0: float, s1: float, back: float) -> FloatArray:
        """The drive from station ``s0`` to station ``s1``, ``back`` metres back from the track.

        Returns
        -------
        ndarray, shape (m, 3)
            World positions every :data:`STATION_STEP_M` at most along the three
            straight legs (out, along, in), both ends included; one row when
            ``s0 == s1``.
        """
        corners = [
            self.position(s0),
            self.position(s0, back),
            self.position(s1, back),
            self.position(s1),
        ]
        points = [corners[0]]
        for a, b in itertools.pairwise(corners):
            n = math.ceil(float(np.linalg.norm(b - a)) / STATION_STEP_M - 1e-9)
            points += [a + (b - a) * k / n for k in range(1, n + 1)]
        return np.asarray(points, dtype=np.float64)


def route_times(route: FloatArray, start: float, speed: float) -> FloatArray:
    """When the base is at each point of ``route`` (m, 3), driving at ``speed`` m/s from
    ``start`` (stream clock, seconds); shape (m,)."""
    steps = np.linalg.norm(np.diff(route, axis=0), axis=1)
    return start + np.concatenate([[0.0], np.cumsum(steps)]) / speed


__all__ = ["RETREATS_M", "STATION_STEP_M", "BaseTrack", "route_times"]
