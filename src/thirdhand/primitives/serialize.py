"""Primitives to and from plain JSON-able dicts (parameters, never pickles).

Every dict carries a ``"kind"`` and the parameters needed to rebuild the
object exactly (the rollout of a rebuilt DMP equals the original's bit for bit).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from thirdhand.primitives.checks import PrimitiveError
from thirdhand.primitives.dmp import DMP
from thirdhand.primitives.promp import ProMP
from thirdhand.primitives.quaternion_dmp import PoseDMP, QuaternionDMP

if TYPE_CHECKING:
    from thirdhand.task.stages import PrimitiveRecord

#: How rollouts interpret time, stored beside every DMP.
TIME_CONVENTION = (
    "s in seconds from the first sample; phase x = exp(-alpha_x s / tau); "
    "tau^2 ydd = K (g - y) - D tau yd - K (g - y0) x + f(x), D = alpha, K = alpha^2 / 4"
)


def _floats(a: np.ndarray) -> list[Any]:
    out: list[Any] = np.asarray(a, dtype=np.float64).tolist()
    return out


def dmp_to_dict(d: DMP | QuaternionDMP) -> dict[str, Any]:
    """Parameters of a fitted position or quaternion DMP."""
    return {
        "kind": "quaternion_dmp" if isinstance(d, QuaternionDMP) else "dmp",
        "n_weights": d.n_weights,
        "alpha": d.alpha,
        "alpha_x": d.alpha_x_,
        "tau": d.tau_,
        "dt": d.dt_,
        "start": _floats(d.start_),
        "goal": _floats(d.goal_),
        "start_velocity": _floats(d.start_velocity_),
        "weights": _floats(d.weights_),
    }


def dmp_from_dict(data: dict[str, Any]) -> DMP | QuaternionDMP:
    """Rebuild a DMP from :func:`dmp_to_dict` output.

    Raises
    ------
    PrimitiveError
        Naming the missing or malformed field.
    """
    kind = data.get("kind")
    cls: type[DMP] | type[QuaternionDMP]
    if kind == "dmp":
        cls = DMP
    elif kind == "quaternion_dmp":
        cls = QuaternionDMP
    else:
        raise PrimitiveError(
            f"DMP parameters: kind must be 'dmp' or 'quaternion_dmp', got {kind!r}"
        )
    try:
        d = cls(int(data["n_weights"]), alpha=float(data["alpha"]), alpha_x=float(data["alpha_x"]))
        w = np.asarray(data["weights"], dtype=np.float64)
        d.weights_ = w
        d.tau_, d.dt_ = float(data["tau"]), float(data["dt"])
        d.start_ = np.asarray(data["start"], dtype=np.float64)
        d.goal_ = np.asarray(data["goal"], dtype=np.float64)
        d.start_velocity_ = np.asarray(data["start_velocity"], dtype=np.float64)
    except KeyError as exc:
        raise PrimitiveError(f"DMP parameters: missing field {exc.args[0]!r}") from None
    except (TypeError, ValueError) as exc:
        raise PrimitiveError(f"DMP parameters: malformed value ({exc})") from None
    if w.ndim != 2 or w.shape[0] != d.n_weights:
        raise PrimitiveError(
            f"DMP parameters: weights must be ({d.n_weights}, dims), got {w.shape}"
        )
    problem = _dmp_problem(d)
    if problem is not None:
        raise PrimitiveError(f"DMP parameters: {problem}")
    return d


#: Most basis functions a DMP is read with (they size every rollout's arrays).
MAX_WEIGHTS = 10_000
#: Longest primitive read, seconds.
MAX_DURATION_S = 3600.0


def _dmp_problem(d: DMP | QuaternionDMP) -> str | None:
    """How a DMP's parameters are not a model (None if they are)."""
    if not 1 <= d.n_weights <= MAX_WEIGHTS:
        return f"n_weights: expected 1 to {MAX_WEIGHTS}, got {d.n_weights}"
    for name in ("alpha", "alpha_x_", "tau_", "dt_"):
        v = float(getattr(d, name))
        if not (math.isfinite(v) and v > 0):
            return f"{name.rstrip('_')}: expected a positive number, got {v}"
    if d.tau_ > MAX_DURATION_S or d.dt_ > d.tau_:
        return f"tau {d.tau_:g} s and dt {d.dt_:g} s: expected dt <= tau <= {MAX_DURATION_S:g} s"
    for name in ("weights_", "start_", "goal_", "start_velocity_"):
        if not np.isfinite(getattr(d, name)).all():
            return f"{name.rstrip('_')}: non-finite values"
    return None


def pose_dmp_to_dict(p: PoseDMP) -> dict[str, Any]:
    """Parameters of a fitted :class:`PoseDMP`."""
    return {
        "kind": "pose_dmp",
        "orientation": p.orientation,
        "time_convention": TIME_CONVENTION,
        "position": dmp_to_dict(p.position_),
        "rotation": dmp_to_dict(p.orientation_),
    }


def pose_dmp_from_dict(data: dict[str, Any]) -> PoseDMP:
    """Rebuild a :class:`PoseDMP`."""
    if data.get("kind") != "pose_dmp":
        raise PrimitiveError(
            f"pose DMP parameters: kind must be 'pose_dmp', got {data.get('kind')!r}"
        )
    try:
        pos, rot = dmp_from_dict(data["position"]), dmp_from_dict(data["rotation"])
        orientation = data["orientation"]
    except KeyError as exc:
        raise PrimitiveError(f"pose DMP parameters: missing field {exc.args[0]!r}") from None
    if not isinstance(pos, DMP) or isinstance(pos, QuaternionDMP):
        raise PrimitiveError("pose DMP parameters: 'position' must be a 'dmp'")
    p = PoseDMP(pos.n_weights, orientation=orientation, alpha=pos.alpha)
    p.position_, p.orientation_ = pos, rot
    return p


def promp_to_dict(p: ProMP) -> dict[str, Any]:
    """Parameters of a ProMP; the covariance as its packed lower Cholesky factor."""
    chol = np.linalg.cholesky(p.cov_)
    return {
        "kind": "promp",
        "n_weights": p.n_weights,
        "dims": p.dims_,
        "duration": p.duration_,
        "noise": p.noise_,
        "mean": _floats(p.mean_),
        "cov_cholesky_lower": _floats(chol[np.tril_indices_from(chol)]),
    }


def promp_from_dict(data: dict[str, Any]) -> ProMP:
    """Rebuild a ProMP from :func:`promp_to_dict` output."""
    if data.get("kind") != "promp":
        raise PrimitiveError(f"ProMP parameters: kind must be 'promp', got {data.get('kind')!r}")
    try:
        mean = np.asarray(data["mean"], dtype=np.float64)
        packed = np.asarray(data["cov_cholesky_lower"], dtype=np.float64)
        dims = int(data["dims"])
        noise, duration = float(data["noise"]), float(data["duration"])
    except KeyError as exc:
        raise PrimitiveError(f"ProMP parameters: missing field {exc.args[0]!r}") from None
    except (TypeError, ValueError) as exc:
        raise PrimitiveError(f"ProMP parameters: malformed value ({exc})") from None
    if not (np.isfinite(mean).all() and np.isfinite(packed).all()):
        raise PrimitiveError("ProMP parameters: non-finite mean or covariance")
    if not (math.isfinite(noise) and noise >= 0):
        raise PrimitiveError(f"ProMP parameters: noise must be a variance >= 0, got {noise}")
    if not (math.isfinite(duration) and 0 < duration <= MAX_DURATION_S):
        raise PrimitiveError(
            f"ProMP parameters: duration must be in (0, {MAX_DURATION_S:g}] s, got {duration}"
        )
    f = mean.size
    if packed.size != f * (f + 1) // 2:
        raise PrimitiveError(
            f"ProMP parameters: cov_cholesky_lower must hold {f * (f + 1) // 2} numbers, "
            f"got {packed.size}"
        )
    chol = np.zeros((f, f))
    chol[np.tril_indices(f)] = packed
    return ProMP.from_params(mean, chol @ chol.T, dims=dims, noise=noise, duration=duration)


def pose_dmp_from_record(record: PrimitiveRecord) -> PoseDMP:
    """The fitted :class:`PoseDMP` a task file's primitive record saved (rebuilt exactly)."""
    return pose_dmp_from_dict(record.dmp.model_dump(mode="json"))


def promp_from_record(record: PrimitiveRecord) -> ProMP:
    """The fitted :class:`ProMP` a task file's primitive record saved."""
    return promp_from_dict(record.promp.model_dump(mode="json"))
