"""When the assist's arm moves: the schedule of a planned fetch, and where it is at a time.

A fetch is two planned paths, home to the grasp and the lift to the hand-over
(:mod:`thirdhand.live.fetch_plan`). Its schedule
(:func:`schedule_fetch`) starts when the planning ends, after the base finished the drive
it is on and drove to the fetch's station; the arm then moves each segment at the joint
speed, closing the gripper between the two paths. :func:`configuration_at` and
:func:`route_index` say where the arm and the base are at a stream time.

Times: the stream clock, seconds. Joint configurations: radians, shape (dof,).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from thirdhand.arrays import FloatArray
from thirdhand.live.base_track import route_times


@dataclass(frozen=True)
class FetchSchedule:
    """When the arm is where along a fetch.

    Attributes
    ----------
    path : ndarray, shape (m, dof)
        The waypoints: the path to the grasp, then from the lift to the hand-over.
    times : ndarray, shape (m,)
        Stream time at which the arm reaches each waypoint.
    grasp_index : int
        The waypoint of the grasp (the next one is the lift's end).
    base_route : ndarray, shape (k, 3)
        The base's drive before the arm moves (world, metres; empty: it stays).
    base_times : ndarray, shape (k,)
        Stream time at which the base is at each point of ``base_route``.
    """

    path: FloatArray
    times: FloatArray
    grasp_index: int
    base_route: FloatArray
    base_times: FloatArray

    @property
    def ready_s(self) -> float:
        """When the part is at the hand-over pose (the last waypoint), seconds."""
        return float(self.times[-1])


def schedule_fetch(
    to_grasp: FloatArray,
    to_hand: FloatArray,
    *,
    start_s: float,
    base_free_s: float | None,
    route: FloatArray,
    joint_speed: float,
    grasp_s: float,
    base_speed: float,
) -> FetchSchedule:
    """The schedule of a fetch planned by ``start_s`` (its decision plus the planning time).

    Parameters
    ----------
    to_grasp : ndarray, shape (m1, dof)
        The path from home to the grasp.
    to_hand : ndarray, shape (m2, dof)
        The path from the lift's end to the hand-over (the lift is the straight segment
        between the two).
    start_s : float
        When the planning ended, seconds.
    base_free_s : float or None
        A moving base: when it finishes the drive it is on (the fetch waits for it);
        None: a fixed base.
    route : ndarray, shape (k, 3)
        The base's drive to the fetch's station (k > 1), before the arm moves.
    joint_speed : float
        Largest joint speed, rad/s: the largest joint's motion sets each segment's
        duration.
    grasp_s : float
        Seconds to close the gripper, between the two paths.
    base_speed : float
        Speed of the base along its route, m/s.
    """
    path = np.vstack([to_grasp, to_hand])
    seg = np.abs(np.diff(path, axis=0)).max(axis=1) / joint_speed
    seg[len(to_grasp) - 1] += grasp_s  # closing the gripper between the two paths
    start = start_s
    if base_free_s is not None:  # the base finishes the drive it is on first
        start = max(start, base_free_s)
    base_route, base_times = np.zeros((0, 3)), np.zeros(0)
    if len(route) > 1:
        base_route = route
        base_times = route_times(route, start, base_speed)
        start = float(base_times[-1])
    times = start + np.concatenate([[0.0], np.cumsum(seg)])
    return FetchSchedule(path, times, len(to_grasp) - 1, base_route, base_times)


def route_index(times: FloatArray, t: float) -> int:
    """The last point of a route or path (``times`` (m,), increasing) reached at ``t``
    (-1 before the first)."""
    return int(np.searchsorted(times, t, side="right")) - 1


def configuration_at(path: FloatArray, times: FloatArray, t: float) -> tuple[int, FloatArray]:
    """The arm's configuration at ``t`` along ``path`` (m, dof) reached at ``times`` (m,),
    linear between waypoints, the last one held after it; with the segment it is on
    (:func:`route_index`). ``t`` at or after ``times[0]``."""
    k = route_index(times, t)
    if k >= len(times) - 1:
        return k, path[-1]
    f = (t - times[k]) / max(times[k + 1] - times[k], 1e-9)
    return k, path[k] + f * (path[k + 1] - path[k])


__all__ = ["FetchSchedule", "configuration_at", "route_index", "schedule_fetch"]
