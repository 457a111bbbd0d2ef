"""The assist's base track: stations, routes and their times, worked out by hand."""

from __future__ import annotations

import numpy as np
import pytest

from thirdhand import se3
from thirdhand.live.base_track import STATION_STEP_M, BaseTrack, route_times


def track() -> BaseTrack:
    """A track 0.6 m beyond (1, 2) from a person on -y, 0.35 m to either side, at z 0.75."""
    return BaseTrack(np.array([1.0, 2.6]), np.array([0.0, 1.0]), 0.35, 0.75)


def test_stations_lie_every_step_nearest_the_middle_first() -> None:
    s = track().stations()
    np.testing.assert_allclose(s, [0.0, -0.1, 0.1, -0.2, 0.2, -0.3, 0.3], atol=1e-12)
    # along the track: away (0, 1) turned a quarter to the left is -x
    np.testing.assert_allclose(track().side, [-1.0, 0.0])
    np.testing.assert_allclose(track().position(0.2), [0.8, 2.6, 0.75], atol=1e-12)
    np.testing.assert_allclose(track().position(-0.1, back=0.4), [1.1, 3.0, 0.75], atol=1e-12)
    # the base faces the assembly: its x axis points back along -away
    x = se3.quat_rotate(track().quat, np.array([1.0, 0.0, 0.0]))
    np.testing.assert_allclose(x, [0.0, -1.0, 0.0], atol=1e-12)


def test_stations_by_distance_from_a_part() -> None:
    t = track()
    got = t.by_distance(np.array([0.55, 2.0]))  # nearest x = 0.55: offsets 0.45 -> 0.3 last
    np.testing.assert_allclose(got[:3], [0.3, 0.2, 0.1], atol=1e-12)


@pytest.mark.parametrize("back", [0.0, 0.2, 0.45])
def test_a_route_goes_out_along_and_in_in_short_straight_steps(back: float) -> None:
    t = track()
    route = t.route(0.3, -0.2, back)
    np.testing.assert_allclose(route[0], t.position(0.3), atol=1e-12)
    np.testing.assert_allclose(route[-1], t.position(-0.2), atol=1e-12)
    steps = np.linalg.norm(np.diff(route, axis=0), axis=1)
    assert np.all(steps <= STATION_STEP_M + 1e-12) and np.all(steps > 0)
    # its length is out + along + in
    assert steps.sum() == pytest.approx(2 * back + 0.5, abs=1e-12)
    # every point is on one of the three legs: on the track's line at either end, or back
    y = route[:, 1] - 2.6
    x = route[:, 0]
    on_leg = np.isclose(x, 0.7) | np.isclose(x, 1.2) | np.isclose(y, back)
    assert np.all(on_leg) and np.all((y >= -1e-12) & (y <= back + 1e-12))
    np.testing.assert_allclose(route[:, 2], 0.75)
    # at 0.5 m/s from t = 2 s
    times = route_times(route, 2.0, 0.5)
    assert times[0] == 2.0 and times[-1] == pytest.approx(2.0 + (2 * back + 0.5) / 0.5)
    np.testing.assert_allclose(np.diff(times), steps / 0.5, atol=1e-12)


def test_a_route_to_where_it_stands_is_that_place() -> None:
    route = track().route(0.1, 0.1, 0.0)
    assert route.shape == (1, 3)
    assert route_times(route, 3.0, 0.5).tolist() == [3.0]
