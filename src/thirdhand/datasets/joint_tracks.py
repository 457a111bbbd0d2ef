"""Random relative-pose tracks of known joints, for tests and benchmarks."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.constraints import geometry as g


@dataclass(frozen=True)
class JointTrack:
    """A synthetic track and the truth it was drawn from.

    Attributes
    ----------
    type : str
    pos : ndarray, shape (n, 3)
        Child positions in the parent frame, metres (noisy, with outliers if asked).
    quat : ndarray, shape (n, 4)
        Child orientations in the parent frame, x y z w.
    axis : ndarray, shape (3,) or None
        Unit joint axis, oriented so that the motion goes the positive way.
    origin : ndarray, shape (3,)
        The point of the axis nearest the final noise-free position (the final
        position itself for fixed and free tracks).
    ranges : ndarray, shape (6, 2)
        ``[min, max]`` of tx ty tz (m) and rx ry rz (rad) from the final pose.
    outliers : ndarray of bool, shape (n,)
    """

    type: str
    pos: FloatArray
    quat: FloatArray
    axis: FloatArray | None
    origin: FloatArray
    ranges: FloatArray
    outliers: NDArray[np.bool_]


def _unit(rng: np.random.Generator) -> FloatArray:
    v = rng.standard_normal(3)
    return np.asarray(v / np.linalg.norm(v), dtype=np.float64)


def random_joint_track(
    kind: str,
    rng: np.random.Generator,
    *,
    n: int = 200,
    pos_noise: float = 0.0,
    rot_noise: float = 0.0,
    outliers: float = 0.0,
    span: float | None = None,
    stroke: float | None = None,
    drift: float = 0.0,
    rot_drift: float = 0.0,
    bias: float = 0.0,
    rot_bias: float = 0.0,
    colour: float = 0.0,
    rot_colour: float = 0.0,
    colour_width: float = 2.0,
    rail_bow: float = 0.0,
) -> JointTrack:
    """A random track of a fixed, prismatic, revolute, cylindrical, screw or free joint.

    Joint axes are uniform on the sphere; revolute radii 5–40 cm and angles
    40–150° (or ``span``); prismatic strokes 10–40 cm (or ``stroke``); the
    configuration moves monotonically (with a smooth speed profile) from its start
    to its end. A free track wanders ±15 cm and ±60° smoothly.

    Parameters
    ----------
    kind : str
    rng : numpy.random.Generator
    n : int
        Number of samples.
    pos_noise : float
        Standard deviation of the Gaussian noise of each position coordinate, metres.
    rot_noise : float
        Standard deviation of each component of a random rotation vector, radians.
    outliers : float
        Fraction of samples replaced by gross outliers (a position 10–50 cm away
        and a uniformly random orientation).
    span : float, optional
        Angle turned by a revolute, cylindrical or screw joint, radians.
    stroke : float, optional
        Displacement of a prismatic or cylindrical joint, metres.
    drift, rot_drift : float
        Standard deviation per axis of a slowly varying error added to the
        positions (metres) and orientations (radians): white noise smoothed over
        a tenth of the track. The error changes with time even where the part
        stands still (a tracker that wanders).
    bias, rot_bias : float
        Standard deviation per axis of a systematic error that depends on the
        pose (metres, radians): a smooth random field of the noise-free position
        and orientation, wavelengths 0.5-1.5 m and 0.5-1.5 rad (a camera's lens
        distortion, an AR tag's viewing angle, a gripper's kinematic
        calibration). A part that stands still sees a constant offset; a moving
        one sees its path bent by the field's change along it.
    colour, rot_colour : float
        Standard deviation per axis of a correlated (coloured) part of the noise
        (metres, radians): white noise smoothed by a Gaussian of ``colour_width``
        samples, as a tracker's filter or a tag detector's jitter makes it. A
        short-window smoother sees little of it: on the real camera tracks of
        ``../shared/data`` the 15- and 21-sample noise estimates are 1.2-2.5 times
        the 7-sample one, which a width of 2 and 2-3 times the white level give.
    rail_bow : float
        A bowed rail or a camera's calibration warp, as a fraction of the path's
        extent: every noise-free position moves, in a random direction
        perpendicular to the path's principal direction, by ``rail_bow · L ·
        (1 - u²)``, with ``L`` the extent along that direction and ``u`` in
        [-1, 1] the position along it: a parabola whose sagitta is ``rail_bow``
        of the chord. On the real prismatic tracks of ``../shared/data`` the
        quadratic part of the path bows by 0.1-3 % of the chord (median 1.2 %;
        ``research/notes/constraints.md``).
    """
    s = np.linspace(0.0, 1.0, n)
    prog = 0.5 - 0.5 * np.cos(np.pi * s)
    centre = rng.uniform(-0.3, 0.3, 3)
    q_rest = se3.random_quat(rng)
    ranges = np.zeros((6, 2))
    axis: FloatArray | None = None
    if kind in ("fixed", "free"):
        pos = np.tile(centre, (n, 1))
        quat = np.tile(q_rest, (n, 1))
        if kind == "free":
            t = np.arange(n)[:, None] / n
            f = rng.uniform(1.0, 4.0, (1, 6))
            ph = rng.uniform(0.0, 2 * np.pi, (1, 6))
            wave = np.sin(2 * np.pi * f * t + ph)
            pos = pos + 0.15 * wave[:, :3]
            rv = np.radians(60.0) * wave[:, 3:]
            quat = se3.quat_multiply(se3.quat_from_matrix(_rotvec_matrix(rv)), q_rest)
        origin = pos[-1].copy()
    else:
        axis = _unit(rng)
        theta = np.zeros(n)
        disp = np.zeros(n)
        lever = np.zeros(3)
        if kind in ("revolute", "cylindrical", "screw"):
            turn = np.radians(rng.uniform(40.0, 150.0))
            span_ = turn if span is None else float(span)
            theta = -span_ + span_ * prog
            perp = np.cross(axis, _unit(rng))
            lever = rng.uniform(0.05, 0.4) * perp / np.linalg.norm(perp)
            lever = lever + rng.uniform(-0.1, 0.1) * axis
            ranges[3] = [-span_, 0.0]
        if kind in ("prismatic", "cylindrical"):
            length = rng.uniform(0.1, 0.4)
            stroke_ = length if stroke is None else float(stroke)
            direction = 1.0 if kind == "prismatic" else rng.choice([-1.0, 1.0])
            # A cylindrical joint's slide is not tied to its turn: linear in time,
            # while the turn follows the smooth profile.
            drive = s if kind == "cylindrical" else prog
            disp = direction * (-stroke_ + stroke_ * drive)
            ranges[0] = [-stroke_, 0.0] if direction > 0 else [0.0, stroke_]
        if kind == "screw":
            # 5-30 mm per radian either way (an M6 thread is 0.16 mm/rad; a lid
            # or a coarse wooden thread is in this range).
            pitch = rng.choice([-1.0, 1.0]) * rng.uniform(0.005, 0.03)
            disp = pitch * theta
            ranges[0] = np.sort(pitch * ranges[3])
        rot = g.quat_axis_angle(axis, theta)
        pos = centre + g.rotate_about(axis, theta, lever) + disp[:, None] * axis
        quat = se3.quat_multiply(rot, q_rest)
        origin = centre + ((pos[-1] - centre) @ axis) * axis
    if bias > 0.0 or rot_bias > 0.0:
        # Drawn from a generator of its own so the other draws stay as they were.
        field = _pose_field(np.random.default_rng(rng.integers(2**63)), pos, quat, q_rest)
        pos = pos + bias * field[:, :3]
        if rot_bias > 0.0:
            quat = se3.quat_multiply(
                se3.quat_from_matrix(_rotvec_matrix(rot_bias * field[:, 3:])), quat
            )
    if rail_bow > 0.0:
        pos = pos + _rail_bow(np.random.default_rng(rng.integers(2**63)), pos, rail_bow)
    if colour > 0.0 or rot_colour > 0.0:
        sub = np.random.default_rng(rng.integers(2**63))
        pos = pos + colour * _smooth_noise(sub, n, colour_width)
        if rot_colour > 0.0:
            jitter = _rotvec_matrix(rot_colour * _smooth_noise(sub, n, colour_width))
            quat = se3.quat_multiply(se3.quat_from_matrix(jitter), quat)
    pos = pos + pos_noise * rng.standard_normal(pos.shape)
    if drift > 0.0:
        pos = pos + drift * _slow_error(rng, n)
    if rot_drift > 0.0:
        slow = se3.quat_from_matrix(_rotvec_matrix(rot_drift * _slow_error(rng, n)))
        quat = se3.quat_multiply(slow, quat)
    if rot_noise > 0.0:
        noise = se3.quat_from_matrix(_rotvec_matrix(rot_noise * rng.standard_normal((n, 3))))
        quat = se3.quat_multiply(noise, quat)
    bad = np.zeros(n, dtype=bool)
    if outliers > 0.0:
        # Keep the two ends clean so the truth's end pose and ranges stay valid.
        k = round(outliers * n)
        idx = rng.choice(np.arange(1, n - 1), size=k, replace=False)
        bad[idx] = True
        dirs = rng.standard_normal((k, 3))
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        pos[idx] += rng.uniform(0.1, 0.5, (k, 1)) * dirs
        quat[idx] = se3.random_quat(rng, k)
    quat = quat * np.where(rng.random(n) < 0.5, -1.0, 1.0)[:, None]
    return JointTrack(kind, pos, quat, axis, origin, ranges, bad)


def _rail_bow(rng: np.random.Generator, pos: FloatArray, bow: float) -> FloatArray:
    """Displacements of a parabolic bow of sagitta ``bow`` of the chord, shape (n, 3)."""
    c = pos - pos.mean(axis=0)
    _, _, vt = np.linalg.svd(c, full_matrices=False)
    along = c @ vt[0]
    extent = float(np.ptp(along))
    if extent <= 0.0:
        return np.zeros_like(pos)
    u = 2.0 * (along - along.min()) / extent - 1.0
    d = rng.standard_normal(3)
    d -= (d @ vt[0]) * vt[0]
    d /= np.linalg.norm(d)
    return np.asarray(bow * extent * (1.0 - u**2)[:, None] * d, dtype=np.float64)


def _slow_error(rng: np.random.Generator, n: int) -> FloatArray:
    """Unit-variance smooth noise, shape (n, 3): white noise under a Gaussian of n/10 samples."""
    width = max(1.0, n / 10.0)
    half = int(3 * width)
    k = np.exp(-0.5 * (np.arange(-half, half + 1) / width) ** 2)
    white = rng.standard_normal((n + 2 * half, 3))
    smooth = np.stack([np.convolve(white[:, a], k, mode="valid") for a in range(3)], axis=1)
    smooth = smooth - smooth.mean(axis=0)
    return np.asarray(smooth / smooth.std(axis=0).mean(), dtype=np.float64)


def _smooth_noise(rng: np.random.Generator, n: int, width: float) -> FloatArray:
    """Unit-variance noise correlated over ``width`` samples (Gaussian kernel), shape (n, 3)."""
    half = int(3 * width) + 1
    k = np.exp(-0.5 * (np.arange(-half, half + 1) / max(width, 1e-9)) ** 2)
    k /= math.sqrt(float(k @ k))
    white = rng.standard_normal((n + 2 * half, 3))
    return np.stack([np.convolve(white[:, a], k, mode="valid") for a in range(3)], axis=1)


def _pose_field(
    rng: np.random.Generator, pos: FloatArray, quat: FloatArray, q_rest: FloatArray
) -> FloatArray:
    """A smooth random field of the pose, unit variance per output, shape (n, 6).

    Each of the 6 outputs (3 for position, 3 for rotation) is a sum of 4 plane
    waves of the 6-D pose feature ``[position (m), rotation vector from the rest
    orientation (rad)]``, wavelengths 0.5-1.5 (m or rad), random directions and
    phases, amplitudes ``sqrt(2 / 4)``: over the whole space its variance is 1.
    """
    rv = se3.rotvec_from_quat(
        se3.quat_multiply(quat, np.tile(se3.quat_conjugate(q_rest), (pos.shape[0], 1)))
    )
    feat = np.concatenate([pos, rv], axis=1)
    waves = 4
    dirs = rng.standard_normal((6, waves, 6))
    dirs /= np.linalg.norm(dirs, axis=2, keepdims=True)
    k = 2.0 * np.pi / rng.uniform(0.5, 1.5, (6, waves, 1)) * dirs
    phase = rng.uniform(0.0, 2.0 * np.pi, (6, waves))
    arg = np.einsum("owd,nd->now", k, feat) + phase
    return np.asarray(math.sqrt(2.0 / waves) * np.sin(arg).sum(axis=2), dtype=np.float64)


def _rotvec_matrix(rv: FloatArray) -> FloatArray:
    from thirdhand import se3

    return se3.matrix_from_rotvec(rv)
