"""A constraint's learned motion as a path with a few key points a person can move.

The primitives stage stores, per constraint, a pose DMP of the child in the
parent's frame (``task.stages.primitives.constraints[key].dmp``, a
:class:`~thirdhand.task.stages.PrimitiveRecord`, see :mod:`thirdhand.primitives.stage`).
:func:`primitive_path` rolls it out as it was demonstrated and marks
:data:`KEY_FRACTIONS` of its duration as key points. Moving one (:func:`move_key_point`)
deforms the rolled-out positions by
a smooth displacement that is the move at that key point and zero at the other
key points, at the start and at the goal (a clamped cubic spline through the
key times, :func:`displacement`), then refits the position DMP's forcing
weights to the deformed path with the DMP's own start and goal
kept: the constraint pose the motion ends at does not change (that is edited
in the constraint), and neither does the orientation DMP.

The refit is a least-squares fit of as many weights as before, so it passes
the moved key point within the DMP's imitation error (a fraction of a
millimetre for the chair's motions), not exactly.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from thirdhand.arrays import FloatArray
from thirdhand.errors import ThirdhandError
from thirdhand.primitives.dmp import DMP, phase
from thirdhand.primitives.quaternion_dmp import PoseDMP
from thirdhand.primitives.serialize import dmp_to_dict, pose_dmp_from_record
from thirdhand.task.stages import DmpParameters, PrimitiveEdit, PrimitiveRecord, PrimitivesBlock

#: Where the editable key points sit, as fractions of the motion's duration.
KEY_FRACTIONS: tuple[float, ...] = (0.25, 0.5, 0.75)
#: Samples of the path drawn in the 3D view.
DRAWN_SAMPLES = 120


class PrimitiveEditError(ThirdhandError, ValueError):
    """A primitive edit that cannot be applied: no primitive, bad index, bad point."""


@dataclass(frozen=True)
class PrimitivePath:
    """The rollout of one constraint's pose DMP, child pose in the parent frame.

    Attributes
    ----------
    key : str
        The primitive's key in the primitives block (the constraint's symbol).
    parent, child : str
    s : ndarray, shape (n,), seconds from the motion's start
    pos : ndarray, shape (n, 3), metres, parent frame
        The position DMP's rollout (the orientation DMP, which an edit leaves as
        it is, is not rolled out: its numerical integration takes seconds).
    key_times : ndarray, shape (k,), seconds
    key_points : ndarray, shape (k, 3), metres, parent frame
        The path's positions at ``key_times``.
    """

    key: str
    parent: str
    child: str
    s: FloatArray
    pos: FloatArray
    key_times: FloatArray
    key_points: FloatArray

    def drawn(self, n: int = DRAWN_SAMPLES) -> FloatArray:
        """``n`` positions along the path (parent frame, metres), shape (n, 3)."""
        t = np.linspace(self.s[0], self.s[-1], n)
        return sample(self.s, self.pos, t)


def sample(s: FloatArray, pos: FloatArray, t: ArrayLike) -> FloatArray:
    """Positions (n, 3) at times ``t`` by linear interpolation of a rollout ``(s, pos)``."""
    tt = np.atleast_1d(np.asarray(t, dtype=np.float64))
    return np.stack([np.interp(tt, s, pos[:, k]) for k in range(pos.shape[1])], axis=1)


def primitive_entry(block: PrimitivesBlock | None, key: str) -> PrimitiveRecord:
    """The record ``key`` of a primitives block (``task.stages.primitives``).

    Raises
    ------
    PrimitiveEditError
        No block, or no record ``key`` (the message lists the keys there are).
    """
    if block is None or not block.constraints:
        raise PrimitiveEditError("the task has no learned primitives (thirdhand learn)")
    entry = block.constraints.get(key)
    if entry is None:
        raise PrimitiveEditError(f"no primitive {key!r}; there are {', '.join(block.constraints)}")
    return entry


def key_for(block: PrimitivesBlock | None, parent: str, child: str) -> str | None:
    """The key of the primitive of ``child`` on ``parent`` in a primitives block, or None."""
    found = None if block is None else block.find(parent, child)
    return None if found is None else found[0]


def _pose_dmp(entry: PrimitiveRecord, key: str) -> PoseDMP:
    try:
        return pose_dmp_from_record(entry)
    except ThirdhandError as exc:
        raise PrimitiveEditError(f"primitive {key!r}: {exc}") from None


def primitive_path(
    block: PrimitivesBlock | None, key: str, *, fractions: Sequence[float] = KEY_FRACTIONS
) -> PrimitivePath:
    """Roll out the primitive ``key`` as demonstrated; its key points at ``fractions`` of it.

    Raises
    ------
    PrimitiveEditError
        No such primitive, or unreadable parameters.
    """
    entry = primitive_entry(block, key)
    dmp = _pose_dmp(entry, key)
    s, pos, _ = dmp.position_.rollout()
    times = np.asarray(fractions, dtype=np.float64) * float(s[-1])
    return PrimitivePath(
        key=key,
        parent=entry.parent,
        child=entry.child,
        s=s,
        pos=pos,
        key_times=times,
        key_points=sample(s, pos, times),
    )


def displacement(s: FloatArray, key_times: FloatArray, offsets: ArrayLike) -> FloatArray:
    """A smooth displacement of a path: ``offsets[k]`` at ``key_times[k]``, zero at the ends.

    Parameters
    ----------
    s : ndarray, shape (n,), seconds, increasing; the path's times
    key_times : ndarray, shape (k,), seconds, strictly inside ``(s[0], s[-1])``
    offsets : array_like, shape (k, 3), metres

    Returns
    -------
    ndarray, shape (n, 3)
        The clamped cubic spline (zero value and zero velocity at ``s[0]`` and
        ``s[-1]``) through the key times' offsets, evaluated at ``s``.
    """
    from scipy.interpolate import CubicSpline

    off = np.asarray(offsets, dtype=np.float64).reshape(len(key_times), 3)
    knots = np.concatenate([[s[0]], key_times, [s[-1]]])
    values = np.concatenate([np.zeros((1, 3)), off, np.zeros((1, 3))])
    spline = CubicSpline(knots, values, axis=0, bc_type="clamped")
    return np.asarray(spline(s), dtype=np.float64)


def refit_position(dmp: DMP, s: FloatArray, pos: FloatArray) -> DMP:
    """A copy of ``dmp`` whose forcing weights fit ``pos`` (n, 3) at times ``s``.

    The start, goal, duration and gains stay the DMP's own (the formula of
    :meth:`DMP.fit` with ``y0`` and ``g`` held), so the motion still starts and
    ends where it did; the start velocity is the path's, as :meth:`DMP.fit`
    takes it (holding the demonstrated one instead, a few mm/s off the path's
    finite-difference estimate, tripled the refit error of an unmoved path).
    """
    new = DMP(dmp.n_weights, alpha=dmp.alpha, alpha_x=dmp.alpha_x)
    new.regularization = dmp.regularization
    tau = float(s[-1] - s[0])
    u = s - s[0]
    yd = np.gradient(pos, u, axis=0, edge_order=2)
    ydd = np.gradient(yd, u, axis=0, edge_order=2)
    x = phase(u, tau, new.alpha_x_)
    g, y0 = dmp.goal_, dmp.start_
    k, d = new.stiffness, new.alpha
    target = tau**2 * ydd - k * (g - pos) + d * tau * yd + k * (g - y0) * x[:, None]
    new._fit_weights(x, target)
    new.tau_, new.dt_ = dmp.tau_, dmp.dt_
    new.start_, new.goal_ = dmp.start_.copy(), dmp.goal_.copy()
    new.start_velocity_ = yd[0].copy()
    return new


def move_key_point(
    block: PrimitivesBlock | None,
    key: str,
    index: int,
    point: ArrayLike,
    *,
    fractions: Sequence[float] = KEY_FRACTIONS,
) -> PrimitivesBlock:
    """The primitives block with key point ``index`` of primitive ``key`` moved to ``point``.

    Parameters
    ----------
    block : PrimitivesBlock
        ``task.stages.primitives``; left untouched.
    key : str
    index : int
        0-based key point.
    point : array_like, shape (3,), metres, parent frame

    Returns
    -------
    PrimitivesBlock
        A new block: the record's ``dmp.position`` refitted, ``source: "corrected"``
        and the move appended to its ``edits`` (:class:`~thirdhand.task.stages.PrimitiveEdit`).

    Raises
    ------
    PrimitiveEditError
        No such primitive, an index out of range, a point that is not three
        finite numbers.
    """
    path = primitive_path(block, key, fractions=fractions)
    n = len(path.key_times)
    if not 0 <= index < n:
        raise PrimitiveEditError(f"primitive {key!r}: no key point {index + 1}; it has {n}")
    p = np.asarray(point, dtype=np.float64).reshape(-1)
    if p.size != 3 or not np.isfinite(p).all():
        raise PrimitiveEditError(
            f"primitive {key!r} key point {index + 1}: expected 3 finite numbers, got {point!r}"
        )
    offsets = np.zeros((n, 3))
    offsets[index] = p - path.key_points[index]
    deformed = path.pos + displacement(path.s, path.key_times, offsets)
    entry = primitive_entry(block, key)
    dmp = _pose_dmp(entry, key)
    position = refit_position(dmp.position_, path.s, deformed)
    edit = PrimitiveEdit.model_validate(
        {
            "index": index,
            "time_s": float(path.key_times[index]),
            "from": path.key_points[index].tolist(),
            "to": p.tolist(),
        }
    )
    new_dmp = entry.dmp.model_copy(
        update={"position": DmpParameters.model_validate(dmp_to_dict(position))}
    )
    new_entry = entry.model_copy(
        update={"dmp": new_dmp, "source": "corrected", "edits": [*entry.edits, edit]}
    )
    assert block is not None  # primitive_path found the entry
    return block.model_copy(update={"constraints": {**block.constraints, key: new_entry}})


__all__ = [
    "DRAWN_SAMPLES",
    "KEY_FRACTIONS",
    "PrimitiveEditError",
    "PrimitivePath",
    "displacement",
    "key_for",
    "move_key_point",
    "primitive_entry",
    "primitive_path",
    "refit_position",
    "sample",
]
