"""Model selection: fit every candidate model and keep the best by BIC.

Unless the caller gives a :class:`~thirdhand.constraints.types.NoiseModel`, the
noise bounds come from the track itself (:mod:`thirdhand.constraints.noise`). A
joint whose turn the track cannot resolve (:func:`degenerate_joint`) is not
chosen, whatever its score, nor one whose score beats a simpler joint's by less
than :data:`EVIDENCE_MARGIN` (:func:`simplest_supported`). The confidence is the
posterior probability of the chosen type (:func:`type_probabilities`): the BIC
scores' weights at the temperature :data:`CONFIDENCE_TEMPERATURE`, mixed with
:data:`CONFIDENCE_FLOOR` of a uniform guess, both calibrated on synthetic tracks.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Collection, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from thirdhand.arrays import FloatArray
from thirdhand.constraints.models import (
    MIN_SAMPLES,
    ModelFit,
    fit_model,
    prepare_track,
    to_constraint,
)
from thirdhand.constraints.noise import estimate_noise
from thirdhand.constraints.types import (
    MODEL_TYPES,
    ConstraintFitError,
    JointFit,
    NoiseModel,
)
from thirdhand.demonstration import Demonstration

#: Models compared by default. Cylindrical (and screw) need orientations and are
#: skipped silently for position-only tracks. Screw is opt-in: its pitch also
#: soaks up a few millimetres of systematic error along a revolute axis, and a
#: cylindrical joint whose slide and turn move together is, per sample, cheaper
#: to describe as a screw with a larger noise (one latent instead of two).
DEFAULT_MODELS: tuple[str, ...] = ("fixed", "prismatic", "revolute", "cylindrical", "free")


#: Calibration of the confidence (``research/scripts/constraint_sweep.py``, tables in
#: ``research/notes/constraints.md``): the temperature that BIC differences are divided by
#: before they become probabilities, the share of a uniform guess mixed in, and the
#: factor on the weight of a type passed over (:func:`type_probabilities`). Real
#: errors are not white and the BIC's evidence grows with the number of samples as
#: if they were; a track with slowly varying error can be wrong by hundreds of BIC
#: units, which no temperature alone makes honest. The three values minimise the
#: log loss of the true type on the calibration seeds of the sweep (3.16 is 10^0.5
#: on its grid). Round 3 (3.98, no uniform share) gave a type passed over
#: probability 0, which the log loss charges as 27.6 nats where it was the truth.
CONFIDENCE_TEMPERATURE = 3.16
CONFIDENCE_FLOOR = 0.005
PASSED_OVER_WEIGHT = 0.3
#: An arc that bows away from its chord by less than this fraction of the chord
#: (``tan(φ/4)/2`` for a turn of φ: 3 % is a turn of 13.7°) is no evidence of a
#: turn from positions alone: real trackers bend a straight stroke by 1-2 % of its
#: length (``drawer_one``: revolute fits of 3-14 m radius over a 45 cm stroke).
MIN_SAGITTA_RATIO = 0.03
#: Orientations confirm a turn they resolve: a range of at least this many
#: rotation noise floors.
MIN_TURN_FLOORS = 5.0
#: ... and at least this turn, radians: a tracker's systematic orientation error
#: (a tag's viewing angle, a camera's distortion) changes by a few degrees along a
#: stroke, which reads as a wide, slight turn. Chosen on the synthetic sweep's
#: calibration seeds (``research/notes/constraints.md``): 5-9° give the same accuracy, 7° by a
#: track; without it 96.6 % becomes 95.5 % (a stroke under a pose-dependent error of
#: 4 times the white level: 97 % against 91 % right). Absolute, not in units of the
#: rotation noise: a precise tracker (a robot's encoders) may still carry a degree of
#: calibration error (10 and 15 noise floors instead: 96.0 and 96.1 %).
MIN_TURN = math.radians(7.0)
#: Largest distance from a hinge to where people grasp the part, metres: a physical
#: prior on revolute joints, stated, not fitted. A room door 0.9 m wide is grasped
#: about 0.85 m from its hinges; kitchen, wardrobe and appliance doors are at most
#: 0.6 m wide; lids, flaps and the hinged parts of assemblies are smaller. An arc
#: flatter than one of this radius over the same chord by :data:`MIN_TURN_FLOORS`
#: standard errors of its bow (:func:`unphysical_turn`) is a straight stroke that the
#: tracker bent (a sliding cabinet door's 59 cm stroke bowed by 2 cm reads as a
#: 1.9 m radius), not a hinge. The leave-one-mechanism-out table of
#: ``research/notes/constraints.md`` (``research/scripts/constraint_lomo.py``) re-fits
#: it per held-out mechanism.
MAX_HINGE_RADIUS = 1.0
#: How a note of :func:`unphysical_turn` says the arc is flatter than any hinge's.
HINGE_NOTE = "flatter than a hinge"
#: A constrained fit whose position noise is at least this fraction of its ceiling
#: and which calls smooth samples outliers (:func:`saturated_joint`) is no joint of
#: the track. Chosen on the synthetic sweep's calibration seeds
#: (``research/notes/constraints.md``): 0.6, 0.7, 0.8, 0.9 and 0.999 (the ceiling itself)
#: leave 54, 41, 38, 39 and 40 of 2,075 tracks wrong; 0.8 the fewest.
NEAR_CEILING = 0.8
#: A joint with more parameters is chosen over a simpler joint only on positive
#: evidence: a BIC lower by at least this much. Twice the calibrated temperature, so
#: that the BIC difference over :data:`CONFIDENCE_TEMPERATURE` is at least 2, Kass and
#: Raftery's "positive" evidence (odds of e : 1 in the calibrated weights). Derived,
#: not tuned: on the synthetic sweep's calibration seeds margins of 0, 2, 4, 6.32, 10
#: and 15 leave 37, 28, 29, 26, 24 and 22 of 2,074 tracks wrong where the motion is at
#: least 5x the noise, and 146, 142, 145, 144, 148 and 153 of all 2,340
#: (``research/notes/constraints.md``). Slowly varying error (time drift, a pose-dependent error)
#: gives a still part a stroke, a stroke a turn, a turn a slide, that wins by 0-5 BIC
#: units: the effective sample count leaves a few samples, where the BIC's penalty per
#: parameter (``log n_eff``, 2 for 8 samples) is no stronger than the AIC's.
EVIDENCE_MARGIN = 2.0 * CONFIDENCE_TEMPERATURE


def bic_weights(scores: dict[str, float], temperature: float = 1.0) -> dict[str, float]:
    """Posterior model weights ``exp(-BIC / (2 T))``, normalised; infinite scores get 0."""
    names = [k for k, v in scores.items() if math.isfinite(v)]
    if not names:
        return {k: 0.0 for k in scores}
    b = np.array([scores[k] for k in names])
    e = np.exp(-0.5 * (b - b.min()) / temperature)
    w = e / e.sum()
    out = {k: 0.0 for k in scores}
    out.update({k: float(v) for k, v in zip(names, w, strict=True)})
    return out


def type_probabilities(
    scores: dict[str, float],
    *,
    passed_over: Collection[str] = (),
    void: Collection[str] = (),
    temperature: float = CONFIDENCE_TEMPERATURE,
    floor: float = CONFIDENCE_FLOOR,
    passed_over_weight: float = PASSED_OVER_WEIGHT,
) -> dict[str, float]:
    """Calibrated probability of each type from its BIC (infinite scores get 0).

    ``(1 - floor) · w + floor / K``, with ``w`` the :func:`bic_weights` at
    ``temperature``, those of the ``passed_over`` types (a turn the track does
    not resolve, :func:`degenerate_joint`; a joint whose error is motion,
    :func:`saturated_joint`) multiplied by ``passed_over_weight`` and all
    renormalised, and ``K`` the number of candidates with a finite score. A type
    passed over keeps a share of its weight: the test that passed it over can be
    wrong, and a close call (a better-scoring joint passed over) should read as
    one. A ``void`` type keeps none of its weight (only its share of the floor):
    a turn whose path is straight (it bows by less than :data:`MIN_SAGITTA_RATIO`
    of its chord, a radius far beyond the track) describes the line's motion, not
    another one; a saturated joint (:func:`saturated_joint`) describes none, its
    error is the part's motion.
    """
    w = bic_weights(scores, temperature)
    for name in passed_over:
        if name in w:
            w[name] *= 0.0 if name in void else passed_over_weight
    total = sum(w.values())
    if total > 0.0:
        w = {k: v / total for k, v in w.items()}
    else:
        # Every finite candidate passed over with no weight left: their own weights.
        w = bic_weights(scores, temperature)
    k = sum(math.isfinite(v) for v in scores.values())
    return {
        name: ((1.0 - floor) * w[name] + floor / k) if math.isfinite(v) else 0.0
        for name, v in scores.items()
    }


_NEEDS_ORIENTATION = ("cylindrical", "screw")
_FIT_ORDER = ("free", "fixed", "prismatic", "revolute", "cylindrical", "screw")


def _margin(best: float) -> float:
    """How far behind the best BIC so far a model may fall before its fit stops early."""
    return 200.0 + 0.1 * abs(best) if math.isfinite(best) else math.inf


def effective_samples(fits: dict[str, ModelFit]) -> float:
    """Effective number of independent samples of a track, from its best model's residuals.

    ``n / τ``, with ``τ`` the integrated autocorrelation time of the residuals of
    the model with the lowest plain BIC (the model whose residuals are closest to
    the sensor error; :meth:`~thirdhand.constraints.robust.ModelFit.residual_correlation_time`).
    White residuals (the synthetic white-noise tracks) give ``n``; a real sensor's
    slowly varying error (a camera's bias that changes along a drawer's stroke, a
    tracker that wanders) gives far fewer, and a systematic error of a few
    millimetres is no longer strong evidence for a curved joint or a slide. The
    lag-1 correlation alone (the AR(1) ``n (1 - ρ) / (1 + ρ)``, used before) counts
    an error that is white noise plus a slow wander as 5-10 times more samples
    than it holds.
    """
    best = min(fits.values(), key=lambda f: f.bic)
    n = float(best.weights.shape[0])
    return max(min(n, float(MIN_SAMPLES)), n / best.residual_correlation_time())


def degenerate_joint(
    fit: ModelFit, *, oriented: bool, rot_floor: float, n_eff: float
) -> str | None:
    """Why a fitted joint with a turn cannot be told from one without, or None.

    A revolute, cylindrical or screw fit whose angle range ``φ`` (of the inlier
    samples) bows the path by less than :data:`MIN_SAGITTA_RATIO` of its chord is
    a straight stroke within a tracker's systematic error (its radius is far
    beyond the track's extent) — unless orientations resolve the turn: ``φ`` at
    least :data:`MIN_TURN` and :data:`MIN_TURN_FLOORS` standard errors
    ``σ √(12 / n_eff)`` of a linear trend of ``n_eff`` effective samples of
    rotation noise ``σ`` (the floor).

    Nor is one chosen whose bow from the chord, ``r (1 - cos(φ/2))``, is under
    :data:`MIN_TURN_FLOORS` standard errors ``σ_pos √(12 / n_eff)`` of a trend in
    its own residuals (``σ_pos`` its fitted position noise), unless orientations
    resolve the turn: a tracker's error that wanders slowly along a stroke bends
    it by more than 3 % of its chord at a few noise levels.

    A cylindrical fit's slide must be resolved as well: at least
    :data:`MIN_TURN_FLOORS` standard errors ``σ_pos √(12 / n_eff)`` of a trend in
    its own residuals (``σ_pos`` its fitted position noise). A slowly varying
    error along a turn (a pose-dependent calibration error, a tag's viewing angle)
    gives a revolute joint a slide of a few millimetres that the residuals'
    correlation time says is no more than that error.
    """
    name = fit.kernel.name
    if name not in ("revolute", "cylindrical", "screw"):
        return None
    keep = fit.inlier if np.any(fit.inlier) else np.ones(fit.inlier.shape, dtype=bool)
    if name == "cylindrical":
        slide = float(np.ptp(fit.proj.latent[keep, 1]))
        se = fit.sigma_pos * math.sqrt(12.0 / n_eff)
        if slide < MIN_TURN_FLOORS * se:
            return (
                f"cylindrical not chosen: its slide of {1e3 * slide:.1f} mm is under "
                f"{MIN_TURN_FLOORS:g} standard errors ({1e3 * MIN_TURN_FLOORS * se:.1f} mm) of a "
                f"trend in its residuals ({n_eff:.0f} effective samples)"
            )
    lat = fit.proj.latent[keep, 0]
    phi = float(np.ptp(lat))
    if oriented and phi >= max(
        MIN_TURN, MIN_TURN_FLOORS * rot_floor * math.sqrt(12.0 / max(n_eff, 12.0))
    ):
        return None
    ratio = 0.5 * math.tan(0.25 * min(phi, 2.0 * math.pi))
    radius = math.nan
    if fit.geom.lever is not None and fit.geom.axis is not None:
        lever = fit.geom.lever - (fit.geom.lever @ fit.geom.axis) * fit.geom.axis
        radius = float(np.linalg.norm(lever))
    bow = radius * (1.0 - math.cos(0.5 * min(phi, math.pi)))
    se = bow_standard_error(fit, n_eff)
    if ratio >= MIN_SAGITTA_RATIO and not bow < MIN_TURN_FLOORS * se:
        return unphysical_turn(fit, n_eff=n_eff)
    if ratio >= MIN_SAGITTA_RATIO:
        return (
            f"{name} not chosen: its {math.degrees(phi):.1f}° turn (radius {radius:.3g} m) "
            f"bows the path by {1e3 * bow:.1f} mm, under {MIN_TURN_FLOORS:g} standard errors "
            f"({1e3 * MIN_TURN_FLOORS * se:.1f} mm) of a trend in its residuals "
            f"({n_eff:.0f} effective samples)"
            + ("" if not oriented else ", and the orientations do not resolve it")
        )
    return (
        f"{name} not chosen: its {math.degrees(phi):.1f}° turn (radius {radius:.3g} m) bows "
        f"the path by {100 * ratio:.1f} {STRAIGHT_NOTE}, under {100 * MIN_SAGITTA_RATIO:.0f} %"
        + ("" if not oriented else ", and the orientations do not resolve it")
    )


def bow_standard_error(fit: ModelFit, n_eff: float) -> float:
    """Standard error of a trend in a fit's residuals, metres: ``σ_pos √(12 / n_eff)``.

    The error model is white noise plus a slowly varying (systematic) part: the fit's
    residual level ``σ_pos`` holds both, and the effective sample count ``n_eff``
    (:func:`effective_samples`, from the residuals' correlation time) counts the
    systematic part once per correlation time, so that ``σ_pos² / n_eff`` is
    ``σ_white² / n + σ_sys² τ_sys / n``: a bow, a slide or a stroke must stand out
    of both.
    """
    return fit.sigma_pos * math.sqrt(12.0 / n_eff)


def unphysical_turn(fit: ModelFit, *, n_eff: float) -> str | None:
    """Why a revolute fit is no hinge a person operates (its radius), or None.

    The fit's arc bows away from its chord ``c`` by ``b``; an arc of the largest
    hinge radius :data:`MAX_HINGE_RADIUS` ``R`` over the same chord bows by
    ``R (1 - cos(asin(c / 2R)))``. When ``b`` falls short of that by at least
    :data:`MIN_TURN_FLOORS` standard errors (:func:`bow_standard_error`) the arc
    is flatter than any hinge's: a straight stroke bent by the tracker's
    systematic error (a calibration warp, a flexing runner). A chord longer than
    ``2 R`` no hinge of radius ``R`` makes. Checked from positions alone (the
    caller skips it when orientations resolve the turn).
    """
    if (
        fit.kernel.name != "revolute"
        or fit.geom.lever is None
        or fit.geom.axis is None
        or not math.isfinite(MAX_HINGE_RADIUS)
    ):
        return None
    keep = fit.inlier if np.any(fit.inlier) else np.ones(fit.inlier.shape, dtype=bool)
    phi = min(float(np.ptp(fit.proj.latent[keep, 0])), 2.0 * math.pi)
    lever = fit.geom.lever - (fit.geom.lever @ fit.geom.axis) * fit.geom.axis
    radius = float(np.linalg.norm(lever))
    chord = 2.0 * radius * math.sin(0.5 * min(phi, math.pi))
    bow = radius * (1.0 - math.cos(0.5 * min(phi, math.pi)))
    r_max = MAX_HINGE_RADIUS
    se = bow_standard_error(fit, n_eff)
    if chord > 2.0 * r_max:
        return (
            f"revolute not chosen: its {math.degrees(phi):.1f}° turn (radius {radius:.3g} m) "
            f"spans a {chord:.2f} m chord: {HINGE_NOTE} of radius {r_max:g} m spans at most "
            f"{2.0 * r_max:g} m"
        )
    bow_max = r_max * (1.0 - math.cos(math.asin(chord / (2.0 * r_max))))
    if bow_max - bow < MIN_TURN_FLOORS * se:
        return None
    return (
        f"revolute not chosen: its {math.degrees(phi):.1f}° turn (radius {radius:.3g} m) "
        f"bows the path by {1e3 * bow:.1f} mm, {1e3 * (bow_max - bow):.1f} mm "
        f"({(bow_max - bow) / se:.1f} standard errors) {HINGE_NOTE} of radius {r_max:g} m "
        f"over its {1e3 * chord:.0f} mm chord"
    )


#: How a note of :func:`degenerate_joint` says the path is straight (a turn that bows
#: it by less than :data:`MIN_SAGITTA_RATIO` of its chord), and how one of
#: :func:`saturated_joint` says the joint's noise is near its ceiling.
STRAIGHT_NOTE = "% of its chord"
SATURATED_NOTE = "is near the ceiling"
#: How a note of :func:`simplest_supported` says a joint's better score is no positive
#: evidence for its extra parameters.
EVIDENCE_NOTE = "no positive evidence"


def passed_over_types(notes: Sequence[str]) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The types a fit's notes pass over, and those of them whose weight is void.

    Each note of :func:`degenerate_joint` and :func:`saturated_joint` starts with the
    type's name. Void (:func:`type_probabilities`): a straight path's
    (:data:`STRAIGHT_NOTE`), a saturated joint's (:data:`SATURATED_NOTE`) and an
    arc flatter than any hinge's (:data:`HINGE_NOTE`, :func:`unphysical_turn`).

    Returns
    -------
    passed_over, void : tuple of str
    """
    names = tuple(note.split()[0] for note in notes)
    void = tuple(
        note.split()[0]
        for note in notes
        if STRAIGHT_NOTE in note or SATURATED_NOTE in note or HINGE_NOTE in note
    )
    return names, void


def saturated_joint(
    fit: ModelFit,
    *,
    ceiling: float,
    gross: NDArray[np.bool_] | None,
    untrusted: bool = False,
) -> str | None:
    """Why a constrained fit is no joint of the track (its error is motion), or None.

    A fixed, prismatic, revolute, cylindrical or screw fit whose position noise is
    near its ceiling (at least :data:`NEAR_CEILING` of it: the ceiling is the
    largest error the tracker may have) and which still gives to the outlier
    class samples that are no gross outliers — no jump away from their
    neighbours in time (``gross``, the flags of the noise estimate,
    :func:`~thirdhand.constraints.noise.estimate_noise`) — explains smooth motion
    away: a part moving freely, whose path a joint follows only with nearly its
    largest noise and a share of it called outliers (position-only free parts:
    a circle with a quarter of the samples as outliers). A joint well inside its
    noise bounds may still give a smooth stretch to the outlier class (the last
    15 % of ``cabinet_one/002``, at 2.2 mm of noise: a real outlier stretch).

    With ``untrusted`` (the bounds come from a noise estimate clipped at its cap,
    :attr:`~thirdhand.constraints.noise.NoiseEstimate.pos_clipped`: the track's
    short-window residuals are beyond any tracker's noise, and the ceiling is the
    largest the cap allows, not a measured error) a fit near its ceiling is
    saturated whether or not it calls samples outliers: nothing about the tracker
    says that it may err by that much.
    """
    if fit.kernel.name == "free" or gross is None or fit.sigma_pos < NEAR_CEILING * ceiling:
        return None
    smooth = int(np.count_nonzero(~fit.inlier & ~gross))
    if smooth == 0 and not untrusted:
        return None
    if smooth == 0:
        return (
            f"{fit.kernel.name} not chosen: its noise ({1e3 * fit.sigma_pos:.1f} mm) "
            f"{SATURATED_NOTE} ({1e3 * ceiling:.1f} mm), set from a noise estimate "
            "clipped at its cap (motion too fast for the window)"
        )
    return (
        f"{fit.kernel.name} not chosen: its noise ({1e3 * fit.sigma_pos:.1f} mm) "
        f"{SATURATED_NOTE} ({1e3 * ceiling:.1f} mm) and it calls {smooth} samples outliers "
        "that are no jumps (smooth motion)"
    )


def simplest_supported(
    scores: dict[str, float], fits: dict[str, ModelFit], candidates: Sequence[str]
) -> tuple[str, list[str]]:
    """The joint to choose among ``candidates``, and why more flexible ones are not.

    The best-scoring candidate, unless a joint with fewer parameters
    (``ModelFit.kernel.n_params``: fixed, prismatic, revolute, cylindrical) scores
    within :data:`EVIDENCE_MARGIN` of it: then the simplest such joint. Free is no
    joint (its spread is the motion): when it scores best it is chosen as is.

    Returns
    -------
    chosen : str
    notes : list of str
        One per candidate with more parameters than ``chosen`` and a better score,
        starting with its name (a type passed over, :func:`passed_over_types`).
    """
    best = min(candidates, key=lambda k: scores[k])
    if best == "free":
        return best, []
    joints = [k for k in candidates if k != "free"]

    def size(k: str) -> int:
        return fits[k].kernel.n_params[int(fits[k].proj.d2_rot is not None)]

    chosen = min(
        (k for k in joints if k == best or scores[k] < scores[best] + EVIDENCE_MARGIN),
        key=lambda k: (size(k), scores[k]),
    )
    notes = [
        f"{k} not chosen: its BIC is {scores[chosen] - scores[k]:.1f} below {chosen}'s, "
        f"under {EVIDENCE_MARGIN:.2f} ({EVIDENCE_NOTE} for {size(k) - size(chosen)} more "
        "parameters)"
        for k in joints
        if size(k) > size(chosen) and scores[k] < scores[chosen]
    ]
    return chosen, notes


def fit_constraint(
    pos: ArrayLike,
    quat: ArrayLike | None = None,
    *,
    models: Sequence[str] = DEFAULT_MODELS,
    noise: NoiseModel | None = None,
    where: str = "track",
) -> JointFit:
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
        Noise bounds. Default: estimated from the track
        (:func:`~thirdhand.constraints.noise.estimate_noise`, floors at twice the
        white-noise estimate); ``NoiseModel()`` is the motion-capture preset
        (1 mm floor), ``NoiseModel.camera()`` the camera one (1 cm).
    where : str
        Name of the track in error messages.

    Returns
    -------
    JointFit
        The chosen model; ``scores`` holds the BIC of every candidate (``inf``
        for one that cannot describe the track), ``confidence`` the calibrated
        probability of the chosen type, ``noise_pos`` and ``noise_rot`` the
        estimated white noise and ``notes`` why a better-scoring joint was
        passed over (:func:`degenerate_joint`, :func:`saturated_joint`,
        :func:`simplest_supported`). A candidate whose BIC
        falls far behind (by 200 plus 10 %) a model fitted before it stops
        iterating early: its score is then an upper bound, not a converged value.

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
    est = estimate_noise(p, q)
    nm = est.noise_model() if noise is None else noise
    fits: dict[str, ModelFit] = {}
    best_bic = math.inf
    # Cheap models first: their BIC lets the joint models that fall far behind stop early.
    for name in sorted(dict.fromkeys(models), key=_FIT_ORDER.index):
        if name in _NEEDS_ORIENTATION and q is None:
            continue
        fit = fit_model(name, p, q, noise=nm, stop_above=best_bic + _margin(best_bic))
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
    notes = []
    passed_over = []
    saturated = {}
    for name, fit in fits.items():
        why = degenerate_joint(fit, oriented=q is not None, rot_floor=nm.rot_floor, n_eff=n_eff)
        if why is None:
            why = saturated_joint(
                fit,
                ceiling=nm.pos_ceiling,
                gross=est.gross,
                untrusted=noise is None and est.pos_clipped,
            )
            if why is not None:
                saturated[name] = why
            continue
        passed_over.append(name)
        notes.append(why)
    # The best score among the joints not passed over (all of them if every one was:
    # only degenerate joints were asked for, the best of them with its note). A
    # saturated joint is passed over (and noted) when it scores better than that.
    left = [k for k in fits if k not in passed_over and k not in saturated]
    left = left or [k for k in fits if k not in passed_over] or list(fits)
    best, occam = simplest_supported(scores, fits, left)
    passed_over += [note.split()[0] for note in occam]
    notes += occam
    for name, why in saturated.items():
        if name != best and scores[name] < scores[best]:
            passed_over.append(name)
            notes.append(why)
    names, void = passed_over_types(notes)
    weights = type_probabilities(scores, passed_over=names, void=void)
    c = to_constraint(fits[best], p, q, confidence=weights[best], scores=scores)
    others = [k for k in fits if k != best]
    runner_up = None
    if others:
        second = max(others, key=lambda k: (weights[k], -scores[k]))
        runner_up = to_constraint(fits[second], p, q, confidence=weights[second], scores=scores)
    return dataclasses.replace(
        c,
        noise_pos=est.sigma_pos,
        noise_rot=est.sigma_rot,
        noise_source="estimated" if noise is None else "given",
        notes=tuple(notes),
        runner_up=runner_up,
    )


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
) -> JointFit:
    """Fit a constraint to the pose of ``child`` in ``parent`` over a time window.

    Parameters
    ----------
    demo : Demonstration
    parent, child : str
        Body names.
    start, end : float, optional
        Window in seconds on the demonstration's time axis (inclusive).
    models, noise
        As :func:`fit_constraint` (by default the noise is estimated from the track).

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
