"""Model selection: fit every candidate model and keep the best by BIC."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from thirdhand.constraints.models import (
    MIN_SAMPLES,
    ModelFit,
    fit_model,
    prepare_track,
    to_constraint,
)
from thirdhand.constraints.types import (
    MODEL_TYPES,
    Constraint,
    ConstraintFitError,
    NoiseModel,
)
from thirdhand.demonstration import Demonstration

FloatArray = NDArray[np.float64]

#: Models compared by default. Cylindrical (and screw) need orientations and are
#: skipped silently for position-only tracks. Screw is opt-in: its pitch also
#: soaks up a few millimetres of systematic error along a revolute axis, and a
#: cylindrical joint whose slide and turn move together is, per sample, cheaper
#: to describe as a screw with a larger noise (one latent instead of two).
DEFAULT_MODELS: tuple[str, ...] = ("fixed", "prismatic", "revolute", "cylindrical", "free")


def bic_weights(scores: dict[str, float]) -> dict[str, float]:
    """Posterior model weights ``exp(-BIC/2)``, normalised; infinite scores get 0."""
    names = [k for k, v in scores.items() if math.isfinite(v)]
    if not names:
        return {k: 0.0 for k in scores}
    b = np.array([scores[k] for k in names])
    e = np.exp(-0.5 * (b - b.min()))
    w = e / e.sum()
    out = {k: 0.0 for k in scores}
    out.update({k: float(v) for k, v in zip(names, w, strict=True)})
    return out


_NEEDS_ORIENTATION = ("cylindrical", "screw")
_FIT_ORDER = ("free", "fixed", "prismatic", "revolute", "cylindrical", "screw")


def _margin(best: float) -> float:
    """How far behind the best BIC so far a model may fall before its fit stops early."""
    return 200.0 + 0.1 * abs(best) if math.isfinite(best) else math.inf


def effective_samples(fits: dict[str, ModelFit]) -> float:
    """Effective number of independent samples of a track, from its best model's residuals.

    With lag-1 autocorrelation ``ρ`` of the residuals of the model with the lowest
    plain BIC (the model whose residuals are closest to the sensor noise), an AR(1)
    error has ``n (1 - ρ) / (1 + ρ)`` effective samples. White residuals (the
    synthetic tracks) give ``n``; a real sensor's slowly varying error (a camera's
    bias that changes along a drawer's stroke) gives far fewer, and a systematic
    error of a few millimetres is no longer strong evidence for a curved joint.
    """
    best = min(fits.values(), key=lambda f: f.bic)
    n = float(best.weights.shape[0])
    rho = best.residual_autocorrelation()
    return max(min(n, float(MIN_SAMPLES)), n * (1.0 - rho) / (1.0 + rho))


def fit_constraint(
    pos: ArrayLike,
    quat: ArrayLike | None = None,
    *,
    models: Sequence[str] = DEFAULT_MODELS,
    noise: NoiseModel | None = None,
    where: str = "track",
) -> Constraint:
    """Fit every candidate model to a relative-pose track and return the best by BIC.

    Parameters
    ----------
    pos : array_like, shape (n, 3)
        Child positions in the parent frame, metres. Rows with a NaN (in the
        position or the quaternion) are dropped.
    quat : array_like, shape (n, 4), optional
        Child orientations in the parent frame, x y z w; None for a position-only
        track (then cylindrical is not a candidate).
    models : sequence of str
        Candidates, among :data:`~thirdhand.constraints.types.MODEL_TYPES`
        (default :data:`DEFAULT_MODELS`: all but ``screw``).
    noise : NoiseModel, optional
        Noise bounds (defaults: 1 mm to 2.5 cm, 0.5° to 6°).
    where : str
        Name of the track in error messages.

    Returns
    -------
    Constraint
        The chosen model; ``scores`` holds the BIC of every candidate (``inf``
        for one that cannot describe the track) and ``confidence`` the chosen
        model's BIC weight. A candidate whose BIC falls far behind (by 200 plus
        10 %) a model fitted before it stops iterating early: its score is then
        an upper bound, not a converged value.

    Raises
    ------
    ConstraintFitError
        For an unknown model name, a malformed track or too few valid samples.
    """
    unknown = [m for m in models if m not in MODEL_TYPES]
    if unknown or not models:
        raise ConstraintFitError(
            f"{where}: unknown model(s) {', '.join(map(repr, unknown)) or '(none given)'}; "
            f"choose among {', '.join(MODEL_TYPES)}"
        )
    p, q = prepare_track(pos, quat, where=where)
    fits: dict[str, ModelFit] = {}
    best_bic = math.inf
    # Cheap models first: their BIC lets the joint models that fall far behind stop early.
    for name in sorted(dict.fromkeys(models), key=_FIT_ORDER.index):
        if name in _NEEDS_ORIENTATION and q is None:
            continue
        fit = fit_model(name, p, q, noise=noise, stop_above=best_bic + _margin(best_bic))
        if fit is not None:
            fits[name] = fit
            best_bic = min(best_bic, fit.bic)
    if not fits:
        raise ConstraintFitError(
            f"{where}: none of the models {', '.join(models)} can describe this track"
        )
    n_eff = effective_samples(fits)
    scores = {
        name: (fits[name].bic_at(n_eff) if name in fits else math.inf)
        for name in dict.fromkeys(models)
        if not (name in _NEEDS_ORIENTATION and q is None)
    }
    weights = bic_weights(scores)
    best = min(fits, key=lambda k: scores[k])
    return to_constraint(fits[best], p, q, confidence=weights[best], scores=scores)


def demo_track(
    demo: Demonstration,
    *,
    parent: str | None = None,
    child: str | None = None,
) -> tuple[FloatArray, FloatArray | None, str]:
    """The pose track a constraint is fitted to, from a recording.

    A single-body recording (an articulation log) gives that body's pose in the
    world; with two or more bodies, ``parent`` and ``child`` pick the pose of the
    child in the parent.

    Returns
    -------
    pos : ndarray, shape (T, 3)
        Metres; NaN where either body is invalid.
    quat : ndarray, shape (T, 4) or None
        x y z w; None when a body is position-only.
    where : str
        A name of the track for messages.

    Raises
    ------
    ConstraintFitError
        For an unknown body, or several bodies without ``parent``/``child``.
    """
    names = demo.body_names
    for name in (parent, child):
        if name is not None and name not in demo:
            raise ConstraintFitError(
                f"no body {name!r} in the recording; bodies are {', '.join(names)}"
            )
    if parent is None and child is None and len(names) == 1:
        body = names[0]
        valid = demo.valid(body)
        pos = np.where(valid[:, None], demo.pos(body), np.nan)
        quat = np.where(valid[:, None], demo.quat(body), np.nan)
        return pos, quat if demo.info(body).oriented else None, body
    if parent is None or child is None:
        raise ConstraintFitError(
            f"the recording has {len(names)} bodies ({', '.join(names)}); "
            "name the track with parent and child"
        )
    p, q, valid = demo.relative_pose(parent, child)
    pos = np.where(valid[:, None], p, np.nan)
    oriented = demo.info(parent).oriented and demo.info(child).oriented
    rel_quat = np.where(valid[:, None], q, np.nan) if oriented else None
    return pos, rel_quat, f"{child} in {parent}"


def fit_relative(
    demo: Demonstration,
    parent: str,
    child: str,
    *,
    start: float | None = None,
    end: float | None = None,
    models: Sequence[str] = DEFAULT_MODELS,
    noise: NoiseModel | None = None,
) -> Constraint:
    """Fit a constraint to the pose of ``child`` in ``parent`` over a time window.

    Parameters
    ----------
    demo : Demonstration
    parent, child : str
        Body names.
    start, end : float, optional
        Window in seconds on the demonstration's time axis (inclusive).
    models, noise
        As :func:`fit_constraint`.

    Raises
    ------
    ConstraintFitError
        For an unknown body, or too few frames where both bodies are valid.
    """
    p, q, where = demo_track(demo, parent=parent, child=child)
    keep = np.ones(demo.n_frames, dtype=bool)
    if start is not None:
        keep &= demo.t >= start
    if end is not None:
        keep &= demo.t <= end
    return fit_constraint(
        p[keep], None if q is None else q[keep], models=models, noise=noise, where=where
    )
