"""The live frame source: replay at the recording's rate, gaps and jitter kept."""

from __future__ import annotations

import numpy as np
import pytest

from thirdhand.demonstration import BodyInfo, Demonstration
from thirdhand.errors import OptionError
from thirdhand.live.source import ReplaySource, check_speed


def _demo() -> Demonstration:
    rng = np.random.default_rng(0)
    t = np.cumsum(np.full(50, 0.01) + rng.uniform(-0.002, 0.002, 50))
    t[30:] += 2.5  # a gap
    pos = rng.normal(size=(50, 3))
    valid = np.ones(50, dtype=bool)
    valid[10:12] = False
    return Demonstration(
        t,
        [BodyInfo("a"), BodyInfo("b")],
        {"a": pos, "b": pos + 1},
        {"a": np.tile([0, 0, 0, 1.0], (50, 1)), "b": np.tile([0, 0, 0, 1.0], (50, 1))},
        valid={"a": valid, "b": np.ones(50, dtype=bool)},
    )


class FakeClock:
    def __init__(self) -> None:
        self.now = 100.0
        self.slept: list[float] = []

    def __call__(self) -> float:
        return self.now

    def sleep(self, s: float) -> None:
        self.slept.append(s)
        self.now += s


@pytest.mark.parametrize("speed", [1.0, 2.0, 0.5])
def test_replay_releases_each_frame_at_its_own_time(speed: float) -> None:
    demo = _demo()
    clock = FakeClock()
    frames = list(ReplaySource(demo, speed, clock=clock, sleep=clock.sleep))
    assert [f.t for f in frames] == demo.t.tolist()  # gaps and jitter as recorded
    due = 100.0 + (demo.t - demo.t[0]) / speed
    np.testing.assert_allclose([f.arrived for f in frames], due, atol=1e-12)
    assert clock.now == pytest.approx(due[-1])
    assert not frames[10].valid[0] and frames[10].valid[1]
    np.testing.assert_array_equal(frames[3].pos[1], demo.pos("b")[3])


def test_speed_zero_never_waits() -> None:
    clock = FakeClock()
    frames = list(ReplaySource(_demo(), 0, clock=clock, sleep=clock.sleep))
    assert len(frames) == 50 and clock.slept == []


@pytest.mark.parametrize("bad", [-1.0, float("inf"), float("nan")])
def test_bad_speed_is_one_line(bad: float) -> None:
    with pytest.raises(OptionError, match="--speed must be") as err:
        check_speed(bad)
    assert "\n" not in str(err.value)
