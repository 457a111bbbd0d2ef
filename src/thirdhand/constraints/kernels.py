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

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit
from numpy.typing import NDArray

from thirdhand import se3_compiled as sc
from thirdhand.arrays import FloatArray
from thirdhand.constraints import geometry as g


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
    d2_pos, d2_rot : ndarray, shape (n,)
        Squared norms of ``e_pos`` and ``e_rot`` (``d2_rot`` None with ``e_rot``);
        computed when not given.
    """

    __slots__ = ("d2_pos", "d2_rot", "e_pos", "e_rot", "g_pos", "g_rot", "latent")

    def __init__(
        self,
        e_pos: FloatArray,
        e_rot: FloatArray | None,
        latent: FloatArray,
        g_pos: FloatArray,
        g_rot: FloatArray,
        d2_pos: FloatArray | None = None,
        d2_rot: FloatArray | None = None,
    ) -> None:
        self.e_pos = e_pos
        self.e_rot = e_rot
        self.latent = latent
        self.g_pos = g_pos
        self.g_rot = g_rot
        self.d2_pos: FloatArray = np.einsum("ij,ij->i", e_pos, e_pos) if d2_pos is None else d2_pos
        self.d2_rot: FloatArray | None = d2_rot
        if e_rot is not None and d2_rot is None:
            self.d2_rot = np.einsum("ij,ij->i", e_rot, e_rot)


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


#: Stand-in for the quaternions of a position-only track in the compiled kernels.
_NO_QUAT = np.zeros((0, 4))


@njit(cache=True, error_model="numpy")
def _put_log(
    out: FloatArray, d2: FloatArray, i: int, x: float, y: float, z: float, w: float
) -> None:  # pragma: no cover - compiled
    """Row ``i`` of ``out`` (rotation vector of ``(x, y, z, w)``) and its squared norm."""
    k = sc.rotvec_scale(x, y, z, w)
    out[i, 0] = x * k
    out[i, 1] = y * k
    out[i, 2] = z * k
    d2[i] = out[i, 0] * out[i, 0] + out[i, 1] * out[i, 1] + out[i, 2] * out[i, 2]


@njit(cache=True, error_model="numpy")
def _offset_project(
    p: FloatArray, q: FloatArray, pos: FloatArray, qp: FloatArray, axis: FloatArray, slide: bool
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:  # pragma: no cover
    """Residuals against a constant pose (``slide``: free translation along ``axis``).

    Returns ``e_pos (n, 3)``, ``e_rot (n, 3)`` (``(0, 3)`` when ``q`` is empty),
    ``d2_pos (n,)``, ``d2_rot (n,)`` and the displacement along the axis ``(n, 1)``.
    """
    n = p.shape[0]
    m = q.shape[0]
    e_pos = np.empty((n, 3))
    d2p = np.empty(n)
    lat = np.zeros((n, 1))
    e_rot = np.empty((m, 3))
    d2r = np.empty(m)
    cx, cy, cz, cw = -qp[0], -qp[1], -qp[2], qp[3]
    for i in range(n):
        v0 = p[i, 0] - pos[0]
        v1 = p[i, 1] - pos[1]
        v2 = p[i, 2] - pos[2]
        if slide:
            t = v0 * axis[0] + v1 * axis[1] + v2 * axis[2]
            lat[i, 0] = t
            v0 = v0 - t * axis[0]
            v1 = v1 - t * axis[1]
            v2 = v2 - t * axis[2]
        e_pos[i, 0] = v0
        e_pos[i, 1] = v1
        e_pos[i, 2] = v2
        d2p[i] = v0 * v0 + v1 * v1 + v2 * v2
    for i in range(m):
        x, y, z, w = sc.qmul(q[i, 0], q[i, 1], q[i, 2], q[i, 3], cx, cy, cz, cw)
        _put_log(e_rot, d2r, i, x, y, z, w)
    return e_pos, e_rot, d2p, d2r, lat


@njit(cache=True, error_model="numpy")
def _revolute_project(
    p: FloatArray,
    q: FloatArray,
    pos: FloatArray,
    q0: FloatArray,
    a: FloatArray,
    lever: FloatArray,
    theta_ref: FloatArray,
    mask: NDArray[np.bool_],
    ratio: float,
    planar: bool,
    pitch: float,
    h0: float,
) -> tuple[
    FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray
]:  # pragma: no cover - compiled
    """Residuals against a rotation about ``a`` (see :meth:`Revolute.project`).

    ``q`` empty for a position-only track (angles from the positions, unwrapped
    over ``mask``); ``pitch`` NaN unless coupled (screw). Returns ``e_pos``,
    ``e_rot``, ``d2_pos``, ``d2_rot``, ``latent``, ``g_pos``, ``g_rot``.
    """
    n = p.shape[0]
    m = q.shape[0]
    coupled = not math.isnan(pitch)
    d = 2 if planar else 1
    la = lever[0] * a[0] + lever[1] * a[1] + lever[2] * a[2]
    lev0 = lever[0] - la * a[0]
    lev1 = lever[1] - la * a[1]
    lev2 = lever[2] - la * a[2]
    r = math.sqrt(lev0 * lev0 + lev1 * lev1 + lev2 * lev2)
    e1 = np.zeros(3)
    if r > 1e-12:
        e1[0], e1[1], e1[2] = lev0 / r, lev1 / r, lev2 / r
    e2 = sc.cross_one(a, e1)
    # Rodrigues: R(θ) u = cos θ (u - par) + sin θ (a × u) + par.
    par = np.array([la * a[0], la * a[1], la * a[2]])
    perp = np.array([lever[0] - par[0], lever[1] - par[1], lever[2] - par[2]])
    axu = sc.cross_one(a, lever)
    theta_pos = np.empty(n)
    height = np.empty(n)
    for i in range(n):
        v0 = p[i, 0] - pos[0]
        v1 = p[i, 1] - pos[1]
        v2 = p[i, 2] - pos[2]
        theta_pos[i] = math.atan2(
            v0 * e2[0] + v1 * e2[1] + v2 * e2[2], v0 * e1[0] + v1 * e1[1] + v2 * e1[2]
        )
        height[i] = v0 * a[0] + v1 * a[1] + v2 * a[2]
    lat = np.empty((n, d))
    gp = np.empty((n, d))
    gr = np.empty((n, d))
    r2 = r * r
    if m == 0:
        theta = g._unwrap_masked(theta_pos, mask)
        gr[:, 0] = 0.0
    else:
        rr = ratio * ratio
        theta = np.empty(n)
        for i in range(n):
            on_branch = theta_ref[i] + g._wrap(theta_pos[i] - theta_ref[i])
            num = rr * theta_ref[i] + r2 * on_branch
            den = rr + r2
            if coupled and abs(pitch) > 1e-12:
                num = num + pitch * (height[i] - h0)
                den = den + pitch * pitch
            theta[i] = num / den
        gr[:, 0] = 1.0
    e_pos = np.empty((n, 3))
    d2p = np.empty(n)
    half_c = np.empty(m)
    half_s = np.empty(m)
    for i in range(n):
        if m:
            # Half angles for the rotation residual; the double-angle formulas give θ's.
            ch = math.cos(0.5 * theta[i])
            sh = math.sin(0.5 * theta[i])
            half_c[i] = ch
            half_s[i] = sh
            c = ch * ch - sh * sh
            s = 2.0 * sh * ch
        else:
            c = math.cos(theta[i])
            s = math.sin(theta[i])
        shift = 0.0
        if coupled:
            shift = h0 + pitch * theta[i]
        elif planar:
            shift = height[i] - la
        dp = 0.0
        for k in range(3):
            pred = pos[k] + (c * perp[k] + s * axu[k] + par[k])
            if coupled or planar:
                pred = pred + shift * a[k]
            e = p[i, k] - pred
            e_pos[i, k] = e
            dp += e * e
        d2p[i] = dp
        lat[i, 0] = theta[i]
        gp[i, 0] = r2 + pitch * pitch if coupled else r2
        if planar:
            lat[i, 1] = height[i]
            gp[i, 1] = 1.0
            gr[i, 1] = 0.0
    e_rot = np.empty((m, 3))
    d2r = np.empty(m)
    if m:
        cx, cy, cz, cw = -q0[0], -q0[1], -q0[2], q0[3]
        for i in range(n):
            x0, x1, x2, x3 = sc.qmul(q[i, 0], q[i, 1], q[i, 2], q[i, 3], cx, cy, cz, cw)
            y0, y1, y2, y3 = sc.qmul(x0, x1, x2, x3, -a[0], -a[1], -a[2], 0.0)
            ch = half_c[i]
            sh = half_s[i]
            _put_log(
                e_rot,
                d2r,
                i,
                ch * x0 + sh * y0,
                ch * x1 + sh * y1,
                ch * x2 + sh * y2,
                ch * x3 + sh * y3,
            )
    return e_pos, e_rot, d2p, d2r, lat, gp, gr


def _projection(
    e_pos: FloatArray,
    e_rot: FloatArray,
    d2p: FloatArray,
    d2r: FloatArray,
    lat: FloatArray,
    gp: FloatArray,
    gr: FloatArray,
    oriented: bool,
) -> Projection:
    if oriented:
        return Projection(e_pos, e_rot, lat, gp, gr, d2p, d2r)
    return Projection(e_pos, None, lat, gp, gr, d2p, None)


class Kernel:
    """Base class: a model's weighted fit and projection."""

    name = ""
    n_latent = 0
    #: Number of free parameters for (position-only, oriented) tracks, for the BIC.
    n_params: tuple[int, int] = (0, 0)

    def uses_ratio(self, oriented: bool) -> bool:
        """Whether :meth:`project` depends on the noise ratio (else a projection of
        unchanged geometry can be reused)."""
        return False

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
        pos = g.col_median(p) if uniform else g.weighted_mean(p, w)
        return Geometry(pos=pos, quat=None if q is None else g.quat_average(q, w))

    def project(
        self, geom: Geometry, p: FloatArray, q: FloatArray | None, ratio: float
    ) -> Projection:
        oriented = q is not None and geom.quat is not None
        e_pos, e_rot, d2p, d2r, _ = _offset_project(
            p,
            q if oriented else _NO_QUAT,  # type: ignore[arg-type]
            geom.pos,
            geom.quat if oriented else geom.pos,  # type: ignore[arg-type]
            geom.pos,
            False,
        )
        empty = np.zeros((p.shape[0], 0))
        return _projection(e_pos, e_rot, d2p, d2r, empty, empty, empty, oriented)


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
        oriented = q is not None and geom.quat is not None
        e_pos, e_rot, d2p, d2r, lat = _offset_project(
            p,
            q if oriented else _NO_QUAT,  # type: ignore[arg-type]
            geom.pos,
            geom.quat if oriented else geom.pos,  # type: ignore[arg-type]
            geom.axis,
            True,
        )
        ones = np.ones((p.shape[0], 1))
        return _projection(e_pos, e_rot, d2p, d2r, lat, ones, np.zeros_like(ones), oriented)


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

    def uses_ratio(self, oriented: bool) -> bool:
        """The angles weigh the positions against the rotations when oriented."""
        return oriented

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

    def project(
        self, geom: Geometry, p: FloatArray, q: FloatArray | None, ratio: float
    ) -> Projection:
        assert geom.axis is not None and geom.lever is not None
        # Angles from the rotations (weighted with the positions' r·Δθ against
        # σ_pos) when oriented, else from the positions alone, unwrapped over the mask.
        oriented = q is not None and geom.theta is not None and geom.quat is not None
        n = p.shape[0]
        mask = np.ones(n, dtype=bool) if geom.mask is None else geom.mask
        pitch, h0 = math.nan, 0.0
        if self.coupled:
            pitch, h0 = geom.extra["pitch"], geom.extra["h0"]
        out = _revolute_project(
            p,
            q if oriented else _NO_QUAT,  # type: ignore[arg-type]
            geom.pos,
            geom.quat if oriented else geom.pos,  # type: ignore[arg-type]
            geom.axis,
            geom.lever,
            geom.theta if oriented else geom.pos,  # type: ignore[arg-type]
            mask,
            float(ratio),
            self.planar,
            float(pitch),
            float(h0),
        )
        return _projection(*out, oriented)


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
