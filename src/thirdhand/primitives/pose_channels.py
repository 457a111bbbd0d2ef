"""Per-sample channels of one tracked body for the skill parser, invariant to where the task was.

A :class:`PoseTrack` is one body's trajectory: times, positions and, when known,
orientations, forces and torques, and the positions of other tracked bodies.
:func:`pose_channels` turns it into per-sample channels on a regular grid, each
unchanged by a translation of the whole scene and by a rotation about the
vertical (the frame a task was recorded in says nothing about the task):

- ``logspeed``: ``log1p(|v| / 0.02 m/s)`` of the smoothed position's velocity;
- ``logangular``: ``log1p(|ω| / 0.1 rad/s)`` of the body's angular velocity,
  smoothed as a vector before its magnitude is taken (needs orientations);
- ``height``: the position along the vertical above the recording's 10th
  percentile of it, in units of 2 cm (the work surface is the recording's own low
  level, wherever it is in the room);
- ``vertical``: the signed ``log1p(|v_z| / 0.02 m/s)`` of the vertical velocity
  (up positive): lowering and lifting differ;
- ``axial``: the signed ``log1p(|v_a| / 0.02 m/s)`` of the velocity along the track's
  principal horizontal direction of motion (:func:`principal_direction`), pointing the
  way the body first moved: a stroke and its return differ, wherever the task faced;
- ``curvature``: ``log1p`` of the path's turning rate ``|v × a| / |v|²`` in units
  of 0.5 rad/s;
- ``logdist``: ``log1p`` of the distance to the nearest other tracked body in units
  of 2 cm (needs other bodies);
- ``logforce`` / ``logtorque``: ``log1p`` of the magnitude of the force (2 N units)
  and torque (0.2 N m units) after subtracting their mean over the first
  :data:`ZERO_FT_S` seconds, the sensor's offset (needs forces).

Log channels are divided by :data:`LOG_UNIT` (a third of an e-fold): a magnitude
40 % larger moves its channel by about one unit, as 2 cm moves ``height``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import uniform_filter1d

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.demonstration import MAX_PLAUSIBLE_POSITION_M, MAX_QUAT_NORM_ERROR
from thirdhand.primitives.checks import PrimitiveError

#: Unit of the log-magnitude channels (dimensionless): a third of an e-fold.
LOG_UNIT = 1.0 / 3.0
#: Units of the magnitudes inside the log channels, and of ``height``.
UNITS = {
    "speed": 0.02,
    "angular": 0.1,
    "height": 0.02,
    "curvature": 0.5,
    "dist": 0.02,
    "force": 2.0,
    "torque": 0.2,
}
#: Every channel :func:`pose_channels` can compute.
CHANNELS = (
    "logspeed",
    "logangular",
    "height",
    "vertical",
    "axial",
    "curvature",
    "logdist",
    "logforce",
    "logtorque",
)
#: Seconds at the start of a track whose mean force and torque are the sensor's zero.
ZERO_FT_S = 0.5
#: Fewest samples of a track (and of its grid): a speed needs neighbours, a skill a run.
MIN_SAMPLES = 5


@dataclass(frozen=True)
class PoseTrack:
    """One tracked body: poses over time, and forces, torques, other bodies when known.

    Attributes
    ----------
    t : ndarray, shape (n,)
        Seconds, strictly increasing.
    pos : ndarray, shape (n, 3)
        Position, metres, world frame whose third axis is vertical (up).
    quat : ndarray, shape (n, 4) or None
        Orientation, unit quaternion x y z w, world frame.
    force, torque : ndarray, shape (n, 3) or None
        Newtons and newton metres, any frame (only magnitudes are used).
    others : tuple of ndarray, shape (n, 3)
        Positions of other tracked bodies (NaN where not tracked), metres.
    name : str
        Where the track came from, for messages.
    """

    t: FloatArray
    pos: FloatArray
    quat: FloatArray | None = None
    force: FloatArray | None = None
    torque: FloatArray | None = None
    others: tuple[FloatArray, ...] = field(default_factory=tuple)
    name: str = "track"

    def __post_init__(self) -> None:
        t = np.asarray(self.t, dtype=np.float64)
        n = t.size
        if t.ndim != 1 or n < MIN_SAMPLES:
            raise PrimitiveError(
                f"{self.name}: {n} samples; a track needs at least {MIN_SAMPLES} to be parsed"
            )
        if not np.isfinite(t).all() or np.any(np.diff(t) <= 0):
            bad = int(np.flatnonzero(~np.isfinite(t) | np.r_[False, np.diff(t) <= 0])[0])
            raise PrimitiveError(
                f"{self.name}: time must be finite and strictly increasing (sample {bad})"
            )
        object.__setattr__(self, "t", t)
        for key, width in (("pos", 3), ("quat", 4), ("force", 3), ("torque", 3)):
            v = getattr(self, key)
            if v is None:
                continue
            a = np.asarray(v, dtype=np.float64)
            if a.shape != (n, width):
                raise PrimitiveError(
                    f"{self.name}: {key} must have shape ({n}, {width}), got {a.shape}"
                )
            rows = np.flatnonzero(~np.isfinite(a).all(axis=1))
            if rows.size:
                raise PrimitiveError(
                    f"{self.name}: {rows.size} samples of {key} are NaN or infinite "
                    f"(first: sample {int(rows[0])}); remove or interpolate them"
                )
            object.__setattr__(self, key, a)
        far = np.flatnonzero((np.abs(self.pos) > MAX_PLAUSIBLE_POSITION_M).any(axis=1))
        if far.size:
            k = int(far[0])
            raise PrimitiveError(
                f"{self.name}: sample {k}: position {np.abs(self.pos[k]).max():.6g} m from the "
                f"origin is beyond {MAX_PLAUSIBLE_POSITION_M:g} m; are these millimetres?"
            )
        if self.quat is not None:
            norm = np.linalg.norm(self.quat, axis=1)
            if np.any(np.abs(norm - 1.0) > MAX_QUAT_NORM_ERROR):
                k = int(np.argmax(np.abs(norm - 1.0)))
                raise PrimitiveError(
                    f"{self.name}: sample {k}: expected a unit quaternion, norm {norm[k]:.4g}"
                )
        others = tuple(np.asarray(o, dtype=np.float64) for o in self.others)
        for o in others:
            if o.shape != (n, 3):
                raise PrimitiveError(
                    f"{self.name}: another body's positions must be ({n}, 3), got {o.shape}"
                )
        object.__setattr__(self, "others", others)
        still = np.ptp(self.pos, axis=0).max() < 1e-9 and (
            self.quat is None or np.ptp(self.quat, axis=0).max() < 1e-9
        )
        if still:
            raise PrimitiveError(
                f"{self.name}: the poses never change over {n} samples: nothing to segment"
            )

    @property
    def n_samples(self) -> int:
        """Number of samples ``n``."""
        return int(self.t.size)

    def moved(self, rotation: Sequence[float], translation: Sequence[float]) -> PoseTrack:
        """The same track after a rigid motion ``x ↦ R x + p`` of the whole scene.

        ``rotation`` is ``R`` as a unit quaternion (4,) x y z w; ``translation`` is
        ``p`` (3,), metres.
        """
        r = se3.check_quat(rotation)
        p = np.asarray(translation, dtype=np.float64)
        quat = None if self.quat is None else se3.quat_multiply(r, se3.check_quat(self.quat))
        return PoseTrack(
            self.t,
            se3.quat_rotate(r, self.pos) + p,
            quat,
            self.force,
            self.torque,
            tuple(se3.quat_rotate(r, o) + p for o in self.others),
            self.name,
        )


#: Largest ratio of two tracks' spatial extents in one set: demonstrations of one
#: skill differ in size by far less; a thousand is millimetres beside metres.
MAX_EXTENT_RATIO = 100.0
#: Tracks that move less than this (in any unit) are not compared.
MIN_EXTENT = 1e-3


def extent(track: PoseTrack) -> float:
    """The diagonal of the track's bounding box, metres."""
    return float(np.linalg.norm(track.pos.max(axis=0) - track.pos.min(axis=0)))


def check_track_set(tracks: Sequence[PoseTrack]) -> None:
    """Tracks a user gives to learn from together: in one unit, no track given twice.

    (Tracks thirdhand cuts from a demonstration itself are in metres by construction
    and may move very differently; they are not held to the extent ratio.)

    Raises
    ------
    PrimitiveError
        Two tracks with the same samples (the same file twice), or two whose
        extents differ by more than :data:`MAX_EXTENT_RATIO` (one in millimetres).
    """
    seen: dict[bytes, int] = {}
    for i, tr in enumerate(tracks):
        key = np.ascontiguousarray(np.column_stack([tr.t, tr.pos])).tobytes()
        if key in seen:
            first = tracks[seen[key]]
            raise PrimitiveError(
                f"{tr.name}: the same samples as {first.name} (track {seen[key] + 1}); "
                "give each demonstration once"
            )
        seen[key] = i
    sizes = [(extent(tr), tr) for tr in tracks]
    moving = [(e, tr) for e, tr in sizes if e > MIN_EXTENT]
    if len(moving) > 1:
        small, big = min(moving, key=lambda m: m[0]), max(moving, key=lambda m: m[0])
        if big[0] > MAX_EXTENT_RATIO * small[0]:
            raise PrimitiveError(
                f"{big[1].name} spans {big[0]:.4g} m, {big[0] / small[0]:.0f} times "
                f"{small[1].name} ({small[0]:.4g} m): give every track in metres"
            )


def default_channels(track: PoseTrack) -> tuple[str, ...]:
    """The channels the parser uses for a track: pose ones, forces when present.

    Speed, angular rate (with orientations), height, signed vertical and axial speeds,
    distance to the nearest other body (with other bodies), force and torque
    magnitudes (with forces).
    """
    names = ["logspeed"]
    if track.quat is not None:
        names.append("logangular")
    names += ["height", "vertical", "axial"]
    if track.others:
        names.append("logdist")
    if track.force is not None:
        names.append("logforce")
    if track.torque is not None:
        names.append("logtorque")
    return tuple(names)


#: The body's first move along its principal direction, which fixes that direction's sense,
#: metres (or a quarter of the track's extent along it, if that is less).
FIRST_MOVE_M = 0.05


def principal_direction(pos: FloatArray, vel: FloatArray) -> FloatArray:
    """Unit horizontal direction (3,) along which a track moves most, pointing its first way.

    The principal axis of the horizontal velocities (the eigenvector of their
    second-moment matrix with the largest eigenvalue), turned to point the way the
    body first went along it: the sign of its displacement from the start along the
    axis when that first reaches :data:`FIRST_MOVE_M` (or a quarter of the track's
    extent along the axis, if that is less). The same task recorded facing elsewhere
    in the room gives the same direction relative to the motion. (Until 2026-12-04 the
    sign came from the first displacement of 5 cm in any horizontal direction, or the
    farthest point: on a 4.5-cm handwritten LASA angle that point lay across the axis,
    and the sense flipped between demonstrations by millimetres.)

    Parameters
    ----------
    pos, vel : ndarray, shape (n, 3)
        Positions (metres) and velocities (m/s), world frame, third axis vertical.
    """
    h = vel[:, :2]
    _, vec = np.linalg.eigh(h.T @ h)
    u = vec[:, -1]
    along = (pos[:, :2] - pos[0, :2]) @ u
    reach = min(FIRST_MOVE_M, 0.25 * float(np.ptp(along)))
    # the first sample that far along it (there is one: some |along| is at least ptp / 2)
    k = int(np.argmax(np.abs(along) >= reach))
    if along[k] < 0.0:
        u = -u
    return np.array([u[0], u[1], 0.0])


def _smooth(x: FloatArray, window: int) -> FloatArray:
    out = uniform_filter1d(x, size=max(window, 1), axis=0, mode="nearest")
    return np.asarray(out, dtype=np.float64)


def _log(x: FloatArray, unit: float) -> FloatArray:
    return np.asarray(np.log1p(np.maximum(x, 0.0) / unit) / LOG_UNIT, dtype=np.float64)


def accumulated_rotation(quat: FloatArray) -> FloatArray:
    """Sum of the sample-to-sample rotation vectors, shape (n, 3), radians, the quaternions' frame.

    A body turned four times by 100° about one axis reads 7 rad along it, where a
    log map would wrap at π; its time derivative is the angular velocity.

    Parameters
    ----------
    quat : ndarray, shape (n, 4), x y z w
        Orientation of a body in some frame (sign-continuous or not).
    """
    q = np.asarray(quat, dtype=np.float64)
    step = se3.rotvec_from_quat(se3.quat_multiply(q[1:], se3.quat_conjugate(q[:-1])))
    return np.vstack([np.zeros((1, 3)), np.cumsum(step, axis=0)])


def _angular_rate(t: FloatArray, quat: FloatArray, window: int) -> FloatArray:
    """Magnitude of the smoothed angular velocity, rad/s, shape (n,): the same in any world frame.

    The accumulated rotation is smoothed over ``window`` samples before it is
    differentiated, as positions are before their speed: tracker noise on the
    orientations averages out instead of adding to the magnitude.
    """
    rot = _smooth(accumulated_rotation(se3.check_quat(quat)), window)
    return np.asarray(np.linalg.norm(np.gradient(rot, t, axis=0), axis=1), dtype=np.float64)


def _nearest(pos: FloatArray, others: Sequence[FloatArray]) -> FloatArray:
    d = np.stack([np.linalg.norm(o - pos, axis=1) for o in others], axis=1)
    d = np.where(np.isfinite(d), d, np.inf).min(axis=1)
    ok = np.isfinite(d)
    if not ok.any():
        return np.zeros(pos.shape[0])
    idx = np.arange(d.size)
    return np.asarray(np.interp(idx, idx[ok], d[ok]), dtype=np.float64)


def grid_times(t: FloatArray, rate_hz: float) -> FloatArray:
    """Regular times from ``t[0]`` to at most ``t[-1]`` at ``rate_hz``, seconds."""
    n = int(np.floor((t[-1] - t[0]) * rate_hz + 1e-9)) + 1
    return np.asarray(np.linspace(t[0], t[0] + (n - 1) / rate_hz, n), dtype=np.float64)


def pose_channels(
    track: PoseTrack,
    names: Sequence[str],
    *,
    rate_hz: float = 20.0,
    window: int = 5,
) -> tuple[FloatArray, FloatArray]:
    """The named channels of a track on a regular grid.

    Parameters
    ----------
    track : PoseTrack
    names : sequence of str
        Channels (:data:`CHANNELS`).
    rate_hz : float
        Grid rate, Hz.
    window : int
        Smoothing, grid samples (applied at the track's own rate, over the same span).

    Returns
    -------
    t : ndarray, shape (m,)
        Grid times, seconds.
    x : ndarray, shape (m, len(names))
        Channel values (dimensionless, see the module docstring).
    """
    t = track.t
    if (t[-1] - t[0]) * rate_hz + 1 < MIN_SAMPLES:
        raise PrimitiveError(
            f"{track.name}: {t[-1] - t[0]:.3g} s long; the parser needs at least "
            f"{(MIN_SAMPLES - 1) / rate_hz:.3g} s ({MIN_SAMPLES} samples at {rate_hz:g} Hz)"
        )
    step = max(round(1.0 / (rate_hz * float(np.median(np.diff(t))))), 1)
    w = window * step
    pos = _smooth(track.pos, w)
    vel = np.gradient(pos, t, axis=0)
    speed = np.linalg.norm(vel, axis=1)
    cols = []
    for name in names:
        if name == "logspeed":
            col = _log(speed, UNITS["speed"])
        elif name == "logangular":
            if track.quat is None:
                raise PrimitiveError(f"{track.name}: channel 'logangular' needs orientations")
            col = _log(_angular_rate(t, track.quat, w), UNITS["angular"])
        elif name == "height":
            z = pos[:, 2]
            col = (z - np.percentile(z, 10)) / UNITS["height"]
        elif name == "vertical":
            col = np.sign(vel[:, 2]) * _log(np.abs(vel[:, 2]), UNITS["speed"])
        elif name == "axial":
            va = vel @ principal_direction(pos, vel)
            col = np.sign(va) * _log(np.abs(va), UNITS["speed"])
        elif name == "curvature":
            acc = np.gradient(vel, t, axis=0)
            turn = np.linalg.norm(np.cross(vel, acc), axis=1) / np.maximum(speed, 1e-3) ** 2
            col = _log(_smooth(turn, w), UNITS["curvature"])
        elif name == "logdist":
            if not track.others:
                raise PrimitiveError(f"{track.name}: channel 'logdist' needs other tracked bodies")
            col = _log(_smooth(_nearest(track.pos, track.others), w), UNITS["dist"])
        elif name in ("logforce", "logtorque"):
            key = name[3:]
            v = getattr(track, key)
            if v is None:
                raise PrimitiveError(f"{track.name}: channel {name!r} needs {key} samples")
            n0 = max(int(np.searchsorted(t, t[0] + ZERO_FT_S)), 1)
            mag = np.linalg.norm(v - v[:n0].mean(axis=0), axis=1)
            col = _log(_smooth(mag, w), UNITS[key])
        else:
            raise PrimitiveError(
                f"unknown channel {name!r}; expected some of {', '.join(CHANNELS)}"
            )
        cols.append(col)
    tg = grid_times(t, rate_hz)
    x = np.stack([np.interp(tg, t, c) for c in cols], axis=1)
    return tg, np.asarray(x, dtype=np.float64)
