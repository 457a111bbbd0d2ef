"""The model fits: a :class:`~thirdhand.constraints.types.JointFit` from one model.

Each ``fit_<model>`` validates the track (:func:`prepare_track`), fits the model
robustly with its likelihood (:func:`thirdhand.constraints.robust.fit_model`) and
turns the fit into a constraint frame, an axis, the final pose and the free-DOF
ranges (:func:`to_constraint`). Model selection is in
:mod:`thirdhand.constraints.select`.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numpy.typing import ArrayLike

from thirdhand import se3
from thirdhand import se3_compiled as sc
from thirdhand.arrays import FloatArray
from thirdhand.constraints import geometry as g
from thirdhand.constraints.noise import estimate_noise
from thirdhand.constraints.robust import MIN_SAMPLES, ModelFit, fit_model, prepare_track
from thirdhand.constraints.types import ConstraintFitError, JointFit, NoiseModel

__all__ = [
    "MIN_SAMPLES",
    "ModelFit",
    "fit_cylindrical",
    "fit_fixed",
    "fit_free",
    "fit_model",
    "fit_prismatic",
    "fit_revolute",
    "fit_screw",
    "prepare_track",
    "to_constraint",
]


def _frame_from_axes(x: FloatArray, y_hint: FloatArray) -> FloatArray:
    """Quaternion of a frame whose x axis is ``x`` and whose y axis is nearest ``y_hint``."""
    return sc.frame_from_axes(np.ascontiguousarray(x), np.ascontiguousarray(y_hint))


def _align_x(q: FloatArray, axis: FloatArray) -> FloatArray:
    """Turn orientation ``q`` by the smallest rotation that takes its x axis to ``axis``."""
    return sc.align_x(np.ascontiguousarray(q), np.ascontiguousarray(axis))


def to_constraint(
    fit: ModelFit,
    pos: FloatArray,
    quat: FloatArray | None,
    *,
    confidence: float = 1.0,
    scores: dict[str, float] | None = None,
) -> JointFit:
    """The :class:`JointFit` described by a model fit of a prepared track.

    Latent ranges are measured from the last inlier sample (the constrained pose);
    the axis is turned so that the first inlier lies at a negative configuration.
    """
    geom, proj = fit.geom, fit.proj
    name = fit.kernel.name
    idx = np.flatnonzero(fit.inlier)
    first, last = int(idx[0]), int(idx[-1])
    lat = proj.latent[idx]
    sign = 1.0
    if lat.shape[1] and proj.latent[first, 0] > proj.latent[last, 0]:
        sign = -1.0
    end_lat = proj.latent[last] * sign
    rel = lat * sign - end_lat
    ranges = np.zeros((6, 2))
    axis = None if geom.axis is None else sign * geom.axis
    radius = None
    oriented = quat is not None
    q_end: FloatArray | None = None
    if name in ("fixed", "free"):
        p_end = geom.pos if name == "fixed" else pos[last]
        if oriented:
            assert geom.quat is not None and quat is not None
            q_end = geom.quat if name == "fixed" else quat[last]
        frame_q = q_end if q_end is not None else np.array([0.0, 0.0, 0.0, 1.0])
        frame_p = p_end
        if name == "free":
            local = se3.quat_rotate(se3.quat_conjugate(frame_q), pos[idx] - p_end)
            ranges[:3, 0] = local.min(axis=0)
            ranges[:3, 1] = local.max(axis=0)
            if oriented and quat is not None:
                rv = se3.rotvec_from_quat(se3.quat_multiply(se3.quat_conjugate(frame_q), quat[idx]))
                ranges[3:, 0] = rv.min(axis=0)
                ranges[3:, 1] = rv.max(axis=0)
            else:
                ranges[3:] = [-math.pi, math.pi]
    elif name == "prismatic":
        assert axis is not None
        p_end = geom.pos + end_lat[0] * axis
        frame_p = p_end
        if oriented:
            assert geom.quat is not None
            q_end = geom.quat
            frame_q = _align_x(q_end, axis)
        else:
            frame_q = _frame_from_axes(axis, np.zeros(3))
        ranges[0] = [rel[:, 0].min(), rel[:, 0].max()]
    else:
        assert axis is not None and geom.lever is not None and geom.axis is not None
        theta_end = proj.latent[last, 0]
        lever_end = g.rotate_about(geom.axis, np.array([theta_end]), geom.lever)[0]
        p_end = geom.pos + lever_end
        if name == "cylindrical":
            p_end = p_end + (proj.latent[last, 1] - geom.lever @ geom.axis) * geom.axis
            ranges[0] = [rel[:, 1].min(), rel[:, 1].max()]
        if name == "screw":
            pitch = geom.extra["pitch"]
            p_end = p_end + (geom.extra["h0"] + pitch * theta_end) * geom.axis
            # Coupled: the translation along the (turned) axis is pitch · angle.
            ranges[0] = np.sort(pitch * np.array([rel[:, 0].min(), rel[:, 0].max()]))
        frame_p = geom.pos + ((p_end - geom.pos) @ axis) * axis
        frame_q = _frame_from_axes(axis, p_end - frame_p)
        radius = float(np.linalg.norm(p_end - frame_p))
        ranges[3] = [rel[:, 0].min(), rel[:, 0].max()]
        if oriented:
            assert geom.quat is not None
            q_end = se3.quat_multiply(
                g.quat_axis_angle(geom.axis, np.array([theta_end])), geom.quat
            )[0]
    w_in = fit.inlier.astype(np.float64)
    rms_pos = math.sqrt(float(w_in @ proj.d2_pos) / w_in.sum())
    rms_rot = None
    if proj.d2_rot is not None:
        rms_rot = math.sqrt(float(w_in @ proj.d2_rot) / w_in.sum())
    if q_end is not None and q_end[3] < 0:
        q_end = -q_end
    if frame_q[3] < 0:
        frame_q = -frame_q
    return JointFit(
        type=name,
        frame_pos=np.asarray(frame_p, dtype=np.float64),
        frame_quat=np.asarray(frame_q, dtype=np.float64),
        axis=axis,
        origin=np.asarray(frame_p, dtype=np.float64),
        pos=np.asarray(p_end, dtype=np.float64),
        quat=q_end,
        ranges=ranges,
        radius=radius,
        pitch=geom.extra.get("pitch") if name == "screw" else None,
        rms_pos=rms_pos,
        rms_rot=rms_rot,
        sigma_pos=fit.sigma_pos,
        sigma_rot=fit.sigma_rot,
        outlier_fraction=fit.outlier_fraction,
        n_samples=int(pos.shape[0]),
        log_likelihood=fit.log_likelihood,
        confidence=confidence,
        scores=dict(scores or {name: fit.bic}),
    )


def _fit_one(
    name: str, pos: ArrayLike, quat: ArrayLike | None, noise: NoiseModel | None
) -> JointFit:
    p, q = prepare_track(pos, quat)
    est = estimate_noise(p, q)
    fit = fit_model(name, p, q, noise=est.noise_model() if noise is None else noise)
    if fit is None:
        why = "it needs orientations" if q is None else "the samples are degenerate"
        raise ConstraintFitError(f"track: cannot fit a {name} model: {why}")
    c = to_constraint(fit, p, q)
    return dataclasses.replace(
        c,
        noise_pos=est.sigma_pos,
        noise_rot=est.sigma_rot,
        noise_source="estimated" if noise is None else "given",
    )


def fit_fixed(
    pos: ArrayLike, quat: ArrayLike | None = None, *, noise: NoiseModel | None = None
) -> JointFit:
    """Fit a fixed (rigid) constraint: robust mean pose.

    Parameters
    ----------
    pos : array_like, shape (n, 3)
        Child positions in the parent frame, metres; NaN rows are dropped.
    quat : array_like, shape (n, 4), optional
        Child orientations in the parent frame, x y z w; None for position-only.
    noise : NoiseModel, optional
        Noise bounds; by default estimated from the track
        (:func:`thirdhand.constraints.noise.estimate_noise`).

    Returns
    -------
    JointFit
        ``scores`` holds this model's BIC only.
    """
    return _fit_one("fixed", pos, quat, noise)


def fit_prismatic(
    pos: ArrayLike, quat: ArrayLike | None = None, *, noise: NoiseModel | None = None
) -> JointFit:
    """Fit a prismatic constraint: a line of positions at constant orientation.

    Parameters and result as :func:`fit_fixed`; ``axis`` is the line direction,
    ``ranges[0]`` (tx) the observed displacement along it from the final pose.
    """
    return _fit_one("prismatic", pos, quat, noise)


def fit_revolute(
    pos: ArrayLike, quat: ArrayLike | None = None, *, noise: NoiseModel | None = None
) -> JointFit:
    """Fit a revolute constraint: rotation about one axis, positions on a circle.

    Parameters and result as :func:`fit_fixed`; ``axis`` and ``origin`` give the
    joint line, ``ranges[3]`` (rx) the observed angles from the final pose.
    A position-only track needs a finite circle (the points must not be collinear).
    """
    return _fit_one("revolute", pos, quat, noise)


def fit_cylindrical(
    pos: ArrayLike, quat: ArrayLike | None = None, *, noise: NoiseModel | None = None
) -> JointFit:
    """Fit a cylindrical constraint: rotation about and translation along one axis.

    Parameters and result as :func:`fit_fixed`; ``ranges[0]`` (tx) and
    ``ranges[3]`` (rx) are free. Needs orientations.
    """
    return _fit_one("cylindrical", pos, quat, noise)


def fit_screw(
    pos: ArrayLike, quat: ArrayLike | None = None, *, noise: NoiseModel | None = None
) -> JointFit:
    """Fit a screw constraint: rotation about an axis coupled to translation along it.

    Parameters and result as :func:`fit_fixed`; ``pitch`` is the translation per
    radian (metres, along ``axis``), ``ranges[3]`` (rx) the observed angles and
    ``ranges[0]`` (tx) the translation they imply. Needs orientations.
    """
    return _fit_one("screw", pos, quat, noise)


def fit_free(
    pos: ArrayLike, quat: ArrayLike | None = None, *, noise: NoiseModel | None = None
) -> JointFit:
    """Fit the free model: mean pose with a spread at least the noise ceiling.

    Parameters and result as :func:`fit_fixed`; ``ranges`` are the observed
    extents of the motion in the frame of the final pose.
    """
    return _fit_one("free", pos, quat, noise)
