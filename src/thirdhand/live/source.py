"""Live frame sources: the interface a lab's streaming client implements, and a replay.

The live loop reads a :class:`FrameSource`: an iterable of :class:`Frame`, one
per sensor sample, in the order the sensor gave them. A lab connects its own
tracker by writing a class with the two attributes and the ``__iter__`` below
(for example around a ROS 2 subscription or a Motive NatNet client)::

    class MyClient:
        bodies = [BodyInfo("seating"), BodyInfo("rh_index", kind="finger", hand="right"), ...]
        meta = {}                       # optional geometry, as a Demonstration's meta

        def __iter__(self):
            for msg in my_stream():     # blocks until the next sample arrives
                yield Frame(t=msg.stamp, pos=..., quat=..., valid=..., arrived=time.perf_counter())

Rules of the interface:

- ``t`` is the stream's clock (seconds), strictly increasing; gaps and jitter
  stay as the sensor gave them: nothing is resampled.
- ``pos`` (n_bodies, 3) metres, world frame; ``quat`` (n_bodies, 4) x y z w;
  ``valid`` (n_bodies,) False where a body was not seen in that sample (its
  ``pos``/``quat`` rows are then ignored). Row ``i`` is ``bodies[i]``.
- ``arrived``: the wall-clock time (``time.perf_counter()``) at which the
  sample reached the process; the loop measures how late it processed each
  frame from it.

:class:`ReplaySource` replays any recording thirdhand reads at its real rate
times ``speed`` (0: as fast as possible), each frame released at its own time
stamp.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from thirdhand.arrays import BoolArray, FloatArray
from thirdhand.demonstration import BodyInfo, Demonstration
from thirdhand.errors import OptionError


@dataclass(frozen=True)
class Frame:
    """One timestamped sample of every tracked body.

    Attributes
    ----------
    t : float
        Stream clock, seconds.
    pos : ndarray, shape (n_bodies, 3), metres, world frame
    quat : ndarray, shape (n_bodies, 4), x y z w
    valid : ndarray of bool, shape (n_bodies,)
    arrived : float
        Wall clock (``time.perf_counter()``, seconds) at which the sample arrived.
    """

    t: float
    pos: FloatArray
    quat: FloatArray
    valid: BoolArray
    arrived: float


class FrameSource(Protocol):
    """What the live loop reads: body descriptions and an iterator of frames."""

    @property
    def bodies(self) -> Sequence[BodyInfo]:
        """The tracked bodies; row ``i`` of every frame is ``bodies[i]``."""
        ...

    @property
    def meta(self) -> Mapping[str, Any]:
        """Free-form metadata as a Demonstration's (``geometry`` gives part boxes)."""
        ...

    def __iter__(self) -> Iterator[Frame]: ...


class FrameLog:
    """A source passed through, every frame kept: the stream as a Demonstration afterwards.

    For a source that is not a recording already (a live client, a file being
    written), so that ``--record`` can write what arrived.
    """

    def __init__(self, source: FrameSource) -> None:
        self.source = source
        self.bodies = source.bodies
        self.meta = source.meta
        self.speed = getattr(source, "speed", 1.0)
        self.frames: list[Frame] = []

    def __iter__(self) -> Iterator[Frame]:
        for frame in self.source:
            self.frames.append(frame)
            yield frame

    def demonstration(self) -> Demonstration:
        """The frames received, as a recording (invalid rows NaN)."""
        names = [b.name for b in self.bodies]
        n = len(self.frames)
        t = np.array([f.t for f in self.frames], dtype=np.float64)
        valid = np.array([f.valid for f in self.frames], dtype=bool).reshape(n, len(names))
        pos = np.array([f.pos for f in self.frames], dtype=np.float64).reshape(n, len(names), 3)
        quat = np.array([f.quat for f in self.frames], dtype=np.float64).reshape(n, len(names), 4)
        pos[~valid] = np.nan
        quat[~valid] = np.nan
        return Demonstration(
            t,
            list(self.bodies),
            {b: pos[:, k] for k, b in enumerate(names)},
            {b: quat[:, k] for k, b in enumerate(names)},
            valid={b: valid[:, k] for k, b in enumerate(names)},
            meta=dict(self.meta),
        )


#: Slowest and fastest replay (times real time) other than 0, as fast as possible:
#: a hundred times slower turns a minute of recording into 100 minutes.
MIN_SPEED, MAX_SPEED = 0.01, 1000.0


def check_speed(speed: float) -> float:
    """A replay speed: 0 (as fast as possible) or within [MIN_SPEED, MAX_SPEED].

    Raises
    ------
    OptionError
        One line naming the value.
    """
    if not (speed == 0 or MIN_SPEED <= speed <= MAX_SPEED):  # NaN fails both
        raise OptionError(
            f"--speed must be 0 (as fast as possible) or between {MIN_SPEED:g} and "
            f"{MAX_SPEED:g} (1: real time), got {speed}"
        )
    return float(speed)


class ReplaySource:
    """Replay a recording as a stream at ``speed`` times its real rate.

    Parameters
    ----------
    demo : Demonstration
    speed : float
        1: real time; 2: twice as fast; 0: as fast as possible (no waiting).
    clock : callable, optional
        Wall clock in seconds (``time.perf_counter``); a test may pass its own.
    sleep : callable, optional
        ``time.sleep``; a test may pass its own.

    Notes
    -----
    Frame ``k`` is released at ``start + (t_k − t_0) / speed`` on the wall
    clock; ``Frame.arrived`` is that scheduled time (or the release time when
    the consumer fell behind, so lateness is measured from when it was due).
    The recording's own time stamps are kept: its gaps and jitter reach the
    consumer as the sensor gave them.
    """

    def __init__(
        self,
        demo: Demonstration,
        speed: float = 1.0,
        *,
        clock: Callable[[], float] = time.perf_counter,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        self.demo = demo
        self.speed = check_speed(speed)
        self._clock = clock
        self._sleep = sleep
        names = demo.body_names
        self._pos = np.stack([demo.pos(n) for n in names], axis=1)
        self._quat = np.stack([demo.quat(n) for n in names], axis=1)
        self._valid = np.stack([demo.valid(n) for n in names], axis=1)

    @property
    def bodies(self) -> Sequence[BodyInfo]:
        """The recording's bodies, in its order."""
        return self.demo.bodies

    @property
    def meta(self) -> Mapping[str, Any]:
        """The recording's metadata."""
        return self.demo.meta

    def __iter__(self) -> Iterator[Frame]:
        t = self.demo.t
        start = self._clock()
        for k in range(t.size):
            due = start
            if self.speed > 0:
                due = start + (float(t[k]) - float(t[0])) / self.speed
                wait = due - self._clock()
                if wait > 0:
                    self._sleep(wait)
            else:
                due = self._clock()
            yield Frame(
                t=float(t[k]),
                pos=self._pos[k],
                quat=self._quat[k],
                valid=self._valid[k],
                arrived=due,
            )


__all__ = ["Frame", "FrameSource", "ReplaySource", "check_speed"]
