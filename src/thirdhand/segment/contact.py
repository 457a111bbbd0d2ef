"""Contact distance of two bodies from their bounding boxes, on the latent time axis.

An observation added to the report's four variances (``FeatureConfig.contact``):
the gap between the two bodies' bounding boxes, in metres. The variances only
see motion; when both bodies are still they cannot tell a screw lying in its
tray from a screw driven into its board, or a finger resting next to a part from
a finger holding it. Touching boxes can.

Bounding boxes come from ``demo.meta["geometry"][name]`` (``bbox_min_m`` and
``bbox_max_m``, body frame, metres), which the synthetic scenes and task files
carry; a body without one is a point at its origin. Two bodies without boxes
thus give exactly the distance between their origins: the feature degrades to
the origin distance on recordings without geometry.

The gap is approximated from the corners: the distance from each corner of B's
box (in A's frame) to A's box and from each corner of A's box (in B's frame) to
B's box, the smallest of the 16. It is exact when the nearest points include a
corner (a point and a box, boxes resting face to face or corner to face, one box
inside the other: 0) and an upper bound otherwise (two edges crossing).

It is computed once per latent step from the window-mean relative pose (mean
position of B in A, normalised mean of the sign-continuous relative quaternion),
so it costs ``O(n_steps)`` per pair, not ``O(n_frames)``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.segment.features import SegmentationError

Box = tuple[FloatArray, FloatArray]


def body_box(meta: Mapping[str, Any], name: str) -> Box | None:
    """Body-frame bounding box ``(lo (3,), hi (3,))``, metres, of ``name``, or None.

    Raises
    ------
    SegmentationError
        A box that is present but malformed (not 3 finite numbers each, ``lo > hi``).
    """
    geometry = meta.get("geometry")
    if not isinstance(geometry, Mapping):
        return None
    entry = geometry.get(name)
    if not isinstance(entry, Mapping) or "bbox_min_m" not in entry or "bbox_max_m" not in entry:
        return None
    try:
        lo = np.asarray(entry["bbox_min_m"], dtype=np.float64).reshape(3)
        hi = np.asarray(entry["bbox_max_m"], dtype=np.float64).reshape(3)
    except (TypeError, ValueError):
        raise SegmentationError(
            f"meta['geometry'][{name!r}]: bounding box must be two lists of 3 numbers"
        ) from None
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(lo <= hi)):
        raise SegmentationError(
            f"meta['geometry'][{name!r}]: bounding box min {lo.tolist()} must be finite "
            f"and not above max {hi.tolist()}"
        )
    return lo, hi


def box_corners(box: Box | None) -> FloatArray:
    """The 8 corners (8, 3) of a box ``(lo (3,), hi (3,))``, x slowest, z fastest, lo
    before hi; the origin (1, 3) for None (a body known as a point)."""
    if box is None:
        return np.zeros((1, 3))
    lo, hi = box
    idx = np.array([[i >> 2 & 1, i >> 1 & 1, i & 1] for i in range(8)], dtype=bool)
    return np.asarray(np.where(idx, hi, lo), dtype=np.float64)


def _to_box(points: FloatArray, box: Box | None) -> FloatArray:
    """Distance of points (..., 3) to a box (or to the origin when None), metres."""
    if box is None:
        return np.sqrt(np.einsum("...i,...i->...", points, points))
    lo, hi = box
    gap = np.maximum(np.maximum(lo - points, points - hi), 0.0)
    return np.sqrt(np.einsum("...i,...i->...", gap, gap))


def box_gap(
    pos_ba: FloatArray, quat_ba: FloatArray, box_a: Box | None, box_b: Box | None
) -> FloatArray:
    """Corner approximation of the gap between two boxes (see the module docstring).

    Parameters
    ----------
    pos_ba : ndarray, shape (n, 3), metres
        B's origin in A's frame.
    quat_ba : ndarray, shape (n, 4), x y z w
        B's orientation in A's frame (need not be normalised; zero rows give NaN).
    box_a, box_b : (lo (3,), hi (3,)) in the body's own frame, metres, or None (a point)

    Returns
    -------
    ndarray, shape (n,), metres
    """
    if box_a is None and box_b is None:
        p0 = np.asarray(pos_ba, dtype=np.float64)
        d0: FloatArray = np.sqrt(np.einsum("ij,ij->i", p0, p0))
        return d0
    q = np.asarray(quat_ba, dtype=np.float64)
    norm = np.linalg.norm(q, axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        q = q / norm
    p = np.asarray(pos_ba, dtype=np.float64)
    ok = np.all(np.isfinite(q), axis=1) & np.all(np.isfinite(p), axis=1)
    out = np.full(p.shape[0], np.nan)
    if not ok.any():
        return out
    p, q = p[ok], q[ok]
    cb, ca = box_corners(box_b), box_corners(box_a)
    # B's corners in A's frame: p + R c.
    b_in_a = p[:, None, :] + se3.quat_rotate(q[:, None, :], cb[None, :, :])
    # A's corners in B's frame: R⁻¹ (c − p).
    qi = q * np.array([-1.0, -1.0, -1.0, 1.0])
    a_in_b = se3.quat_rotate(qi[:, None, :], ca[None, :, :] - p[:, None, :])
    d = np.minimum(_to_box(b_in_a, box_a).min(axis=1), _to_box(a_in_b, box_b).min(axis=1))
    out[ok] = d
    return out


__all__ = ["body_box", "box_corners", "box_gap"]
