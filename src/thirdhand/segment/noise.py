"""The recording's own noise floor, and rest decided from it.

A tracker's noise ranges from ~10 µm (a Polhemus G4 at rest) to ~1 mm (an
optical system) and 1–3 cm (AR tags); a model cannot be told which. Each
body's floor is estimated from its own track: the second difference of a
sampled signal, ``Δ²x_k = x_{k+1} − 2 x_k + x_{k−1}``, removes any smooth
motion to first order and multiplies white noise of variance ``σ²`` per axis
by 6, so over a recording that is mostly slow, the median of ``|Δ²x|²`` over
consecutive valid triples is ``6 σ² m_3``, ``m_3 ≈ 2.366`` the median of a
χ² with three degrees of freedom. The floor reported is the trace of the noise
covariance, ``τ = 3 σ²``, the value the windowed variance ``ν`` of a still
body takes (:mod:`thirdhand.segment.features`).

Rest: a window whose variances are within ``factor`` times the floor (the
estimate of a variance from a 0.25 s window of ≥ 10 samples stays below 3 × its
expectation with probability > 0.999 for three or more degrees of freedom)
shows no motion beyond the sensor's. The report's label is "the hand is
actively manipulating the object": the object moves with the hand. An object
at rest is therefore not being manipulated, whatever the hand does; the
pipeline labels such steps 0 for hand/finger–object pairs
(:func:`~thirdhand.segment.pipeline.segment_demonstration`), never an
extrapolated guess of the model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from thirdhand.arrays import BoolArray, FloatArray

#: Median of a χ² variable with 3 degrees of freedom.
CHI2_3_MEDIAN = 2.365973884375338
#: A window is at rest when each variance is at most this many times its floor.
REST_FACTOR = 3.0
#: Lower bound of a floor (m² or quaternion units²): a noise-free track.
FLOOR_MIN = 1e-14


@dataclass(frozen=True)
class NoiseFloor:
    """Noise floor of one body's track.

    Attributes
    ----------
    pos : float
        Trace of the position noise covariance, m² (``3 σ²``, ``σ`` per axis).
    rot : float
        Same for the sign-continuous quaternion components (unitless).
    n : int
        Consecutive valid triples the estimate is based on.
    """

    pos: float
    rot: float
    n: int

    @property
    def pos_sigma_m(self) -> float:
        """Position noise per axis, metres."""
        return float(np.sqrt(self.pos / 3.0))


def _second_difference_floor(x: FloatArray, valid: BoolArray) -> tuple[float, int]:
    ok = valid[2:] & valid[1:-1] & valid[:-2]
    if not ok.any():
        return float("nan"), 0
    d2 = x[2:] - 2.0 * x[1:-1] + x[:-2]
    sq = np.einsum("ij,ij->i", d2[ok], d2[ok])
    sigma2 = float(np.median(sq)) / (6.0 * CHI2_3_MEDIAN)
    return max(3.0 * sigma2, FLOOR_MIN), int(ok.sum())


def noise_floor(pos: FloatArray, quat: FloatArray, valid: BoolArray) -> NoiseFloor:
    """Noise floor of one track from its second differences.

    Parameters
    ----------
    pos : ndarray, shape (n_frames, 3), metres, world frame
    quat : ndarray, shape (n_frames, 4), x y z w
    valid : ndarray of bool, shape (n_frames,)

    Returns
    -------
    NoiseFloor
        NaN floors (``n == 0``) when the track never has three valid frames in a row.
    """
    from thirdhand.se3_compiled import continuous_quat_rows

    v = np.asarray(valid, dtype=np.bool_)
    p = np.where(v[:, None], np.asarray(pos, np.float64), 0.0)
    q = continuous_quat_rows(np.where(v[:, None], quat, 0.0).astype(np.float64), v)
    fp, n = _second_difference_floor(p, v)
    fr, _ = _second_difference_floor(q, v)
    return NoiseFloor(pos=fp, rot=fr, n=n)


def at_rest(
    var_pos: FloatArray, var_rot: FloatArray, floor: NoiseFloor, factor: float = REST_FACTOR
) -> BoolArray:
    """Steps whose windowed variances are all within ``factor`` × the floor.

    Parameters
    ----------
    var_pos : ndarray, shape (n_steps,), m²
    var_rot : ndarray, shape (n_steps,)
    floor : NoiseFloor
    factor : float

    Returns
    -------
    ndarray of bool, shape (n_steps,)
        All False when the floor is unknown.
    """
    if floor.n == 0 or not np.isfinite(floor.pos):
        return np.zeros(len(var_pos), dtype=bool)
    return (np.asarray(var_pos) <= factor * floor.pos) & (np.asarray(var_rot) <= factor * floor.rot)


__all__ = ["REST_FACTOR", "NoiseFloor", "at_rest", "noise_floor"]
