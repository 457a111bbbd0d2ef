"""A motion-capture sensor model: sampling rate, noise, occlusion gaps, quaternion signs.

Two kinds of loss, both measured on real recordings (``research/notes/segmentation_results.md``,
"Realistic sensor"): *occlusions* of one body (Poisson gaps of ``gap_min`` to
``gap_max`` seconds: an AR tag turned away for seconds) and *dropouts* of a whole
hub (a Polhemus G4 hub serves the sensors of one hand or of the objects; its
packets are lost for 1–``dropout_max`` frames at a time, ~15 times a second,
every sensor of the hub together). Time stamps can carry jitter
(``time_jitter``, a fraction of the frame period): the stamps of a real
recording are not the instants the poses were sampled. :meth:`SensorModel.random`
draws a sensor from the range real trackers span (10 µm–1 mm noise, 20–120 Hz).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from thirdhand import se3
from thirdhand.arrays import BoolArray, FloatArray
from thirdhand.errors import ThirdhandError
from thirdhand.synth.motion import quat_exp


@dataclass(frozen=True)
class SensorModel:
    """How the tracker sees the scene.

    Attributes
    ----------
    rate : float
        Frame rate, Hz (100–120 Hz is typical of optical and magnetic trackers).
    pos_noise : float
        Standard deviation of the white position noise per axis, metres.
    rot_noise : float
        Standard deviation of each component of the rotation-vector noise applied in
        the body frame, radians.
    finger_gap_rate, body_gap_rate : float
        Occlusion gaps per second of a fingertip, and of any other body.
    gap_min, gap_max : float
        Gap lengths are log-uniform in ``[gap_min, gap_max]``, seconds.
    sign_flips : bool
        Give each frame's quaternion a random sign (``q`` and ``−q`` are the same
        rotation; trackers do not keep the sign continuous).
    """

    rate: float = 120.0
    pos_noise: float = 0.001
    rot_noise: float = math.radians(0.5)
    finger_gap_rate: float = 0.15
    body_gap_rate: float = 0.03
    gap_min: float = 0.05
    gap_max: float = 0.5
    sign_flips: bool = True
    dropout_rate: float = 0.0
    dropout_max: int = 3
    time_jitter: float = 0.0

    @classmethod
    def random(cls, rng: np.random.Generator) -> SensorModel:
        """A sensor drawn from the range of real trackers.

        Position noise log-uniform in 10 µm–1 mm (a Polhemus at rest to an
        optical system), rotation noise 10–30 rad per metre of it (0.01°–1.7°),
        frame rate 20–120 Hz, hub dropouts (runs of 1–3 frames losing up to a
        quarter of the frames) in most recordings, time-stamp jitter up to half a
        frame period.
        """
        pos_noise = float(np.exp(rng.uniform(np.log(1e-5), np.log(1e-3))))
        rate = float(rng.choice([20.0, 30.0, 50.0, 60.0, 100.0, 120.0]))
        run = int(rng.integers(1, 4))
        # Up to a quarter of the frames lost in runs of 1..run frames (the real
        # Polhemus file: 19-25 %, ~15 runs a second at 100 Hz).
        lost = float(rng.uniform(0.0, 0.25)) if rng.random() < 0.7 else 0.0
        return cls(
            rate=rate,
            pos_noise=pos_noise,
            rot_noise=pos_noise * float(rng.uniform(10.0, 30.0)),
            finger_gap_rate=float(rng.uniform(0.0, 0.2)),
            body_gap_rate=float(rng.uniform(0.0, 0.05)),
            dropout_rate=lost * rate / ((1 + run) / 2),
            dropout_max=run,
            time_jitter=float(rng.uniform(0.0, 0.5)),
        )

    def __post_init__(self) -> None:
        if not (isinstance(self.dropout_max, int) and self.dropout_max >= 1):
            raise ThirdhandError(
                f"SensorModel.dropout_max must be >= 1 frame, got {self.dropout_max}"
            )
        if not 0.0 <= self.time_jitter < 1.0:
            raise ThirdhandError(
                f"SensorModel.time_jitter must be in [0, 1) frame periods, got {self.time_jitter}"
            )
        if not (math.isfinite(self.rate) and self.rate <= 10_000):
            raise ThirdhandError(f"SensorModel.rate must be finite and <= 10 kHz, got {self.rate}")
        for name in ("rate", "gap_min", "gap_max"):
            if not getattr(self, name) > 0:
                raise ThirdhandError(f"SensorModel.{name} must be > 0, got {getattr(self, name)}")
        for name in ("pos_noise", "rot_noise", "finger_gap_rate", "body_gap_rate", "dropout_rate"):
            if not (getattr(self, name) >= 0 and math.isfinite(getattr(self, name))):
                raise ThirdhandError(f"SensorModel.{name} must be >= 0, got {getattr(self, name)}")
        if self.gap_min > self.gap_max:
            raise ThirdhandError(
                f"SensorModel.gap_min {self.gap_min} s exceeds gap_max {self.gap_max} s"
            )

    def to_meta(self) -> dict[str, Any]:
        """JSON-able parameters."""
        return dataclasses.asdict(self)

    def stamps(self, t: FloatArray, rng: np.random.Generator) -> FloatArray:
        """Recorded time stamps of frames sampled at ``t`` (n,), seconds, strictly increasing.

        Each stamp is off by a normal error of ``time_jitter`` frame periods
        (none when it is 0); the stamps keep their order.
        """
        if self.time_jitter <= 0 or t.size < 2:
            return t
        period = 1.0 / self.rate
        st = t + rng.normal(0.0, self.time_jitter * period / 2.0, t.size)
        st = np.clip(st, t - 0.45 * period, t + 0.45 * period)
        return st

    def dropouts(self, n: int, rng: np.random.Generator) -> BoolArray:
        """Frames a hub delivers, shape (n,): runs of 1–``dropout_max`` lost frames."""
        keep = np.ones(n, dtype=bool)
        if self.dropout_rate <= 0 or n == 0:
            return keep
        k = int(rng.poisson(self.dropout_rate * n / self.rate))
        starts = rng.integers(0, n, k)
        lengths = rng.integers(1, self.dropout_max + 1, k)
        marks = np.zeros(n + 1, dtype=np.int64)
        np.add.at(marks, starts, 1)
        np.add.at(marks, np.minimum(starts + lengths, n), -1)
        return np.cumsum(marks[:n]) == 0

    def observe(
        self,
        t: FloatArray,
        pos: FloatArray,
        quat: FloatArray,
        kind: str,
        rng: np.random.Generator,
        *,
        delivered: BoolArray | None = None,
    ) -> tuple[FloatArray, FloatArray, BoolArray]:
        """One body seen through the sensor.

        Parameters
        ----------
        t : ndarray, shape (n,), seconds
        pos : ndarray, shape (n, 3), metres, world frame (true)
        quat : ndarray, shape (n, 4), x y z w (true)
        kind : str
            The body's kind; fingers are occluded more often.
        rng : numpy.random.Generator
        delivered : ndarray of bool, shape (n,), optional
            Frames the body's hub delivered (:meth:`dropouts`); all by default.

        Returns
        -------
        pos : ndarray, shape (n, 3), NaN in gaps
        quat : ndarray, shape (n, 4), NaN in gaps
        valid : ndarray of bool, shape (n,)
        """
        n = t.size
        p = pos + rng.normal(0.0, self.pos_noise, (n, 3)) if self.pos_noise > 0 else pos.copy()
        q = quat
        if self.rot_noise > 0:
            q = se3.quat_multiply(quat, quat_exp(rng.normal(0.0, self.rot_noise, (n, 3))))
        if self.sign_flips:
            q = q * np.where(rng.random(n) < 0.5, -1.0, 1.0)[:, None]
        rate = self.finger_gap_rate if kind == "finger" else self.body_gap_rate
        valid = self.gaps(t, rate, rng)
        if delivered is not None:
            valid &= delivered
        p = np.where(valid[:, None], p, np.nan)
        q = np.where(valid[:, None], q, np.nan)
        return p, q, valid

    def gaps(self, t: FloatArray, rate: float, rng: np.random.Generator) -> BoolArray:
        """Tracking mask (n,) with Poisson-distributed gaps of log-uniform length."""
        n = t.size
        duration = float(t[-1] - t[0]) if n else 0.0
        k = int(rng.poisson(rate * duration)) if rate > 0 else 0
        starts = rng.uniform(t[0], t[0] + duration, k) if k else np.zeros(0)
        lengths = np.exp(rng.uniform(np.log(self.gap_min), np.log(self.gap_max), k))
        i0 = np.searchsorted(t, starts)
        i1 = np.searchsorted(t, starts + lengths)
        marks = np.zeros(n + 1, dtype=np.int64)
        np.add.at(marks, i0, 1)
        np.add.at(marks, i1, -1)
        return np.cumsum(marks[:n]) == 0
