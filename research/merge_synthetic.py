"""Synthetic pairs of recordings of one session with a known clock mapping and world transform.

Used by the tests and ``research/scripts/merge_figures.py``: the motion is analytic
(sums of sines, not periodic over the recording), so each system samples it
exactly at its own clock's instants.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.demonstration import BodyInfo, Demonstration


@dataclass(frozen=True)
class PairTruth:
    """What :func:`make_pair` built: ``t_ref = (1 + drift) t + offset``, ``x_ref = R x + p``."""

    offset_s: float
    drift: float
    translation: FloatArray
    rotation: FloatArray


def motion(t: FloatArray, k: int) -> tuple[FloatArray, FloatArray]:
    """Pose of synthetic body ``k`` at times ``t`` (s): positions (m), quaternions x y z w."""
    from scipy.spatial.transform import Rotation

    ph = 1.7 * k
    f = np.array([0.31, 0.53, 0.71, 1.13, 1.57, 2.3]) * (1.0 + 0.1 * k)
    p = np.stack(
        [
            0.3 * np.sin(f[0] * t + ph) + 0.08 * np.sin(f[3] * t + 2 * ph),
            0.2 * np.cos(f[1] * t + ph) + 0.05 * np.sin(f[4] * t),
            0.8 + 0.1 * np.sin(f[2] * t + ph) + 0.03 * np.cos(f[5] * t + ph),
        ],
        axis=1,
    )
    rv = np.stack(
        [
            0.6 * np.sin(f[0] * 1.3 * t + ph),
            0.4 * np.cos(f[2] * 0.9 * t + 2 * ph),
            0.8 * np.sin(f[1] * 1.1 * t + ph) + 0.2 * np.sin(f[5] * t),
        ],
        axis=1,
    )
    return p, Rotation.from_rotvec(rv).as_quat()


def make_pair(
    *,
    offset: float = 3.2571,
    drift: float = 150e-6,
    rotation: FloatArray | None = None,
    translation: FloatArray | None = None,
    duration: float = 60.0,
    rates: tuple[float, float] = (120.0, 100.0),
    noise_m: float = 0.0,
    outliers: float = 0.0,
    gaps: bool = False,
    seed: int = 0,
) -> tuple[Demonstration, Demonstration, PairTruth]:
    """A reference recording (bodies ``a, b, hand``) and another (``a, b, camera``).

    The other system's clock starts ``offset`` seconds after the reference's
    and runs ``drift`` fast; its world frame is the reference's moved by
    ``(R, p)``. ``noise_m`` adds Gaussian position noise (per axis, metres) to
    both; ``outliers`` replaces that fraction of the other's samples of ``a`` by
    a pose 5–20 cm off; ``gaps`` drops 0.5 s stretches from both.
    """
    rng = np.random.default_rng(seed)
    q_r = se3.random_quat(rng) if rotation is None else np.asarray(rotation, float)
    p_r = np.array([0.5, -1.2, 0.3]) if translation is None else np.asarray(translation, float)
    ta = np.arange(0.0, duration, 1.0 / rates[0])
    tb = np.arange(0.0, duration - offset - 2.0, 1.0 / rates[1])
    t_true = (1.0 + drift) * tb + offset
    pi, qi = se3.pose_invert(p_r, q_r)

    def build(t: FloatArray, names: list[str], other: bool) -> Demonstration:
        pos, quat, valid = {}, {}, {}
        for n in names:
            k = {"a": 0, "b": 1, "hand": 2, "camera": 3}[n]
            p, q = motion(t, k)
            if other:
                p, q = se3.pose_compose(pi, qi, p, q)
            p = p + rng.normal(scale=noise_m, size=p.shape) if noise_m else p
            v = np.ones(t.size, bool)
            if gaps:
                for start in rng.uniform(0, t[-1], size=4):
                    v &= ~((t >= start) & (t < start + 0.5))
            if other and outliers and n == "a":
                bad = rng.random(t.size) < outliers
                jump = rng.normal(size=(t.size, 3))
                jump *= rng.uniform(0.05, 0.2, size=(t.size, 1)) / np.linalg.norm(
                    jump, axis=1, keepdims=True
                )
                p = np.where(bad[:, None], p + jump, p)
            pos[n], quat[n], valid[n] = p, q, v
        return Demonstration(t, [BodyInfo(n) for n in names], pos, quat, valid)

    ref = build(ta, ["a", "b", "hand"], other=False)
    oth = build(t_true, ["a", "b", "camera"], other=True)
    oth = oth.replace(t=tb)
    return ref, oth, PairTruth(offset, drift, p_r, q_r)
