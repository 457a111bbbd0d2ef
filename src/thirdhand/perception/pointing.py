"""Pointing gestures from tracked thumb, index and middle fingertips.

A hand points when the index is extended and the thumb and middle finger are
curled together (fingertip distances: index to middle and index to thumb over
``extended``, thumb to middle under ``curled``) and the index tip is nearly
still (speed under ``max_speed``), held for ``dwell`` seconds. During a grasp
the index and middle fingertips stay side by side (2-3 cm), so reaching and
grasping never look like pointing.

The pointing ray runs from the middle of the thumb and middle fingertips
through the index tip (``ray="index"``) or, when the person's head is tracked,
from the head through the index tip (``ray="head"``, how people aim). The target
is the part or tool whose centre is at the smallest angle from the ray, inside
a cone of ``cone_deg`` (median over the gesture's frames). Each gesture is an
event ``pointed(hand, object, t0, t1)``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from thirdhand.arrays import BoolArray, FloatArray
from thirdhand.demonstration import Demonstration
from thirdhand.errors import ThirdhandError
from thirdhand.perception.attention import object_centres, ray_angles

ROLES = ("thumb", "index", "middle")


@dataclass(frozen=True)
class PointingEvent:
    """``pointed(hand, object, t0, t1)``.

    Attributes
    ----------
    hand : str
        The hand body (``hand_body`` of its fingers, e.g. ``"rh"``).
    object : str or None
        The target; None when nothing lay inside the cone.
    t0, t1 : float, seconds
        First and last frame of the held posture.
    angle_deg : float
        Median angle between the ray and the target's centre (inf without target).
    ray : {"index", "head"}
    """

    hand: str
    object: str | None
    t0: float
    t1: float
    angle_deg: float
    ray: str

    def to_dict(self) -> dict[str, Any]:
        """JSON-able form."""
        return {
            "hand": self.hand,
            "object": self.object,
            "t0": round(self.t0, 4),
            "t1": round(self.t1, 4),
            "angle_deg": None if not np.isfinite(self.angle_deg) else round(self.angle_deg, 2),
            "ray": self.ray,
        }


def finger_roles(demo: Demonstration) -> dict[str, dict[str, str]]:
    """Tracked thumb, index and middle fingertips per hand.

    Fingers (bodies of kind ``finger``) are grouped by ``hand_body`` (else by
    ``person`` and ``hand``); the role comes from the name (``thumb``, ``index``,
    ``middle`` anywhere in it, any case). Hands missing one of the three are left out.

    Returns
    -------
    dict
        ``{hand: {"thumb": body, "index": body, "middle": body}}``.
    """
    hands: dict[str, dict[str, str]] = {}
    for name in demo.bodies_of_kind("finger"):
        info = demo.info(name)
        hand = info.hand_body or "_".join(x for x in (info.person, info.hand) if x) or "hand"
        for role in ROLES:
            if role in name.lower():
                hands.setdefault(hand, {})[role] = name
    return {h: r for h, r in hands.items() if all(k in r for k in ROLES)}


def pointing_posture(
    thumb: ArrayLike,
    index: ArrayLike,
    middle: ArrayLike,
    *,
    extended: float = 0.05,
    curled: float = 0.035,
) -> BoolArray:
    """Frames where the fingertips are in the pointing posture.

    Parameters
    ----------
    thumb, index, middle : array_like, shape (n, 3), metres
        Fingertip positions (NaN where untracked: not pointing).
    extended, curled : float, metres
        Index farther than ``extended`` from both others; thumb and middle closer
        than ``curled``.

    Returns
    -------
    ndarray, shape (n,), bool
    """
    th, ix, md = (np.asarray(a, dtype=np.float64) for a in (thumb, index, middle))
    d_im = np.linalg.norm(ix - md, axis=1)
    d_it = np.linalg.norm(ix - th, axis=1)
    d_tm = np.linalg.norm(th - md, axis=1)
    with np.errstate(invalid="ignore"):
        return np.asarray((d_im > extended) & (d_it > extended) & (d_tm < curled))


def _speed(t: FloatArray, p: FloatArray, half_window: float) -> FloatArray:
    """Central-difference speed over ``±half_window`` seconds, m/s (NaN across gaps)."""
    lo = np.searchsorted(t, t - half_window)
    hi = np.minimum(np.searchsorted(t, t + half_window, side="right") - 1, t.size - 1)
    dt = np.maximum(t[hi] - t[lo], 1e-12)
    return np.asarray(np.linalg.norm(p[hi] - p[lo], axis=1) / dt, dtype=np.float64)


def _runs(mask: BoolArray, t: FloatArray, bridge: float) -> list[tuple[int, int]]:
    """Half-open index ranges of the True runs, joined across gaps under ``bridge`` seconds."""
    edges = np.flatnonzero(np.diff(np.r_[0, mask.astype(np.int8), 0]))
    runs: list[tuple[int, int]] = []
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        if runs and t[a] - t[runs[-1][1] - 1] <= bridge:
            runs[-1] = (runs[-1][0], int(b))
        else:
            runs.append((int(a), int(b)))
    return runs


def detect_pointing(
    demo: Demonstration,
    *,
    dwell: float = 0.4,
    cone_deg: float = 15.0,
    ray: str = "auto",
    max_speed: float = 0.25,
    extended: float = 0.05,
    curled: float = 0.035,
    targets: Sequence[str] | None = None,
    bridge: float = 0.15,
    max_gap: float = 0.3,
) -> list[PointingEvent]:
    """Pointing events of every hand with tracked thumb, index and middle.

    Parameters
    ----------
    demo : Demonstration
    dwell : float, seconds
        Shortest held posture that counts as a gesture.
    cone_deg : float, degrees
        Half-angle of the cone in which a target is looked for (10-20° is usual).
    ray : {"auto", "index", "head"}
        ``auto``: from the person's head through the fingertip when exactly one
        head of that person is tracked, else along the index.
    max_speed : float, m/s
        The index tip moves slower than this while pointing.
    extended, curled : float, metres
        See :func:`pointing_posture`.
    targets : sequence of str, optional
        Objects that can be pointed at; default every part and tool.
    bridge : float, seconds
        A posture interrupted for at most this long (a tracking gap, a tremor
        spike) is one gesture.
    max_gap : float, seconds
        Fingertip and head tracking gaps up to this long are interpolated first.

    Returns
    -------
    list of PointingEvent, in time order

    Raises
    ------
    ThirdhandError
        If no hand has all three fingertips tracked, or ``ray="head"`` and no
        head is tracked.
    """
    if ray not in ("auto", "index", "head"):
        raise ThirdhandError(f"pointing: ray must be auto, index or head, got {ray!r}")
    hands = finger_roles(demo)
    if not hands:
        raise ThirdhandError(
            "pointing: no hand with thumb, index and middle fingertips tracked "
            "(bodies of kind 'finger' named ...thumb, ...index, ...middle)"
        )
    names, centres = object_centres(demo, targets)
    bodies = [b for roles in hands.values() for b in roles.values()] + demo.bodies_of_kind("head")
    demo = demo.select(bodies).fill_gaps(max_gap)
    t = demo.t
    events: list[PointingEvent] = []
    for hand, roles in sorted(hands.items()):
        p = {}
        for role, body in roles.items():
            xyz = demo.pos(body).copy()
            xyz[~demo.valid(body)] = np.nan
            p[role] = xyz
        mode, head = _ray_mode(demo, roles["index"], ray)
        posture = pointing_posture(
            p["thumb"], p["index"], p["middle"], extended=extended, curled=curled
        )
        with np.errstate(invalid="ignore"):
            still = _speed(t, p["index"], 0.05) < max_speed
        for lo, hi in _runs(posture & still, t, bridge):
            if t[hi - 1] - t[lo] < dwell:
                continue
            tip = p["index"][lo:hi]
            if head is None:
                origin = tip
                direction = tip - 0.5 * (p["thumb"][lo:hi] + p["middle"][lo:hi])
            else:
                origin = demo.pos(head)[lo:hi]
                direction = tip - origin
            ang = ray_angles(origin, direction, centres[lo:hi], min_distance=0.05)
            med = np.median(ang, axis=0) if ang.shape[1] else np.zeros(0)
            k = int(np.argmin(med)) if med.size else -1
            hit = k >= 0 and med[k] < cone_deg
            events.append(
                PointingEvent(
                    hand,
                    names[k] if hit else None,
                    float(t[lo]),
                    float(t[hi - 1]),
                    float(med[k]) if hit else float("inf"),
                    mode,
                )
            )
    events.sort(key=lambda e: (e.t0, e.hand))
    return events


def _ray_mode(demo: Demonstration, index_body: str, ray: str) -> tuple[str, str | None]:
    """The ray kind and the head body it starts from (None: along the index)."""
    if ray == "index":
        return "index", None
    person = demo.info(index_body).person
    heads = [h for h in demo.bodies_of_kind("head") if demo.info(h).person == person]
    if len(heads) == 1:
        return "head", heads[0]
    if ray == "head":
        raise ThirdhandError(
            f"pointing: ray='head' needs one tracked head of {person or 'the person'}, "
            f"found {len(heads)}"
        )
    return "index", None
