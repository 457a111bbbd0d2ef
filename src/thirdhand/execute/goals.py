"""Goal poses of a part from its constraint, variations inside the free DOFs, and detection.

A constraint gives the child's pose in the parent frame, ``T_parent_child``, and
the free degrees of freedom: ranges of tx ty tz (m) and rx ry rz (rad) in the
constraint frame, whose pose in the child frame is ``F = T_child_constraint``.
A displacement ``D`` inside the free DOFs (translation ``(tx, ty, tz)`` then
rotation ``R_x(rx) R_y(ry) R_z(rz)``, both in the constraint frame) moves the
child to::

    T_parent_child' = T_parent_child · F · D · F⁻¹

so a leg free to spin about its own axis (``rx`` free, constraint frame on the
axis) turns about that axis and nothing else. :func:`dof_displacement` inverts
this map, and :func:`constraint_holds` uses it to tell from two observed poses
whether the constraint is established: the displacement's locked coordinates
must be zero and its free ones inside their ranges, within tolerances.

Every pose here is a homogeneous matrix, shape ``(4, 4)`` (or ``(n, 4, 4)``),
mapping the second frame's coordinates into the first's (``T_a_b``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.task.constraint import Constraint

#: Default tolerances of :func:`constraint_holds`: metres and radians.
POS_TOL_M = 0.005
ROT_TOL_RAD = np.deg2rad(3.0)


#: Inverse of rigid transforms (..., 4, 4): :func:`thirdhand.se3.transform_invert`.
invert = se3.transform_invert


def displacement_matrix(dofs: ArrayLike) -> FloatArray:
    """Transforms ``D`` of displacements ``(tx, ty, tz, rx, ry, rz)``, shape (..., 6) → (..., 4, 4).

    The rotation is ``R_x(rx) R_y(ry) R_z(rz)`` (intrinsic x, y, z), metres and radians.
    """
    d = np.asarray(dofs, dtype=np.float64)
    flat = d.reshape(-1, 6)
    out = np.tile(np.eye(4), (flat.shape[0], 1, 1))
    out[:, :3, :3] = se3.matrix_from_euler(flat[:, 3:], "XYZ")
    out[:, :3, 3] = flat[:, :3]
    return out.reshape(*d.shape[:-1], 4, 4)


def constraint_matrix(constraint: Constraint) -> FloatArray:
    """``T_parent_child`` of a constraint, shape (4, 4)."""
    return constraint.pose.matrix()


def goal_pose(parent_world: ArrayLike, constraint: Constraint) -> FloatArray:
    """World pose of the child when the constraint holds: ``T_world_parent · T_parent_child``.

    Parameters
    ----------
    parent_world : array_like, shape (4, 4)
        ``T_world_parent``.
    constraint : Constraint

    Returns
    -------
    ndarray, shape (4, 4)
        ``T_world_child``.
    """
    return np.asarray(parent_world, dtype=np.float64) @ constraint_matrix(constraint)


def vary(constraint: Constraint, dofs: ArrayLike) -> FloatArray:
    """Child poses in the parent frame displaced by ``dofs`` inside the constraint frame.

    Parameters
    ----------
    constraint : Constraint
    dofs : array_like, shape (6,) or (n, 6)
        ``(tx, ty, tz, rx, ry, rz)`` in the constraint frame, metres and radians.

    Returns
    -------
    ndarray, shape (4, 4) or (n, 4, 4)
        ``T_parent_child' = T_parent_child · F · D · F⁻¹``.
    """
    f = constraint.frame.matrix()
    return constraint_matrix(constraint) @ f @ displacement_matrix(dofs) @ invert(f)


def sample_dofs(
    constraint: Constraint,
    n: int,
    rng: int | np.random.Generator = 0,
    *,
    include_nominal: bool = True,
    stratified: bool = False,
) -> FloatArray:
    """Displacements drawn uniformly inside the constraint's free-DOF ranges.

    Parameters
    ----------
    constraint : Constraint
    n : int
        Number of displacements.
    rng : int or numpy.random.Generator
        Seed or generator.
    include_nominal : bool
        Make the first one the zero displacement (the demonstrated pose).
    stratified : bool
        Latin hypercube with one random offset per DOF: each free range is cut
        into as many equal strata as there are drawn displacements and every
        stratum gets one, at the same offset inside it, in random order (15
        drawn spins of a leg lie exactly 24° apart instead of clumping).

    Returns
    -------
    ndarray, shape (n, 6)
        Locked DOFs are 0. A constraint with no free DOF gives ``n`` zero rows.
    """
    gen = np.random.default_rng(rng)
    ranges = constraint.free_dof_array()
    if stratified:
        m = n - 1 if include_nominal and n > 0 else n
        u = np.zeros((n, 6))
        for k in range(6):
            u[n - m :, k] = (gen.permutation(m) + gen.uniform()) / max(m, 1)
        out = ranges[:, 0] + u * (ranges[:, 1] - ranges[:, 0])
    else:
        out = gen.uniform(ranges[:, 0], ranges[:, 1], size=(n, 6))
    if include_nominal and n > 0:
        # the demonstrated pose, or the range's middle when 0 lies outside it
        out[0] = np.clip(0.0, ranges[:, 0], ranges[:, 1])
    return np.asarray(out, dtype=np.float64)


def sample_goals(
    parent_world: ArrayLike,
    constraint: Constraint,
    n: int,
    rng: int | np.random.Generator = 0,
    *,
    include_nominal: bool = True,
    stratified: bool = False,
) -> tuple[FloatArray, FloatArray]:
    """World goal poses of the child sampled inside the free DOFs.

    Parameters
    ----------
    parent_world : array_like, shape (4, 4)
        ``T_world_parent``.
    constraint : Constraint
    n : int
    rng : int or numpy.random.Generator
    include_nominal : bool
        The first goal is the constraint's own pose.
    stratified : bool
        Latin hypercube sampling (see :func:`sample_dofs`).

    Returns
    -------
    goals : ndarray, shape (n, 4, 4)
        ``T_world_child``.
    dofs : ndarray, shape (n, 6)
        The displacement of each goal (constraint frame).
    """
    dofs = sample_dofs(constraint, n, rng, include_nominal=include_nominal, stratified=stratified)
    return np.asarray(parent_world, dtype=np.float64) @ vary(constraint, dofs), dofs


def sweep_dofs(
    constraint: Constraint,
    *,
    turn_step: float = np.pi / 18,
    shift_steps: int = 5,
    max_poses: int = 512,
) -> FloatArray:
    """Displacements covering the constraint's free DOFs on a grid (for sweeping shapes).

    Each free rotation is cut into steps of at most ``turn_step`` (a full turn: 36
    displacements 10° apart, the ends included), each free translation into
    ``shift_steps`` (its ends included); the grid is their product. When it would hold
    more than ``max_poses`` rows, the corners of the ranges and stratified draws
    (:func:`sample_dofs`) fill ``max_poses`` rows instead.

    Parameters
    ----------
    constraint : Constraint
    turn_step : float
        Largest step between swept turns, radians.
    shift_steps : int
        Displacements along each free translation (>= 2).
    max_poses : int
        Largest number of displacements returned.

    Returns
    -------
    ndarray, shape (n, 6)
        ``(tx, ty, tz, rx, ry, rz)`` in the constraint frame; the zero displacement (or the
        ranges' nearest point to it) first. A constraint with no free DOF gives one zero row.
    """
    ranges = constraint.free_dof_array()
    nominal = np.clip(0.0, ranges[:, 0], ranges[:, 1])
    axes: list[FloatArray] = []
    for k in range(6):
        lo, hi = float(ranges[k, 0]), float(ranges[k, 1])
        if hi <= lo:
            axes.append(np.array([nominal[k]]))
        elif k >= 3:
            axes.append(np.linspace(lo, hi, max(int(np.ceil((hi - lo) / turn_step)) + 1, 2)))
        else:
            axes.append(np.linspace(lo, hi, max(shift_steps, 2)))
    size = int(np.prod([len(a) for a in axes]))
    if size <= max_poses:
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 6)
    else:
        corners = np.stack(
            np.meshgrid(*[a[[0, -1]] if len(a) > 1 else a for a in axes], indexing="ij"), axis=-1
        ).reshape(-1, 6)[:max_poses]
        draws = sample_dofs(constraint, max(max_poses - len(corners), 0), 0, stratified=True)
        grid = np.vstack([corners, draws])
    return np.asarray(np.vstack([nominal[None, :], grid]), dtype=np.float64)


def _wrap(a: FloatArray) -> FloatArray:
    return np.asarray((a + np.pi) % (2.0 * np.pi) - np.pi, dtype=np.float64)


def dof_displacement(child_in_parent: ArrayLike, constraint: Constraint) -> FloatArray:
    """The displacement ``(tx, ty, tz, rx, ry, rz)`` that maps the constraint pose onto a pose.

    Inverse of :func:`vary`: ``D = F⁻¹ · T_pc⁻¹ · T_pc_observed · F``.

    Parameters
    ----------
    child_in_parent : array_like, shape (4, 4) or (n, 4, 4)
        Observed ``T_parent_child``.
    constraint : Constraint

    Returns
    -------
    ndarray, shape (6,) or (n, 6)
        Metres and radians (angles in ``[-π, π]``, intrinsic x y z).
    """
    obs = np.asarray(child_in_parent, dtype=np.float64)
    f = constraint.frame.matrix()
    d = invert(f) @ invert(constraint_matrix(constraint)) @ obs @ f
    flat = d.reshape(-1, 4, 4)
    angles = se3.euler_from_matrix(flat[:, :3, :3], "XYZ")
    out = np.concatenate([flat[:, :3, 3], angles], axis=1)
    return out.reshape(*obs.shape[:-2], 6)


def dof_violation(child_in_parent: ArrayLike, constraint: Constraint) -> FloatArray:
    """How far an observed pose lies outside the constraint's free-DOF ranges, per DOF.

    Returns
    -------
    ndarray, shape (6,) or (n, 6)
        Distance of each displacement coordinate from its range (0 inside), metres
        and radians. A rotation range spanning the full turn is never violated.
    """
    d = dof_displacement(child_in_parent, constraint)
    ranges = constraint.free_dof_array()
    lo, hi = ranges[:, 0], ranges[:, 1]
    below = lo - d
    above = d - hi
    rot = np.array([False, False, False, True, True, True])
    # angles are periodic: also measure from the range's wrapped ends
    wrapped_lo = np.abs(_wrap(d - lo))
    wrapped_hi = np.abs(_wrap(d - hi))
    gap = np.maximum(np.maximum(below, above), 0.0)
    rot_gap = np.where(gap > 0.0, np.minimum(gap, np.minimum(wrapped_lo, wrapped_hi)), 0.0)
    full = (hi - lo) >= 2.0 * np.pi - 1e-9
    rot_gap = np.where(full, 0.0, rot_gap)
    return np.asarray(np.where(rot, rot_gap, gap), dtype=np.float64)


def constraint_holds(
    child_in_parent: ArrayLike,
    constraint: Constraint,
    *,
    pos_tol: float = POS_TOL_M,
    rot_tol: float = ROT_TOL_RAD,
) -> bool:
    """True if the observed child pose satisfies the constraint within tolerances.

    Parameters
    ----------
    child_in_parent : array_like, shape (4, 4)
        Observed ``T_parent_child`` (``inv(T_world_parent) @ T_world_child``).
    constraint : Constraint
    pos_tol : float
        Metres a translation may lie outside its range (a locked one: away from 0).
    rot_tol : float
        Radians, likewise for rotations.
    """
    v = dof_violation(child_in_parent, constraint)
    return bool(np.all(v[:3] <= pos_tol) and np.all(v[3:] <= rot_tol))
