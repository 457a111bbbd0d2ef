"""Where the assist's arm stands: its first place, and the stations it drives to for a fetch.

The arm's base stands on the far side of the assembly from the person
(:func:`away_from_person`), beyond the hand-over point. A fixed base takes the first
of the places turned about the root (:func:`fixed_places`) from which the arm at home
touches nothing tracked; a moving base (:class:`~thirdhand.live.base_track.BaseTrack`,
:func:`track_for`) the first such station nearest the middle of its track
(:func:`first_station`), and for each fetch tries the stations nearest the part it
can drive to (:func:`fetch_drives`).

Whether the arm at home touches something with its base at a point is the caller's
world to say: the functions take it as ``clear(point) -> bool``.

Frames: world, metres; only x and y vary (the base stays on the table's plane).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from thirdhand.arrays import FloatArray
from thirdhand.live.base_track import RETREATS_M, BaseTrack

#: A moving base tries the fetch from this many stations at most, the nearest the part first.
MAX_STATIONS = 3
#: The turns about the root (radians, from the far side) a fixed base tries, in order.
FIXED_TURNS = (0.0, 0.5, -0.5, 1.0, -1.0, 1.4, -1.4)
#: How much farther than its nearest distance a fixed base tries at each turn, metres.
FIXED_FARTHER_M = 0.1

#: Whether the arm at home touches nothing with its base at a point (3,), world.
Clear = Callable[[FloatArray], bool]


def away_from_person(root: FloatArray, hands: FloatArray) -> FloatArray:
    """Unit horizontal direction from the person to the root, shape (2,).

    ``root`` (3,): the root's position; ``hands`` (n, 3): the fingers tracked now (the
    person stands at their mean; 0.5 m towards -y of the root without any).
    """
    person = hands.mean(axis=0) if len(hands) else root - np.array([0.0, 0.5, 0.0])
    away = root[:2] - person[:2]
    away = away / max(float(np.linalg.norm(away)), 1e-9)
    return np.asarray(away, dtype=np.float64)


def base_distance(reach_m: float, handover_beyond_m: float, base_beyond_m: float) -> float:
    """How far from the root (horizontally) the arm's base stands, metres: beyond the
    assembly's reach by the hand-over's offset, and beyond that by ``base_beyond_m``."""
    return reach_m + handover_beyond_m + base_beyond_m


def track_for(
    root: FloatArray, away: FloatArray, near: float, track_m: float, table_z: float
) -> BaseTrack:
    """The track of a moving base: ``near`` metres beyond the root (3,) along ``away`` (2,),
    ``track_m`` long across that line, at the table's height ``table_z``."""
    return BaseTrack(root[:2] + near * away, away, track_m / 2.0, table_z)


def fixed_places(
    root: FloatArray, away: FloatArray, near: float, table_z: float
) -> list[tuple[FloatArray, FloatArray]]:
    """The places a fixed base tries, in order: ``(position (3,), direction (2,))`` each.

    At each of :data:`FIXED_TURNS` about the root (3,) from the far side (``away`` (2,)
    turned), ``near`` and :data:`FIXED_FARTHER_M` farther; the direction is the turned
    ``away`` (the base faces against it, towards the assembly).
    """
    out = []
    for ang in FIXED_TURNS:
        c, sn = math.cos(ang), math.sin(ang)
        turned = np.array([c * away[0] - sn * away[1], sn * away[0] + c * away[1]])
        for dist in (near, near + FIXED_FARTHER_M):
            out.append((np.array([*(root[:2] + dist * turned), table_z]), turned))
    return out


def first_fixed_place(
    places: list[tuple[FloatArray, FloatArray]],
    clear: Callable[[FloatArray, FloatArray], bool],
) -> tuple[FloatArray, FloatArray]:
    """The first of ``places`` (:func:`fixed_places`) where ``clear(position, direction)``;
    the last without one."""
    for place in places:
        if clear(*place):
            return place
    return places[-1]


def first_station(track: BaseTrack, clear: Clear) -> float:
    """The station nearest the middle of ``track`` where ``clear`` (the last tried without
    one), metres along the track."""
    for s in track.stations():
        if clear(track.position(s)):
            break
    return float(s)


def standing(track: BaseTrack | None, station: float, base: FloatArray) -> FloatArray:
    """Where the base stands (3,), world metres: a moving base at ``station`` of its track,
    once its drive is done; a fixed one at ``base``."""
    if track is None:
        return np.asarray(base, dtype=np.float64).copy()
    return track.position(station)


def route_clear(route: FloatArray, clear: Clear) -> bool:
    """Whether ``clear`` at every point of ``route`` (m, 3); the last point first: most
    routes fail there."""
    return all(clear(p) for p in route[::-1])


def fetch_drives(
    track: BaseTrack,
    station: float,
    here: FloatArray,
    part_xy: FloatArray,
    clear: Clear,
) -> list[tuple[float, FloatArray]]:
    """The stations to fetch a part from, and the base's routes to them.

    Parameters
    ----------
    track : BaseTrack
    station : float
        Where the base stands now along the track, metres.
    here : ndarray, shape (3,)
        Its position, world.
    part_xy : ndarray, shape (2,)
        The part's horizontal position, world.
    clear : callable
        Whether the arm at home touches nothing with its base at a point (3,).

    Returns
    -------
    list of (float, ndarray of shape (m, 3))
        The :data:`MAX_STATIONS` stations nearest the part at which the arm at home is
        clear and to which the base drives clear (checked every
        :data:`~thirdhand.live.base_track.STATION_STEP_M`, straight along the track or
        back from it by each of :data:`~thirdhand.live.base_track.RETREATS_M` in turn),
        with the route there (one row, ``here``: it stays), nearest first.
    """
    out: list[tuple[float, FloatArray]] = []
    for s in track.by_distance(part_xy):
        if len(out) == MAX_STATIONS:
            break
        if abs(s - station) < 1e-9:
            out.append((station, here[None]))
            continue
        for back in RETREATS_M:
            route = track.route(station, float(s), back)
            if route_clear(route[1:], clear):
                out.append((float(s), route))
                break
    return out


__all__ = [
    "FIXED_FARTHER_M",
    "FIXED_TURNS",
    "MAX_STATIONS",
    "away_from_person",
    "base_distance",
    "fetch_drives",
    "first_fixed_place",
    "first_station",
    "fixed_places",
    "route_clear",
    "standing",
    "track_for",
]
