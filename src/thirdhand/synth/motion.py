"""Motion building blocks: minimum-jerk timing, pose paths, screw motions, tremor.

Every motion is a small object with ``__call__(t) -> (pos, quat)`` that evaluates
a pose at an array of times, vectorised. A motion is either absolute (world
frame) or relative to a parent body; :mod:`thirdhand.synth.engine` composes them.
Outside its own ``[t0, t1]`` a motion holds its end poses (the phase is clipped),
so a body keeps still after its last motion ends.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from thirdhand import se3
from thirdhand.arrays import FloatArray


def min_jerk(tau: ArrayLike) -> FloatArray:
    """Minimum-jerk phase ``10τ³ − 15τ⁴ + 6τ⁵`` of a normalised time, clipped to [0, 1].

    Zero velocity and acceleration at both ends; its derivative is a bell-shaped
    speed profile with a single peak at ``τ = 0.5``.
    """
    x = np.clip(np.asarray(tau, dtype=np.float64), 0.0, 1.0)
    return x * x * x * (10.0 - 15.0 * x + 6.0 * x * x)


def phase(t: FloatArray, t0: float, t1: float) -> FloatArray:
    """Normalised time ``(t − t0) / (t1 − t0)`` clipped to [0, 1], shape of ``t``."""
    return np.clip((t - t0) / max(t1 - t0, 1e-12), 0.0, 1.0)


# One rotation algebra for the whole package (thirdhand.se3); these names stay for the scenes.
quat_exp = se3.quat_from_rotvec
quat_log = se3.rotvec_from_quat


def axis_angle_quat(axis: ArrayLike, angle: float) -> FloatArray:
    """Quaternion (4,) x y z w of a rotation by ``angle`` radians about ``axis``."""
    a = np.asarray(axis, dtype=np.float64)
    return quat_exp(a / np.linalg.norm(a) * angle)


@dataclass(frozen=True)
class Tremor:
    """Band-limited hand tremor and drift: a sum of sinusoids per axis.

    Attributes
    ----------
    freqs : ndarray, shape (k,), Hz
    amps : ndarray, shape (k, 3), metres
    phases : ndarray, shape (k, 3), radians
    """

    freqs: FloatArray
    amps: FloatArray
    phases: FloatArray

    @classmethod
    def random(
        cls, rng: np.random.Generator, *, amplitude: float = 3e-4, drift: float = 1.5e-3
    ) -> Tremor:
        """Physiological tremor (6–11 Hz, ``amplitude`` m) plus slow drift (0.1–0.5 Hz)."""
        freqs = np.concatenate([rng.uniform(6.0, 11.0, 3), rng.uniform(0.1, 0.5, 2)])
        scale = np.array([amplitude] * 3 + [drift] * 2)[:, None]
        amps = scale * rng.uniform(0.5, 1.0, (5, 3)) / np.sqrt(2.0)
        return cls(freqs, amps, rng.uniform(0.0, 2.0 * np.pi, (5, 3)))

    def __call__(self, t: FloatArray) -> FloatArray:
        """Displacement, shape (n, 3), metres, at times ``t`` (n,) seconds."""
        arg = 2.0 * np.pi * t[:, None, None] * self.freqs[None, :, None] + self.phases[None]
        return np.einsum("nkd,kd->nd", np.sin(arg), self.amps)


@dataclass(frozen=True)
class Hold:
    """A constant pose (absolute or relative to the parent)."""

    pos: FloatArray
    quat: FloatArray

    def __call__(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        n = t.shape[0]
        return np.broadcast_to(self.pos, (n, 3)).copy(), np.broadcast_to(self.quat, (n, 4)).copy()


@dataclass(frozen=True)
class PosePath:
    """Minimum-jerk pose path from ``(p0, q0)`` over ``[t0, t1]``.

    ``p(s) = p0 + s dp + 4 s (1 − s) bump``, ``q(s) = q0 ⊗ exp(s rotvec)`` with
    ``s`` the minimum-jerk phase: straight or arced translation, rotation at constant
    axis (slerp when ``rotvec = log(q0⁻¹ q1)``). An optional tremor, faded in and out
    by ``sin²(πτ)``, is added to the position so both end poses stay exact.

    Attributes
    ----------
    t0, t1 : float, seconds
    p0 : ndarray, shape (3,), metres
    q0 : ndarray, shape (4,), x y z w
    dp : ndarray, shape (3,), metres
    rotvec : ndarray, shape (3,), radians, in the frame of ``q0``
    bump : ndarray, shape (3,), metres, peak arc offset at mid-path
    tremor : Tremor or None
    turn : Tremor or None
        Rotation vector (radians, body frame) faded in and out like the tremor: an
        idle hand's own small rotation.
    """

    t0: float
    t1: float
    p0: FloatArray
    q0: FloatArray
    dp: FloatArray
    rotvec: FloatArray
    bump: FloatArray
    tremor: Tremor | None = None
    turn: Tremor | None = None

    @classmethod
    def between(
        cls,
        t0: float,
        t1: float,
        start: tuple[FloatArray, FloatArray],
        end: tuple[FloatArray, FloatArray],
        *,
        bump: ArrayLike = (0.0, 0.0, 0.0),
        tremor: Tremor | None = None,
        turn: Tremor | None = None,
    ) -> PosePath:
        """Shortest-rotation path from pose ``start`` to pose ``end``."""
        p0, q0 = (np.asarray(a, dtype=np.float64) for a in start)
        p1, q1 = (np.asarray(a, dtype=np.float64) for a in end)
        rv = quat_log(se3.quat_multiply(se3.quat_conjugate(q0), q1))
        bump_a = np.asarray(bump, dtype=np.float64)
        return cls(t0, t1, p0, q0, p1 - p0, rv, bump_a, tremor, turn)

    def end(self) -> tuple[FloatArray, FloatArray]:
        """Pose at ``t1``: position (3,), quaternion (4,)."""
        return self.p0 + self.dp, se3.quat_multiply(self.q0, quat_exp(self.rotvec))

    def __call__(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        tau = phase(t, self.t0, self.t1)
        s = min_jerk(tau)[:, None]
        p = self.p0 + s * self.dp + (4.0 * s * (1.0 - s)) * self.bump
        env = np.sin(np.pi * tau)[:, None] ** 2
        if self.tremor is not None:
            p = p + env * self.tremor(t)
        q = se3.quat_multiply(self.q0, quat_exp(s * self.rotvec))
        if self.turn is not None:
            q = se3.quat_multiply(q, quat_exp(env * self.turn(t)))
        return p, q


@dataclass(frozen=True)
class ScrewPath:
    """Screw motion of a child in its parent: spin about and slide along one body axis.

    ``q(s) = q_ref ⊗ exp(axis (θ0 + s dθ))`` and
    ``p(s) = p_ref + R(q_ref) axis (d0 + s dd)`` with ``s`` the minimum-jerk phase.
    ``dd = 0`` is a pure revolute turn, ``dθ = 0`` a pure prismatic slide.

    Attributes
    ----------
    t0, t1 : float, seconds
    p_ref : ndarray, shape (3,), metres, parent frame (the joint's reference pose)
    q_ref : ndarray, shape (4,), x y z w, parent frame
    axis : ndarray, shape (3,), unit, child frame
    theta0, dtheta : float, radians
    d0, dd : float, metres
    """

    t0: float
    t1: float
    p_ref: FloatArray
    q_ref: FloatArray
    axis: FloatArray
    theta0: float
    dtheta: float
    d0: float
    dd: float

    def at(self, s: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Relative pose at phases ``s`` (n,): positions (n, 3), quaternions (n, 4)."""
        theta = (self.theta0 + s * self.dtheta)[:, None]
        d = (self.d0 + s * self.dd)[:, None]
        direction = se3.quat_rotate(self.q_ref, self.axis)
        return self.p_ref + d * direction, se3.quat_multiply(
            self.q_ref, quat_exp(theta * self.axis)
        )

    def end(self) -> tuple[FloatArray, FloatArray]:
        """Relative pose at ``t1``: position (3,), quaternion (4,)."""
        p, q = self.at(np.ones(1))
        return p[0], q[0]

    def __call__(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        return self.at(min_jerk(phase(t, self.t0, self.t1)))


@dataclass(frozen=True)
class Sway:
    """Slow head motion: a base pose plus smooth sinusoidal drift in position and yaw/pitch."""

    pos: FloatArray
    quat: FloatArray
    tremor: Tremor
    angle_amp: float

    def __call__(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        d = self.tremor(t)
        p = self.pos + d
        rv = np.stack([np.zeros_like(t), d[:, 0], d[:, 1]], axis=1)
        rv *= self.angle_amp / max(float(np.abs(self.tremor.amps).sum()), 1e-12)
        return p, se3.quat_multiply(self.quat, quat_exp(rv))


@dataclass(frozen=True)
class Push:
    """One push or twist of a held body (a screwing stroke of the other hand).

    Attributes
    ----------
    t0, t1 : float, seconds
    dp : ndarray, shape (3,), metres, world frame; peak displacement
    rotvec : ndarray, shape (3,), radians, world frame; peak rotation about the pivot
    """

    t0: float
    t1: float
    dp: FloatArray
    rotvec: FloatArray

    def envelope(self, t: FloatArray) -> FloatArray:
        """``sin²(π τ)`` over the push, zero outside it; shape of ``t``."""
        inside = (t > self.t0) & (t < self.t1)
        return np.where(inside, np.sin(np.pi * phase(t, self.t0, self.t1)) ** 2, 0.0)


@dataclass(frozen=True)
class Wobble:
    """A held body at rest in the world, following the holding hand's small motion.

    The body's pose is its resting pose ``(pos, quat)`` moved by a rigid
    displacement about ``pivot`` (the grasp point): ``p = c + R (pos − c) + d``,
    ``q = R quat`` with ``d = g (Σ sinusoids) + Σ pushes``, ``R = exp(rv)``. ``g``
    ramps in by minimum jerk over ``ramp`` seconds from ``t_start``, so the pose is
    continuous where the wobble starts (whatever held the body before).
    ``pushes`` is filled while the scene is scripted (in time order: each push
    only changes the pose inside its own interval).

    Attributes
    ----------
    pos : ndarray, shape (3,), metres, world
    quat : ndarray, shape (4,), x y z w, world
    pivot : ndarray, shape (3,), metres, world
    shift : Tremor
        Displacement, metres.
    turn : Tremor
        Rotation vector, radians (read through :class:`Tremor`'s sum of sinusoids).
    t_start, ramp : float, seconds
    pushes : list of Push
    """

    pos: FloatArray
    quat: FloatArray
    pivot: FloatArray
    shift: Tremor
    turn: Tremor
    t_start: float
    ramp: float = 0.4
    pushes: list[Push] = dataclasses.field(default_factory=list)

    def offset(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Displacement (n, 3) metres and rotation vector (n, 3) radians, world frame."""
        g = min_jerk(phase(t, self.t_start, self.t_start + self.ramp))[:, None]
        d = g * self.shift(t)
        rv = g * self.turn(t)
        for push in self.pushes:
            e = push.envelope(t)[:, None]
            d = d + e * push.dp
            rv = rv + e * push.rotvec
        return d, rv

    def __call__(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        d, rv = self.offset(t)
        r = quat_exp(rv)
        p = self.pivot + se3.quat_rotate(r, self.pos - self.pivot) + d
        return p, se3.quat_multiply(r, np.broadcast_to(self.quat, r.shape))


@dataclasses.dataclass
class Flex:
    """A fingertip on a held object that is not perfectly rigid: a grasp that flexes.

    Real fingertip sensors sit on the nails; while a hand moves an object the
    fingers press, roll and slide on it by a millimetre or two (on the real
    ``toolbox_coop_4`` the left fingers move by ~2 mm in the board's frame while
    they carry it). The pose is the grasp pose ``(pos, quat)`` in the object's
    frame plus ``shift(t)``, faded in over ``ramp`` seconds from ``t_start`` and
    out over the ``ramp`` seconds before ``t_end`` (set when the hand lets go),
    so the finger's path stays continuous at the grasp and at the release.

    Attributes
    ----------
    pos : ndarray, shape (3,), metres, object frame
    quat : ndarray, shape (4,), x y z w, object frame
    shift : Tremor
        Displacement, metres, object frame.
    t_start : float, seconds
    t_end : float, seconds (infinite until the release)
    ramp : float, seconds
    """

    pos: FloatArray
    quat: FloatArray
    shift: Tremor
    t_start: float
    t_end: float = float("inf")
    ramp: float = 0.3

    def __call__(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        g = min_jerk(phase(t, self.t_start, self.t_start + self.ramp))
        if np.isfinite(self.t_end):
            g = g * (1.0 - min_jerk(phase(t, self.t_end - self.ramp, self.t_end)))
        p = self.pos + g[:, None] * self.shift(t)
        return p, np.broadcast_to(self.quat, (t.shape[0], 4)).copy()


def hold_motion(
    rng: np.random.Generator, *, amplitude: float = 2.5e-3, angle: float = np.deg2rad(1.5)
) -> tuple[Tremor, Tremor]:
    """Random low-frequency motion of a holding hand: (shift in m, turn in rad).

    Three sinusoids per axis between 0.3 and 3 Hz; ``amplitude`` and ``angle`` are
    the typical peak per axis.
    """
    freqs = np.array([rng.uniform(0.3, 0.8), rng.uniform(0.8, 1.6), rng.uniform(1.6, 3.0)])
    weights = np.array([0.6, 0.6, 0.4])[:, None]
    shift = Tremor(freqs, amplitude * weights * rng.uniform(0.6, 1.0, (3, 3)),
                   rng.uniform(0.0, 2.0 * np.pi, (3, 3)))  # fmt: skip
    turn = Tremor(freqs[::-1].copy(), angle * weights * rng.uniform(0.6, 1.0, (3, 3)),
                  rng.uniform(0.0, 2.0 * np.pi, (3, 3)))  # fmt: skip
    return shift, turn
