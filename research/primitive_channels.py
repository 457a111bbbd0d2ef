"""Channels of a labelled recording for the primitive-library parser: shape and levels.

Two kinds of input per arm, chosen by name:

- **shape** channels, modelled by each skill's ProMP after the segment is
  translated to start at zero: ``pos`` (metres), ``rot`` (orientation as the
  log map ``log(R_0ᵀ R_t)`` relative to the recording's first sample, radians),
  ``force`` (N), ``torque`` (N m);
- **level** channels, modelled per sample by each skill's Gaussian (absolute
  values, not translated), smoothed over ``window`` samples. Per arm:

  - ``force`` and ``torque`` (magnitudes, N and N m), ``speed`` (m/s),
    ``angular`` (rad/s);
  - ``velocity`` (the three signed components, m/s, base frame: a move down and
    a move up differ sample by sample);
  - ``forcevec`` and ``torquevec`` (the three signed components, N and N m, in
    the frame the file reports them in — read as the force/torque sensor's, which
    moves with the end effector, from how gravity shows off contact; the files do
    not say: pressing and pulling differ);
  - ``bodyangular`` (the angular velocity about the arm's own end-effector axes,
    ``log(R_tᵀ R_{t+1}) / dt``, 3 columns, rad/s: a turn of the held object
    about its own axis reads the same wherever it is held);
  - ``logforce``, ``logtorque``, ``logspeed``, ``logangular`` (``log1p`` of the
    magnitude in its linear channel's unit, dimensionless, in units of
    :data:`LOG_UNIT`: a ratio, not a difference, tells two magnitudes apart).

  And once per recording from its first two arms, the first holding the tool
  and the second the object (``arms`` gives the order):

  - ``relpos`` (tool position minus holder position, 3 columns, m, base frame);
  - ``objpos`` (the same vector in the holding arm's end-effector frame,
    ``R_holderᵀ (p_tool − p_holder)``, m: where the tool is on the object,
    unchanged by a rigid motion of the whole scene);
  - ``objvel`` (the time derivative of ``objpos``, m/s, holding arm's frame:
    the tool's velocity as seen from the object, which also moves when the
    object turns under a still tool);
  - ``holdangular`` (``bodyangular`` of the holding arm alone, 3 columns, rad/s,
    its own axes: the object turned about its own axis);
  - ``objcyl`` (``objpos`` in cylindrical coordinates about the holding arm's
    z axis, the flange axis its wrist turns the object about: the distance from
    that axis and the position along it, 2 columns, m: unchanged by a turn of
    the object about the flange axis as well) and ``objcylvel`` (their time
    derivatives, m/s: moving away from the axis against moving along it).

``zero_ft`` subtracts each arm's mean force and torque over the first
:data:`ZERO_FT_S` seconds from its force and torque: a force/torque sensor has
an offset of its own in every recording (on the peeling streams the peeling
arm's force reads 1.1 N in one and 2.8 N in the other while it returns to a
stroke, touching nothing), and the robot holds still before the demonstration
starts.

Each channel is divided by a fixed unit (:data:`SHAPE_UNITS`, :data:`LEVEL_UNITS`)
so that a centimetre, a tenth of a radian and a newton weigh about the same in
the skills' shared observation noise.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.ndimage import uniform_filter1d
from scipy.spatial.transform import Rotation

from thirdhand.arrays import FloatArray
from thirdhand.io.figueroa import ArmTrack, LabelledStream
from thirdhand.primitives.checks import PrimitiveError

#: Unit of each shape channel (its values are divided by it).
SHAPE_UNITS = {"pos": 0.02, "rot": 0.1, "force": 2.0, "torque": 0.2}
#: Unit of the log-magnitude level channels (``log1p`` of a magnitude in its channel's
#: unit, dimensionless): a third of an e-fold, so that a magnitude 40 % larger moves the
#: channel by about one unit, as a unit step does on a linear channel.
LOG_UNIT = 1.0 / 3.0
#: Unit of each level channel.
LEVEL_UNITS = {
    "force": 2.0,
    "torque": 0.2,
    "speed": 0.02,
    "angular": 0.1,
    "velocity": 0.02,
    "forcevec": 2.0,
    "torquevec": 0.2,
    "bodyangular": 0.1,
    "logforce": LOG_UNIT,
    "logtorque": LOG_UNIT,
    "logspeed": LOG_UNIT,
    "logangular": LOG_UNIT,
    "relpos": 0.02,
    "objpos": 0.02,
    "objvel": 0.02,
    "holdangular": 0.1,
    "objcyl": 0.02,
    "objcylvel": 0.02,
}
#: Level channels computed once per recording from two arms, not per arm.
PAIR_LEVELS = ("relpos", "objpos", "objvel", "holdangular", "objcyl", "objcylvel")
#: Seconds at the start of a recording whose mean force and torque are the sensor's zero.
ZERO_FT_S = 0.5


def _check(names: Sequence[str], allowed: dict[str, float], what: str) -> None:
    for n in names:
        if n not in allowed:
            raise PrimitiveError(
                f"unknown {what} channel {n!r}; expected some of {', '.join(allowed)}"
            )


def _shape(arm: ArmTrack, name: str) -> FloatArray:
    if name == "pos":
        return arm.pos
    if name == "rot":
        r = Rotation.from_quat(arm.quat)
        return np.asarray((r[0].inv() * r).as_rotvec(), dtype=np.float64)
    if name == "force":
        return arm.force
    return arm.torque


def _magnitude(arm: ArmTrack, name: str, dt: float) -> FloatArray:
    if name == "force":
        return np.asarray(np.linalg.norm(arm.force, axis=1), dtype=np.float64)
    if name == "torque":
        return np.asarray(np.linalg.norm(arm.torque, axis=1), dtype=np.float64)
    if name == "speed":
        return np.asarray(np.linalg.norm(np.gradient(arm.pos, dt, axis=0), axis=1))
    r = Rotation.from_quat(arm.quat)
    step = (r[1:] * r[:-1].inv()).magnitude() / dt
    return np.concatenate([step[:1], step])


def _body_angular(quat: FloatArray, dt: float) -> FloatArray:
    # R_t^T R_{t+1}: the turn of one sample about the arm's own axes at time t
    r = Rotation.from_quat(quat)
    w = (r[:-1].inv() * r[1:]).as_rotvec() / dt
    return np.asarray(np.vstack([w[:1], w]), dtype=np.float64)


def _smooth(x: FloatArray, window: int) -> FloatArray:
    out = uniform_filter1d(x, size=max(window, 1), axis=0, mode="nearest")
    return np.asarray(out, dtype=np.float64).reshape(x.shape[0], -1)


def _level(arm: ArmTrack, name: str, dt: float, window: int) -> FloatArray:
    if name == "velocity":
        return _smooth(np.gradient(arm.pos, dt, axis=0), window)
    if name == "forcevec":
        return _smooth(arm.force, window)
    if name == "torquevec":
        return _smooth(arm.torque, window)
    if name == "bodyangular":
        return _smooth(_body_angular(arm.quat, dt), window)
    if name.startswith("log"):
        lin = name[3:]
        return np.log1p(_smooth(_magnitude(arm, lin, dt), window) / LEVEL_UNITS[lin])
    return _smooth(_magnitude(arm, name, dt), window)


def object_frame_position(tool: ArmTrack, holder: ArmTrack) -> FloatArray:
    """The tool's position relative to the held object, in the holding arm's frame.

    Parameters
    ----------
    tool, holder : ArmTrack
        The arm with the tool and the arm holding the object (positions in metres,
        one base frame).

    Returns
    -------
    ndarray, shape (n, 3)
        ``R_holderᵀ (p_tool − p_holder)``, metres, the holding arm's end-effector
        frame: the same wherever and however the object is held, and unchanged by a
        rigid motion of the whole scene.
    """
    r = Rotation.from_quat(holder.quat)
    return np.asarray(r.inv().apply(tool.pos - holder.pos), dtype=np.float64)


def _pair_level(tool: ArmTrack, holder: ArmTrack, name: str, dt: float, window: int) -> FloatArray:
    if name == "relpos":
        return _smooth(tool.pos - holder.pos, window)
    if name == "holdangular":
        return _smooth(_body_angular(holder.quat, dt), window)
    obj = object_frame_position(tool, holder)
    if name == "objpos":
        return _smooth(obj, window)
    if name in ("objcyl", "objcylvel"):
        # distance from the holder's z (flange) axis and position along it: unchanged
        # when the object is turned about that axis
        cyl = np.column_stack([np.hypot(obj[:, 0], obj[:, 1]), obj[:, 2]])
        if name == "objcylvel":
            cyl = np.gradient(cyl, dt, axis=0)
        return _smooth(cyl, window)
    # objvel: the tool's velocity as seen from the (possibly turning) object
    return _smooth(np.gradient(obj, dt, axis=0), window)


def stream_channels(
    stream: LabelledStream,
    *,
    shape: Sequence[str] = ("pos",),
    levels: Sequence[str] = (),
    arms: Sequence[int] | None = None,
    window: int = 5,
    zero_ft: bool = False,
) -> tuple[FloatArray, FloatArray]:
    """The shape and level arrays of a recording.

    Parameters
    ----------
    stream : LabelledStream
    shape, levels : sequence of str
        Channel names (see the module docstring); ``shape`` must not be empty.
    arms : sequence of int, optional
        Arms to use (default all).
    window : int
        Smoothing of the level channels, samples.
    zero_ft : bool
        Subtract each arm's force/torque over the first :data:`ZERO_FT_S` seconds.

    Returns
    -------
    shape : ndarray, shape (n, 3 · len(shape) · arms), in channel units
    levels : ndarray, shape (n, L), in channel units: the per-arm channels of each arm in
        turn (3 columns for a vector channel, 1 for a magnitude), then the pair channels
        (3 columns each, 2 for ``objcyl`` / ``objcylvel``), in the order given
    """
    if not shape:
        raise PrimitiveError("at least one shape channel is needed (pos, rot, force, torque)")
    _check(shape, SHAPE_UNITS, "shape")
    _check(levels, LEVEL_UNITS, "level")
    use = list(range(len(stream.arms))) if arms is None else list(arms)
    for a in use:
        if not 0 <= a < len(stream.arms):
            raise PrimitiveError(f"{stream.name}: no arm {a} (it has {len(stream.arms)})")
    dt = float(np.median(np.diff(stream.t)))
    arm_tracks = [stream.arms[a] for a in use]
    if zero_ft:
        n0 = max(int(np.searchsorted(stream.t, stream.t[0] + ZERO_FT_S)), 1)
        arm_tracks = [
            ArmTrack(
                a.pos, a.quat, a.force - a.force[:n0].mean(0), a.torque - a.torque[:n0].mean(0)
            )
            for a in arm_tracks
        ]
    ys = [_shape(a, n) / SHAPE_UNITS[n] for a in arm_tracks for n in shape]
    ls = [
        _level(a, n, dt, window) / LEVEL_UNITS[n]
        for a in arm_tracks
        for n in levels
        if n not in PAIR_LEVELS
    ]
    for n in levels:
        if n not in PAIR_LEVELS:
            continue
        if len(arm_tracks) < 2:
            raise PrimitiveError(f"{stream.name}: level {n!r} needs two arms, got {len(use)}")
        ls.append(_pair_level(arm_tracks[0], arm_tracks[1], n, dt, window) / LEVEL_UNITS[n])
    lev = np.hstack(ls) if ls else np.zeros((stream.n_samples, 0))
    return np.hstack(ys), lev
