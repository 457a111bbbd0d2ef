"""The geometry of each constraint model: a weighted fit and a projection.

A model explains each sample ``(p_i, q_i)`` of a relative-pose track as a point
of a ``d``-dimensional configuration space (the latent: nothing for fixed, the
displacement for prismatic, the angle for revolute, both for cylindrical) plus
Gaussian noise. :meth:`Kernel.fit` estimates the model's parameters from
weighted samples; :meth:`Kernel.project` finds each sample's latent value and
returns the residuals and the latent's Jacobian norms that the likelihood of
:mod:`thirdhand.constraints.models` needs.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from thirdhand.constraints import geometry as g

FloatArray = NDArray[np.float64]


@dataclass
class Projection:
    """Residuals of a track against a fitted model.

    Attributes
    ----------
    e_pos : ndarray, shape (n, 3)
        Observed minus predicted position, metres, parent frame.
    e_rot : ndarray, shape (n, 3) or None
        Rotation vector of ``q_obs ⊗ q_pred⁻¹``, radians; None for position-only.
    latent : ndarray, shape (n, d)
        Configuration of each sample (metres along an axis, radians about it).
    g_pos, g_rot : ndarray, shape (n, d)
        Squared norms of the position and rotation Jacobians of each latent
        coordinate (``1`` and ``0`` for a translation; ``r²`` and ``1`` for a
        rotation at radius ``r``). The latent coordinates are orthogonal.
    """

    e_pos: FloatArray
    e_rot: FloatArray | None
    latent: FloatArray
    g_pos: FloatArray
    g_rot: FloatArray
    #: Squared norms of ``e_pos`` and ``e_rot``, shape (n,), filled on construction.
    d2_pos: FloatArray = field(init=False)
    d2_rot: FloatArray | None = field(init=False)

    def __post_init__(self) -> None:
        self.d2_pos = np.einsum("ij,ij->i", self.e_pos, self.e_pos)
        self.d2_rot = None if self.e_rot is None else np.einsum("ij,ij->i", self.e_rot, self.e_rot)


@dataclass
class Geometry:
    """Fitted parameters of one model (the fields a model does not use stay None)."""

    pos: FloatArray
    quat: FloatArray | None
    axis: FloatArray | None = None
    lever: FloatArray | None = None
    theta: FloatArray | None = None
    basis: FloatArray | None = None
    mask: NDArray[np.bool_] | None = None
    extra: dict[str, float] = field(default_factory=dict)


def _rot_residual(q: FloatArray | None, q_pred: FloatArray | None) -> FloatArray | None:
    """Rotation vectors of ``q ⊗ q_pred⁻¹`` for a constant ``q_pred (4,)``, shape (n, 3)."""
    if q is None or q_pred is None:
        return None
    return g.quat_log(q @ g.quat_right_matrix(g.quat_conj(q_pred)))


class Kernel:
    """Base class: a model's weighted fit and projection."""

    name = ""
    n_latent = 0
    #: Number of free parameters for (position-only, oriented) tracks, for the BIC.
    n_params: tuple[int, int] = (0, 0)

    def fit(
        self, p: FloatArray, q: FloatArray | None, w: FloatArray, ratio: float
    ) -> Geometry | None:
        """Fit to weighted samples; ``ratio = σ_pos / σ_rot`` (metres per radian).

        Returns None when the samples cannot support the model (e.g. collinear
        points for a position-only circle).
        """
        raise NotImplementedError

    def project(
        self, geom: Geometry, p: FloatArray, q: FloatArray | None, ratio: float
    ) -> Projection:
        """Latent values and residuals of every sample."""
        raise NotImplementedError


class Fixed(Kernel):
    """Constant relative pose: robust mean position and average orientation."""

    name = "fixed"
    n_params = (3, 6)

    def fit(
        self, p: FloatArray, q: FloatArray | None, w: FloatArray, ratio: float
    ) -> Geometry | None:
        uniform = bool(np.all(w == w[0]))
        pos = np.median(p, axis=0) if uniform else g.weighted_mean(p, w)
        return Geometry(pos=pos, quat=None if q is None else g.quat_average(q, w))

    def project(
        self, geom: Geometry, p: FloatArray, q: FloatArray | None, ratio: float
    ) -> Projection:
        empty = np.zeros((p.shape[0], 0))
        return Projection(p - geom.pos, _rot_residual(q, geom.quat), empty, empty, empty)


class Free(Fixed):
    """Unconstrained motion: the mean pose and a broad spread (set by the likelihood)."""

    name = "free"

    def fit(
        self, p: FloatArray, q: FloatArray | None, w: FloatArray, ratio: float
    ) -> Geometry | None:
        return Geometry(pos=g.weighted_mean(p, w), quat=None if q is None else g.quat_average(q, w))


class Prismatic(Kernel):
    """Translation along a line at constant orientation."""

    name = "prismatic"
    n_latent = 1
    n_params = (6, 9)

    def fit(
        self, p: FloatArray, q: FloatArray | None, w: FloatArray, ratio: float
    ) -> Geometry | None:
        centroid, axes, _ = g.plane_fit(p, w)
        quat = None if q is None else g.quat_average(q, w)
        return Geometry(pos=centroid, quat=quat, axis=axes[0])

    def project(
        self, geom: Geometry, p: FloatArray, q: FloatArray | None, ratio: float
    ) -> Projection:
        assert geom.axis is not None
        s = (p - geom.pos) @ geom.axis
        e_pos = p - geom.pos - s[:, None] * geom.axis
        ones = np.ones((p.shape[0], 1))
        return Projection(e_pos, _rot_residual(q, geom.quat), s[:, None], ones, 0.0 * ones)


class Revolute(Kernel):
    """Rotation about a fixed axis; positions on a circle around it.

    With orientations, the axis and angles come from the rotations
    (:func:`geometry.rotation_plane_axis`) and the centre from a linear least
    squares; without, from a plane fit and a circle fit of the positions.
    """

    name = "revolute"
    n_latent = 1
    n_params = (8, 11)
    #: Translation along the axis is a free latent (cylindrical).
    planar = False
    #: Translation along the axis is ``pitch · θ`` (screw).
    coupled = False

    def fit(
        self, p: FloatArray, q: FloatArray | None, w: FloatArray, ratio: float
    ) -> Geometry | None:
        if q is None:
            return self._fit_positions(p, w)
        axis, theta, q0 = g.rotation_plane_axis(q, w)
        if not self.planar:
            axis = g.refine_axis_with_plane(axis, p, theta, w, ratio)
        centre, lever = g.revolute_centre(p, axis, theta, w, planar=self.planar)
        return Geometry(pos=centre, quat=q0, axis=axis, lever=lever, theta=theta)

    def _fit_positions(self, p: FloatArray, w: FloatArray) -> Geometry | None:
        centroid, axes, _ = g.plane_fit(p, w)
        normal = axes[2]
        e1 = axes[0]
        e2 = g.cross3(normal, e1)
        basis = np.stack([e1, e2])
        xy = (p - centroid) @ basis.T
        c2, r = g.circle_fit_2d(xy, w)
        if not np.isfinite(r):
            return None
        centre = centroid + c2 @ basis
        return Geometry(pos=centre, quat=None, axis=normal, lever=r * e1, basis=basis, mask=w > 0)

    def _angles(self, geom: Geometry, p: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Angle of each position about the axis from the lever, and the radii."""
        assert geom.axis is not None and geom.lever is not None
        a = geom.axis
        lev = geom.lever - (geom.lever @ a) * a
        r = float(np.linalg.norm(lev))
        e1 = lev / r if r > 1e-12 else np.zeros(3)
        e2 = g.cross3(a, e1)
        v = p - geom.pos
        return np.arctan2(v @ e2, v @ e1), v @ a, np.full(p.shape[0], r)

    def project(
        self, geom: Geometry, p: FloatArray, q: FloatArray | None, ratio: float
    ) -> Projection:
        assert geom.axis is not None and geom.lever is not None
        a = geom.axis
        theta_pos, height, radius = self._angles(geom, p)
        if q is None or geom.theta is None:
            mask = np.ones(p.shape[0], dtype=bool) if geom.mask is None else geom.mask
            theta = g.unwrap_masked(theta_pos, mask)
            rot_w = np.zeros_like(theta)
        else:
            # Weighted least squares of the angle estimates: position error r·Δθ
            # against σ_pos, rotation error Δθ against σ_rot (and, for a screw, the
            # height error pitch·Δθ against σ_pos).
            r2 = radius * radius
            on_branch = geom.theta + g.wrap_angle(theta_pos - geom.theta)
            num = ratio * ratio * geom.theta + r2 * on_branch
            den = ratio * ratio + r2
            if self.coupled:
                pitch, h0 = geom.extra["pitch"], geom.extra["h0"]
                if abs(pitch) > 1e-12:
                    num = num + pitch * (height - h0)
                    den = den + pitch * pitch
            theta = num / den
            rot_w = np.ones_like(theta)
        pred = geom.pos + g.rotate_about(a, theta, geom.lever)
        lat = [theta]
        gp = [radius * radius]
        gr = [rot_w]
        if self.coupled:
            pitch, h0 = geom.extra["pitch"], geom.extra["h0"]
            pred = pred + (h0 + pitch * theta)[:, None] * a
            gp = [radius * radius + pitch * pitch]
        if self.planar:
            pred = pred + (height - geom.lever @ a)[:, None] * a
            lat.append(height)
            gp.append(np.ones_like(theta))
            gr.append(np.zeros_like(theta))
        e_rot = None
        if q is not None and geom.quat is not None:
            # q ⊗ (rot(a, θ) ⊗ q0)⁻¹ = (q ⊗ q0⁻¹) ⊗ (cos θ/2, -sin θ/2 a): two matmuls.
            x = q @ g.quat_right_matrix(g.quat_conj(geom.quat))
            y = x @ g.quat_right_matrix(np.append(-a, 0.0))
            half = 0.5 * theta
            e_rot = g.quat_log(np.cos(half)[:, None] * x + np.sin(half)[:, None] * y)
        return Projection(
            p - pred,
            e_rot,
            np.stack(lat, axis=1),
            np.stack(gp, axis=1),
            np.stack(gr, axis=1),
        )


class Cylindrical(Revolute):
    """Rotation about and translation along one axis, independent (needs orientations)."""

    name = "cylindrical"
    n_latent = 2
    n_params = (12, 12)
    planar = True

    def fit(
        self, p: FloatArray, q: FloatArray | None, w: FloatArray, ratio: float
    ) -> Geometry | None:
        if q is None:
            return None
        return super().fit(p, q, w, ratio)


class Screw(Revolute):
    """Rotation about an axis coupled to translation along it, ``h = h0 + pitch · θ``.

    Needs orientations. The axis and angles come from the rotations, the centre
    from the positions projected on the plane normal to the axis, the pitch from a
    weighted line fit of the height along the axis against the angle.
    """

    name = "screw"
    n_params = (12, 12)
    coupled = True

    def fit(
        self, p: FloatArray, q: FloatArray | None, w: FloatArray, ratio: float
    ) -> Geometry | None:
        if q is None:
            return None
        axis, theta, q0 = g.rotation_plane_axis(q, w)
        centre, lever = g.revolute_centre(p, axis, theta, w, planar=True)
        height = (p - centre) @ axis
        sw = w.sum()
        t_mean = (w @ theta) / sw
        h_mean = (w @ height) / sw
        dt = theta - t_mean
        var = w @ (dt * dt)
        pitch = float(w @ (dt * (height - h_mean)) / var) if var > 1e-18 * sw else 0.0
        geom = Geometry(pos=centre, quat=q0, axis=axis, lever=lever, theta=theta)
        geom.extra = {"pitch": pitch, "h0": float(h_mean - pitch * t_mean)}
        return geom


KERNELS: dict[str, Kernel] = {
    k.name: k for k in (Fixed(), Prismatic(), Revolute(), Cylindrical(), Screw(), Free())
}
