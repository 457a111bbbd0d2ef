"""A motion-capture sensor model: sampling rate, noise, occlusion gaps, quaternion signs."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from thirdhand import se3
from thirdhand.errors import ThirdhandError
from thirdhand.synth.motion import quat_exp

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


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

    def __post_init__(self) -> None:
        for name in ("rate", "gap_min", "gap_max"):
            if not getattr(self, name) > 0:
                raise ThirdhandError(f"SensorModel.{name} must be > 0, got {getattr(self, name)}")
        for name in ("pos_noise", "rot_noise", "finger_gap_rate", "body_gap_rate"):
            if not getattr(self, name) >= 0:
                raise ThirdhandError(f"SensorModel.{name} must be >= 0, got {getattr(self, name)}")
        if self.gap_min > self.gap_max:
            raise ThirdhandError(
                f"SensorModel.gap_min {self.gap_min} s exceeds gap_max {self.gap_max} s"
            )

    def to_meta(self) -> dict[str, Any]:
        """JSON-able parameters."""
        return dataclasses.asdict(self)

    def observe(
        self, t: FloatArray, pos: FloatArray, quat: FloatArray, kind: str, rng: np.random.Generator
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
