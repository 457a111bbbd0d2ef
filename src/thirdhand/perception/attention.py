"""Which object a head (or gaze) ray attends to over time: cone, hysteresis, intervals.

A ray is an origin and a direction per frame (world frame, metres). An object
is attended while the angle between the ray and the line from the origin to the
object's centre is inside a cone; the attended object changes only when another
one is clearly closer to the ray (by ``hysteresis_deg``) or the current one
leaves a cone widened by the same margin, so a ray wavering between two
neighbours does not flicker. Intervals shorter than ``min_duration`` are dropped.

Rays come from a head tracked by motion capture (:func:`head_rays`, a body of
kind ``head``) or from a camera's head pose (:func:`camera_head_rays`, the
face's forward axis carried into the capture frame by the camera's pose).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.demonstration import Demonstration
from thirdhand.errors import ThirdhandError

#: Objects a person attends to or points at: the bodies of these kinds.
TARGET_KINDS = ("part", "tool")


@dataclass(frozen=True)
class AttentionInterval:
    """``attends(object, t0, t1)``: the ray stayed on ``object`` from ``t0`` to ``t1`` seconds.

    Attributes
    ----------
    object : str
    t0, t1 : float, seconds
    angle_deg : float
        Median angle between the ray and the object's centre over the interval.
    source : str
        Where the ray came from (a head body, ``"camera"``).
    """

    object: str
    t0: float
    t1: float
    angle_deg: float
    source: str = "head"


def object_centres(
    demo: Demonstration, names: Sequence[str] | None = None
) -> tuple[list[str], FloatArray]:
    """World centres of objects over time.

    The centre is that of the bounding box in ``demo.meta["geometry"][name]``
    (``bbox_min_m``, ``bbox_max_m``, body frame) when known, else the body's origin.

    Parameters
    ----------
    demo : Demonstration
    names : sequence of str, optional
        Default: every body of kind part or tool.

    Returns
    -------
    names : list of str
    centres : ndarray, shape (n_frames, n_objects, 3), metres, world frame
        NaN where the body is not tracked.
    """
    if names is None:
        names = demo.bodies_of_kind(*TARGET_KINDS)
    geometry = demo.meta.get("geometry", {}) if isinstance(demo.meta, dict) else {}
    out = np.full((demo.n_frames, len(names), 3), np.nan)
    for j, name in enumerate(names):
        if name not in demo:
            raise ThirdhandError(f"attention: no body {name!r} in the demonstration")
        geo = geometry.get(name, {}) if isinstance(geometry, dict) else {}
        lo, hi = geo.get("bbox_min_m"), geo.get("bbox_max_m")
        local = np.zeros(3) if lo is None or hi is None else 0.5 * np.add(lo, hi)
        c = demo.pos(name) + se3.quat_rotate(demo.quat(name), np.asarray(local, dtype=np.float64))
        c[~demo.valid(name)] = np.nan
        out[:, j] = c
    return list(names), out


def head_rays(
    demo: Demonstration,
    head: str | None = None,
    *,
    forward: ArrayLike = (1.0, 0.0, 0.0),
    eye: ArrayLike = (0.0, 0.0, 0.0),
) -> tuple[FloatArray, FloatArray]:
    """Rays of a motion-captured head.

    Parameters
    ----------
    demo : Demonstration
    head : str, optional
        The head body; default the only body of kind ``head``.
    forward : array_like, shape (3,), head frame
        Viewing direction (the synthetic heads look along their ``x`` axis).
    eye : array_like, shape (3,), metres, head frame
        Ray origin (between the eyes).

    Returns
    -------
    origin, direction : ndarray, shape (n_frames, 3), world frame; NaN where untracked
    """
    if head is None:
        heads = demo.bodies_of_kind("head")
        if len(heads) != 1:
            raise ThirdhandError(
                f"attention: expected one body of kind 'head', found {len(heads)}; name one"
            )
        head = heads[0]
    if head not in demo:
        raise ThirdhandError(f"attention: no body {head!r} in the demonstration")
    q = demo.quat(head)
    origin = demo.pos(head) + se3.quat_rotate(q, np.asarray(eye, dtype=np.float64))
    f = np.asarray(forward, dtype=np.float64)
    direction = se3.quat_rotate(q, f / np.linalg.norm(f))
    bad = ~demo.valid(head)
    origin[bad] = np.nan
    direction[bad] = np.nan
    return origin, direction


def camera_head_rays(
    camera_pos: ArrayLike,
    camera_quat: ArrayLike,
    rotation: ArrayLike,
    translation: ArrayLike,
) -> tuple[FloatArray, FloatArray]:
    """Head rays in the capture frame from a camera's head poses.

    Parameters
    ----------
    camera_pos : array_like, shape (3,), metres; camera_quat : shape (4,), x y z w
        The camera's pose in the capture (world) frame, OpenCV camera axes.
    rotation : array_like, shape (n, 3, 3)
        ``R_cam_head`` per frame (:class:`thirdhand.perception.track.HeadTrack`).
    translation : array_like, shape (n, 3), metres, camera frame

    Returns
    -------
    origin, direction : ndarray, shape (n, 3), world frame
        The face's nose tip and forward axis (model ``−z``).
    """
    r = np.asarray(rotation, dtype=np.float64)
    fwd_cam = -r[:, :, 2]
    cq = np.asarray(camera_quat, dtype=np.float64)
    origin = np.asarray(camera_pos, dtype=np.float64) + se3.quat_rotate(
        cq, np.asarray(translation, dtype=np.float64)
    )
    return origin, se3.quat_rotate(cq, fwd_cam)


def ray_angles(
    origin: ArrayLike, direction: ArrayLike, centres: ArrayLike, *, min_distance: float = 0.0
) -> FloatArray:
    """Angle between each ray and the line from its origin to each object's centre.

    Parameters
    ----------
    origin, direction : array_like, shape (n, 3), world frame
    centres : array_like, shape (n, k, 3), metres, world frame
    min_distance : float, metres
        Objects closer than this to the origin get an infinite angle (the hand's
        own fingers, an object the hand touches).

    Returns
    -------
    ndarray, shape (n, k), degrees
        ``inf`` where a ray or a centre is missing (NaN) or too close.
    """
    o = np.asarray(origin, dtype=np.float64)
    d = np.asarray(direction, dtype=np.float64)
    v = np.asarray(centres, dtype=np.float64) - o[:, None, :]
    dist = np.linalg.norm(v, axis=-1)
    dn = np.linalg.norm(d, axis=-1)[:, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = np.einsum("nkd,nd->nk", v, d) / (dist * dn)
    ang = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    return np.where(np.isfinite(ang) & (dist >= min_distance), ang, np.inf)


def attention_intervals(
    t: ArrayLike,
    angles: ArrayLike,
    names: Sequence[str],
    *,
    cone_deg: float = 15.0,
    hysteresis_deg: float = 3.0,
    min_duration: float = 0.2,
    source: str = "head",
) -> list[AttentionInterval]:
    """Intervals during which one object is attended (see the module docstring).

    Parameters
    ----------
    t : array_like, shape (n,), seconds, increasing
    angles : array_like, shape (n, k), degrees (:func:`ray_angles`)
    names : sequence of k str
    cone_deg : float
        An object enters attention inside this half-angle...
    hysteresis_deg : float
        ...leaves it beyond ``cone_deg + hysteresis_deg``, and yields to another
        object only when that one is closer to the ray by this margin.
    min_duration : float, seconds
    source : str
        Recorded in each interval.

    Returns
    -------
    list of AttentionInterval, in time order
    """
    tt = np.asarray(t, dtype=np.float64)
    a = np.asarray(angles, dtype=np.float64)
    if a.shape != (tt.size, len(names)):
        raise ThirdhandError(
            f"attention: angles of shape {a.shape}, expected ({tt.size}, {len(names)})"
        )
    if a.shape[1] == 0 or tt.size == 0:
        return []
    best = np.argmin(a, axis=1)
    best_angle = a[np.arange(tt.size), best]
    label = np.full(tt.size, -1, dtype=np.int64)
    cur = -1
    for i in range(tt.size):
        if cur >= 0:
            here = a[i, cur]
            if here > cone_deg + hysteresis_deg:
                cur = -1
            elif best[i] != cur and best_angle[i] < here - hysteresis_deg:
                cur = int(best[i])
        if cur < 0 and best_angle[i] < cone_deg:
            cur = int(best[i])
        label[i] = cur
    out = []
    edges = np.flatnonzero(np.diff(label)) + 1
    for lo, hi in zip(np.r_[0, edges], np.r_[edges, tt.size], strict=True):
        k = int(label[lo])
        if k < 0 or tt[hi - 1] - tt[lo] < min_duration:
            continue
        med = float(np.median(a[lo:hi, k]))
        out.append(AttentionInterval(names[k], float(tt[lo]), float(tt[hi - 1]), med, source))
    return out


def attended_objects(
    demo: Demonstration,
    head: str | None = None,
    *,
    forward: ArrayLike = (1.0, 0.0, 0.0),
    eye: ArrayLike = (0.0, 0.0, 0.0),
    cone_deg: float = 15.0,
    hysteresis_deg: float = 3.0,
    min_duration: float = 0.2,
) -> list[AttentionInterval]:
    """Attention intervals of a motion-captured head over the parts and tools.

    See :func:`head_rays` and :func:`attention_intervals` for the parameters.
    """
    origin, direction = head_rays(demo, head, forward=forward, eye=eye)
    names, centres = object_centres(demo)
    ang = ray_angles(origin, direction, centres)
    src = head if head is not None else demo.bodies_of_kind("head")[0]
    return attention_intervals(
        demo.t,
        ang,
        names,
        cone_deg=cone_deg,
        hysteresis_deg=hysteresis_deg,
        min_duration=min_duration,
        source=src,
    )
