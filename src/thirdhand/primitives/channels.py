"""Channels of a labelled recording for the primitive-library parser: shape and levels.

Two kinds of input per arm, chosen by name:

- **shape** channels, modelled by each skill's ProMP after the segment is
  translated to start at zero: ``pos`` (metres), ``rot`` (orientation as the
  log map ``log(R_0ᵀ R_t)`` relative to the recording's first sample, radians),
  ``force`` (N), ``torque`` (N m);
- **level** channels, modelled per sample by each skill's Gaussian (absolute
  values, not translated): ``force`` and ``torque`` (magnitudes, N and N m),
  ``speed`` (m/s), ``angular`` (rad/s) and ``velocity`` (the three signed
  components, m/s, base frame: a move down and a move up differ sample by
  sample), smoothed over ``window`` samples; and, with two or more arms,
  ``relpos`` (the first arm's position minus the second's, 3 columns, base
  frame, once per recording, not per arm): where the tool is relative to the
  hand holding the object.

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
from numpy.typing import NDArray
from scipy.ndimage import uniform_filter1d
from scipy.spatial.transform import Rotation

from thirdhand.io.figueroa import ArmTrack, LabelledStream
from thirdhand.primitives._checks import PrimitiveError

FloatArray = NDArray[np.float64]

#: Unit of each shape channel (its values are divided by it).
SHAPE_UNITS = {"pos": 0.02, "rot": 0.1, "force": 2.0, "torque": 0.2}
#: Unit of each level channel.
LEVEL_UNITS = {
    "force": 2.0,
    "torque": 0.2,
    "speed": 0.02,
    "angular": 0.1,
    "velocity": 0.02,
    "relpos": 0.02,
}
#: Level channels computed once per recording from two arms, not per arm.
PAIR_LEVELS = ("relpos",)
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


def _level(arm: ArmTrack, name: str, dt: float, window: int) -> FloatArray:
    if name == "force":
        x = np.linalg.norm(arm.force, axis=1)
    elif name == "torque":
        x = np.linalg.norm(arm.torque, axis=1)
    elif name == "speed":
        x = np.linalg.norm(np.gradient(arm.pos, dt, axis=0), axis=1)
    elif name == "velocity":
        x = np.gradient(arm.pos, dt, axis=0)
    else:
        r = Rotation.from_quat(arm.quat)
        step = (r[1:] * r[:-1].inv()).magnitude() / dt
        x = np.concatenate([step[:1], step])
    out = uniform_filter1d(x, size=max(window, 1), axis=0, mode="nearest")
    return np.asarray(out, dtype=np.float64).reshape(x.shape[0], -1)


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
    levels : ndarray, shape (n, L), in channel units (3 columns for ``velocity``, else 1, per
        arm; then 3 for ``relpos``)
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
    if "relpos" in levels:
        if len(arm_tracks) < 2:
            raise PrimitiveError(f"{stream.name}: level 'relpos' needs two arms, got {len(use)}")
        rel = arm_tracks[0].pos - arm_tracks[1].pos
        ls.append(
            uniform_filter1d(rel, size=max(window, 1), axis=0, mode="nearest")
            / LEVEL_UNITS["relpos"]
        )
    lev = np.hstack(ls) if ls else np.zeros((stream.n_samples, 0))
    return np.hstack(ys), lev
