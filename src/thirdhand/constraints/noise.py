"""Sensor noise of a relative-pose track, estimated from the track itself.

Every sample is compared with a quadratic fitted (least squares) to its
``window`` neighbours in time, centre included; the residual at the centre,
divided by ``sqrt(1 - h)`` (``h`` the centre's leverage), has the variance of the
noise whatever the smooth motion underneath. Per coordinate, the noise level is
the median of the squared residuals divided by the median of a chi-square with
one degree of freedom (robust: up to half the windows may hold an outlier or a
jump); the position level is the root mean square over x, y, z, and the
rotation level that of the rotation vectors taken relative to each window's
centre sample (so that a turn through π does not wrap).

Such a short-window estimate sees the high-frequency (white) part of a
tracker's error. Real trackers add a slowly varying part that no local smoother
can tell from motion (a camera's lens distortion bends a drawer's stroke by 1–2 %
of its length); :meth:`NoiseEstimate.noise_model` turns the estimate into the
bounds the model fits use.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit
from numpy.typing import NDArray

from thirdhand import se3_compiled as sc
from thirdhand.arrays import FloatArray
from thirdhand.constraints.types import ConstraintFitError, NoiseModel

#: Median of a chi-square with one degree of freedom.
_CHI2_1_MEDIAN = 0.454936
#: Samples per local fit (the shortest tracks use 5).
DEFAULT_WINDOW = 7
#: Noise floor of the model fits, in units of the white-noise estimate. Real
#: trackers' error is coloured: on the real tracks of ``../shared/data`` 15- and
#: 21-sample estimates read 1.2-2.8 times the 7-sample one (white noise: 1), as
#: white noise plus a part correlated over 2 samples at 2-3 times its level does,
#: whose per-sample error is 2.2-3.1 times the estimate. Chosen on the synthetic
#: sweep (``research/notes/constraints.md``): 1.5 and 2 tie on the broad mix of conditions
#: (96.6 %), 2 is the better of them on noise coloured like the real tracks'
#: (91.3 % against 88.1 %).
FLOOR_FACTOR = 2.0
#: The same for rotations: the real tracks need no allowance for slowly varying
#: rotation error (the stapler's revolute wins at 1, 1.5 and 2), and each unit
#: above 1 hides a turn's structure from the cylindrical-revolute comparison.
ROT_FLOOR_FACTOR = 1.0
#: Smallest floors, metres and radians: a noise-free track must not make a
#: likelihood infinite.
MIN_POS_FLOOR = 1e-6
MIN_ROT_FLOOR = 1e-6
#: Largest estimates, metres and radians: no tracker of the seed's users is noisier
#: than 2 cm and 10°; a larger estimate is motion too fast for the window (a free
#: part waved about, sampled 20 times), not noise.
MAX_POS_NOISE = 0.02
MAX_ROT_NOISE = math.radians(10.0)
#: Ceilings of the constrained models (the largest error they may put down to the
#: tracker: beyond it a sample is an outlier, or the motion is ``free``), in units
#: of the floor, when above :data:`MIN_POS_CEILING` and the rotation default of
#: :class:`NoiseModel` (6°).
CEILING_FACTOR = 2.0
#: Smallest position ceiling, metres: room for the systematic error of a tracker
#: whose white noise is tiny (a robot's kinematic calibration, a mocap volume's).
#: Chosen on the synthetic sweep's calibration seeds (``research/notes/constraints.md``):
#: 5, 7.5, 10 and 15 mm give the same accuracy (93.0-93.1 %), 10 mm by one track;
#: the old 2.5 cm (92.0 %) lets a prismatic or revolute fit absorb a free part's
#: wander as 2-4 cm of "noise" (free, position-only: 79 % against 88 %).
MIN_POS_CEILING = 0.01


@dataclass(frozen=True)
class NoiseEstimate:
    """White-noise levels of a track, estimated from its short-window residuals.

    Attributes
    ----------
    sigma_pos : float
        Per-axis position noise, metres.
    sigma_rot : float
        Per-axis rotation noise, radians; NaN for a position-only track.
    window : int
        Samples per local fit.
    n_windows : int
        Number of local fits the medians were taken over.
    gross : ndarray of bool, shape (n,), optional
        Samples flagged as gross outliers: jumps away from their neighbours in time
        (:func:`_flag_outliers`, positions and orientations).
    pos_clipped : bool
        Whether the position level was clipped to :data:`MAX_POS_NOISE`: the
        residuals are beyond any tracker's noise, motion too fast for the window,
        and ``sigma_pos`` is the cap, not a measurement.
    """

    sigma_pos: float
    sigma_rot: float
    window: int
    n_windows: int
    gross: NDArray[np.bool_] | None = field(default=None, compare=False, repr=False)
    pos_clipped: bool = False

    def noise_model(self, *, max_outliers: float = 0.25) -> NoiseModel:
        """The bounds of the model fits: floors at :data:`FLOOR_FACTOR` times the estimate.

        Ceilings (the largest error a constrained model may have) are
        :data:`CEILING_FACTOR` times the floor, at least :data:`MIN_POS_CEILING`
        (1 cm) and the rotation default of :class:`NoiseModel` (6°).
        """
        base = NoiseModel()
        fp = max(FLOOR_FACTOR * self.sigma_pos, MIN_POS_FLOOR)
        sr = self.sigma_rot if math.isfinite(self.sigma_rot) else base.rot_floor / ROT_FLOOR_FACTOR
        fr = max(ROT_FLOOR_FACTOR * sr, MIN_ROT_FLOOR)
        return NoiseModel(
            pos_floor=fp,
            pos_ceiling=max(MIN_POS_CEILING, CEILING_FACTOR * fp),
            rot_floor=fr,
            rot_ceiling=max(base.rot_ceiling, CEILING_FACTOR * fr),
            max_outliers=max_outliers,
        )

    def at_least(self, bounds: NoiseModel, *, max_outliers: float = 0.25) -> NoiseModel:
        """:meth:`noise_model`, with floors and ceilings no lower than ``bounds``'."""
        nm = self.noise_model(max_outliers=max_outliers)
        return NoiseModel(
            pos_floor=max(nm.pos_floor, bounds.pos_floor),
            pos_ceiling=max(nm.pos_ceiling, bounds.pos_ceiling),
            rot_floor=max(nm.rot_floor, bounds.rot_floor),
            rot_ceiling=max(nm.rot_ceiling, bounds.rot_ceiling),
            max_outliers=max_outliers,
        )

    def to_dict(self) -> dict[str, float | int | None]:
        """JSON-able form (NaN as None)."""
        return {
            "sigma_pos": self.sigma_pos,
            "sigma_rot": self.sigma_rot if math.isfinite(self.sigma_rot) else None,
            "window": self.window,
            "n_windows": self.n_windows,
        }


@functools.lru_cache(maxsize=8)
def _filter(window: int) -> FloatArray:
    """Weights giving the normalised centre residual of a local quadratic, shape (window,)."""
    h = window // 2
    t = np.arange(-h, h + 1, dtype=np.float64)
    v = np.vander(t, 3)
    hat = v @ np.linalg.pinv(v)
    out = np.asarray((np.eye(window) - hat)[h] / math.sqrt(1.0 - hat[h, h]), dtype=np.float64)
    out.setflags(write=False)
    return out


def _robust_level(res: FloatArray, keep: NDArray[np.bool_] | None = None) -> float:
    """Root mean square over coordinates of the robust per-coordinate scale of ``res (m, k)``.

    From the median of the squared residuals of the ``keep`` rows (all when None,
    or when fewer than 3 are kept).
    """
    rows = np.ones(res.shape[0], dtype=bool) if keep is None or keep.sum() < 3 else keep
    return _robust_level_kernel(np.ascontiguousarray(res), rows)


@njit(cache=True, error_model="numpy")
def _robust_level_kernel(res: FloatArray, keep: NDArray[np.bool_]) -> float:  # pragma: no cover
    """:func:`_robust_level` of ``res (m, k)`` over the rows where ``keep`` holds."""
    idx = np.flatnonzero(keep)
    k = res.shape[1]
    col = np.empty(idx.size)
    total = 0.0
    for a in range(k):
        for r in range(idx.size):
            col[r] = res[idx[r], a] ** 2
        total += np.median(col) / _CHI2_1_MEDIAN
    return math.sqrt(total / k)


def _pos_residuals(pos: FloatArray, w: int) -> FloatArray:
    """Normalised centre residuals of local quadratics of positions, shape (n - w + 1, 3)."""
    return _pos_residuals_kernel(np.ascontiguousarray(pos), _filter(w))


@njit(cache=True, error_model="numpy")
def _pos_residuals_kernel(p: FloatArray, f: FloatArray) -> FloatArray:  # pragma: no cover
    """:func:`_pos_residuals` for positions ``p (n, 3)`` and filter ``f (w,)``."""
    w = f.shape[0]
    m = p.shape[0] - w + 1
    out = np.zeros((m, 3))
    for i in range(m):
        for j in range(w):
            for a in range(3):
                out[i, a] += f[j] * p[i + j, a]
    return out


def _rot_residuals(quat: FloatArray, w: int) -> FloatArray:
    """Same for rotations, as rotation vectors relative to each window's centre, radians."""
    return _rot_residual_pair(quat, w, w)[1]


def _rot_residual_pair(quat: FloatArray, short: int, w: int) -> tuple[FloatArray, FloatArray]:
    """:func:`_rot_residuals` for windows ``short`` and ``w >= short`` in one pass.

    The rotation vectors relative to a centre sample serve both windows around
    it, so each sample pair's logarithm is taken once.
    """
    return _rot_pair_kernel(np.ascontiguousarray(quat), _filter(short), _filter(w))


@njit(cache=True, error_model="numpy")
def _rot_pair_kernel(
    q: FloatArray, fs: FloatArray, fl: FloatArray
) -> tuple[FloatArray, FloatArray]:  # pragma: no cover
    """Centre residuals of unit quaternions ``q (n, 4)`` for filters ``fs`` and ``fl``."""
    n = q.shape[0]
    hs = fs.shape[0] // 2
    hl = fl.shape[0] // 2
    out_s = np.zeros((n - 2 * hs, 3))
    out_l = np.zeros((n - 2 * hl, 3))
    for c in range(hs, n - hs):
        long_c = hl <= c < n - hl
        h = hl if long_c else hs
        cx, cy, cz, cw = -q[c, 0], -q[c, 1], -q[c, 2], q[c, 3]
        for d in range(-h, h + 1):
            k = c + d
            x, y, z, s = sc.qmul(cx, cy, cz, cw, q[k, 0], q[k, 1], q[k, 2], q[k, 3])
            scale = sc.rotvec_scale(x, y, z, s)
            if -hs <= d <= hs:
                a = fs[d + hs] * scale
                out_s[c - hs, 0] += x * a
                out_s[c - hs, 1] += y * a
                out_s[c - hs, 2] += z * a
            if long_c:
                b = fl[d + hl] * scale
                out_l[c - hl, 0] += x * b
                out_l[c - hl, 1] += y * b
                out_l[c - hl, 2] += z * b
    return out_s, out_l


def _flag_outliers(res: FloatArray, w: int) -> NDArray[np.bool_]:
    """Samples that are gross outliers, shape (n,), from centre residuals ``res (n - w + 1, 3)``.

    An outlier spoils every window it falls in (with 25 % of them, three in four
    windows of 5): the lowest decile of the squared residuals gives a first scale
    and centres beyond 6 of it are flagged.
    """
    d2 = np.einsum("ij,ij->i", res, res)
    # Lowest decile of a chi-square with 3 degrees of freedom.
    s2 = float(np.partition(d2, d2.size // 10)[d2.size // 10]) / 0.5844
    m = res.shape[0]
    bad = np.zeros(m + w - 1, dtype=bool)
    bad[w // 2 : w // 2 + m] = d2 > 36.0 * 3.0 * max(s2, 1e-300)
    return bad


def _clean_windows(bad: NDArray[np.bool_], w: int) -> NDArray[np.bool_]:
    """Windows of ``w`` samples holding no flagged sample, shape (n - w + 1,)."""
    hits = np.convolve(bad.astype(np.float64), np.ones(w), mode="valid")
    return np.asarray(hits == 0.0, dtype=bool)


def estimate_noise(
    pos: FloatArray, quat: FloatArray | None = None, *, window: int = DEFAULT_WINDOW
) -> NoiseEstimate:
    """Estimate the white position and rotation noise of a prepared track.

    Estimates are clipped to :data:`MAX_POS_NOISE` and :data:`MAX_ROT_NOISE`.
    Gross outliers are flagged first, from the residuals of 5-sample fits (beyond
    6 times a scale from their lowest decile), and the windows that hold one are
    left out of the medians.

    Parameters
    ----------
    pos : ndarray, shape (n, 3)
        Valid child positions in the parent frame, metres, in time order
        (see :func:`thirdhand.constraints.prepare_track`).
    quat : ndarray, shape (n, 4), optional
        Unit child orientations, x y z w; None for position-only.
    window : int
        Samples per local quadratic fit (odd, at least 5); a track shorter than
        the window uses the largest odd window it holds.

    Returns
    -------
    NoiseEstimate

    Raises
    ------
    ConstraintFitError
        For fewer than 5 samples or a bad window.
    """
    n = pos.shape[0]
    if window < 5 or window % 2 == 0:
        raise ConstraintFitError(f"noise estimate: expected an odd window >= 5, got {window}")
    if n < 5:
        raise ConstraintFitError(f"noise estimate: expected at least 5 samples, got {n}")
    w = min(window, n if n % 2 else n - 1)
    bad = _flag_outliers(_pos_residuals(pos, 5), 5)
    res_r = None
    if quat is not None:
        res_r5, res_r = _rot_residual_pair(quat, 5, w)
        bad |= _flag_outliers(res_r5, 5)
    keep = _clean_windows(bad, w)
    if keep.sum() < 3 and w > 5:
        # Outliers too dense for windows of w (a quarter of the samples): windows of 5.
        w = 5
        keep = _clean_windows(bad, w)
        res_r = res_r5 if quat is not None else None
    if keep.sum() < 3:
        keep = np.ones(n - w + 1, dtype=bool)
    res_p = _pos_residuals(pos, w)
    sigma_rot = math.nan
    if res_r is not None:
        sigma_rot = min(_robust_level(res_r, keep), MAX_ROT_NOISE)
    level = _robust_level(res_p, keep)
    return NoiseEstimate(
        sigma_pos=min(level, MAX_POS_NOISE),
        sigma_rot=sigma_rot,
        window=w,
        n_windows=int(keep.sum()),
        gross=bad,
        pos_clipped=level >= MAX_POS_NOISE,
    )
