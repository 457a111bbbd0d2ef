"""What makes a skill library's parameters a model, checked wherever a library is read.

A skill library (``thirdhand.skill-library/1``, alone or in a task's
``stages.primitives``) is a hidden semi-Markov model: per skill a Gaussian over
the channels, a log-normal duration in samples, and log-probabilities of
starting, moving on and ending. :func:`skill_model_problem` is the check of its
content, a pure function returning the first problem as one line: covariances
symmetric positive definite, duration standard deviations positive, every
log-probability at most 0, every transition row and the start distribution
summing to 1 in probability, channels unique, and the rate and durations within
bounds, since they size the parser's work (a 2 MHz rate or a duration of a
billion samples must not reach an allocation).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

#: Highest rate a library parses tracks at, Hz (motion capture runs at 100-360 Hz).
MAX_RATE_HZ = 1000.0
#: Longest skill a library may hold, seconds: ``max_duration`` / ``rate_hz`` (an hour).
MAX_SKILL_S = 3600.0
#: Longest skill in samples whatever the rate (the parser's arrays grow with it).
MAX_SKILL_SAMPLES = 100_000
#: Widest smoothing window, samples.
MAX_WINDOW = 10_000
#: How far a probability sum may be from 1 (the file stores 17 significant digits).
PROB_TOL = 1e-6


def _array(value: Any) -> Any:
    """A float array; null (None) is -inf, an impossible move."""
    if isinstance(value, np.ndarray):
        return value.astype(np.float64)
    if isinstance(value, list):
        return np.array([_array(v) for v in value], dtype=np.float64)
    return -np.inf if value is None else float(value)


def skill_model_problem(
    *,
    channels: Sequence[str],
    rate_hz: float,
    window: int,
    means: Any,
    covs: Any,
    duration_log_mean: Any,
    duration_log_sd: Any,
    max_duration: int,
    log_trans: Any,
    log_init: Any,
    log_final: Any,
) -> str | None:
    """The first way the parameters are not a skill model, as one line, or None.

    Parameters
    ----------
    channels : sequence of str
        Unique channel names, C of them.
    rate_hz : float
        Parse rate, Hz: in (0, :data:`MAX_RATE_HZ`].
    window : int
        Smoothing, samples: 1 to :data:`MAX_WINDOW`.
    means : array-like, shape (K, C)
    covs : array-like, shape (K, C, C)
        Symmetric positive definite.
    duration_log_mean, duration_log_sd : array-like, shape (K,)
        Log-normal durations in samples: finite means of at most
        :data:`MAX_SKILL_S` seconds; positive finite standard deviations.
    max_duration : int
        Longest skill, samples: at least 1, at most :data:`MAX_SKILL_S` seconds
        and :data:`MAX_SKILL_SAMPLES`.
    log_trans : array-like, shape (K, K)
        Each row's probabilities sum to 1, or the row is all impossible (an exit).
    log_init : array-like, shape (K,)
        Probabilities summing to 1.
    log_final : array-like, shape (K,)
        Log-probabilities (each at most 0).
    """
    dup = sorted({c for c in channels if list(channels).count(c) > 1})
    if dup:
        return f"channels: {dup[0]!r} is listed twice"
    if not (math.isfinite(rate_hz) and 0 < rate_hz <= MAX_RATE_HZ):
        return f"rate_hz: expected a rate in (0, {MAX_RATE_HZ:g}] Hz, got {rate_hz:g}"
    if not 1 <= window <= MAX_WINDOW:
        return f"window: expected 1 to {MAX_WINDOW} samples, got {window}"
    longest = min(MAX_SKILL_S * rate_hz, MAX_SKILL_SAMPLES)
    if not 1 <= max_duration <= longest:
        return (
            f"skills.max_duration: expected 1 to {longest:.0f} samples (at most "
            f"{MAX_SKILL_S:g} s at {rate_hz:g} Hz), got {max_duration}"
        )
    try:
        mu, cov = _array(means), _array(covs)
        dmu, dsd = _array(duration_log_mean), _array(duration_log_sd)
        trans, init, final = _array(log_trans), _array(log_init), _array(log_final)
    except (TypeError, ValueError):
        return "skills: expected arrays of numbers"
    for name, a in (("means", mu), ("covs", cov), ("duration_log_mean", dmu)):
        if not np.isfinite(a).all():
            return f"skills.{name}: non-finite value {a[~np.isfinite(a)][0]}"
    bad = ~(np.isfinite(dsd) & (dsd > 0))
    if bad.any():
        k = int(np.argmax(bad))
        return f"skills.duration_log_sd[{k}] is {dsd[k]}; a standard deviation is positive"
    over = dmu > math.log(longest)
    if over.any():
        k = int(np.argmax(over))
        return (
            f"skills.duration_log_mean[{k}] is {dmu[k]:.6g}: skills of "
            f"{math.exp(min(dmu[k], 700.0)):.3g} samples, beyond {MAX_SKILL_S:g} s "
            f"at {rate_hz:g} Hz"
        )
    if cov.ndim == 3:
        for k in range(cov.shape[0]):
            if not np.allclose(cov[k], cov[k].T, rtol=1e-9, atol=1e-12):
                return f"skills.covs[{k}] is not symmetric"
            try:
                np.linalg.cholesky(cov[k])
            except np.linalg.LinAlgError:
                return f"skills.covs[{k}] is not positive definite"
    for name, a in (("log_trans", trans), ("log_init", init), ("log_final", final)):
        if np.isnan(a).any():
            return f"skills.{name}: NaN is no log-probability (null is an impossible move)"
        pos = a > 1e-12
        if pos.any():
            where = ", ".join(str(int(v)) for v in np.argwhere(pos)[0])
            return f"skills.{name}[{where}] is {a[pos][0]:.6g} > 0; a log-probability is at most 0"
    with np.errstate(under="ignore"):
        rows = np.exp(trans).sum(axis=-1) if trans.ndim == 2 else np.zeros(0)
        start = float(np.exp(init).sum()) if init.ndim == 1 else 1.0
    for k, total in enumerate(rows):
        if total != 0.0 and abs(total - 1.0) > PROB_TOL:
            return f"skills.log_trans[{k}]: its probabilities sum to {total:.6g}, not 1"
    if abs(start - 1.0) > PROB_TOL:
        return f"skills.log_init: its probabilities sum to {start:.6g}, not 1"
    return None
