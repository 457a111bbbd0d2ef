"""Which body pairs of a collision world are checked, and with which margins: pure functions.

A collision world's bodies are numbered in one order: the robot's links
``0 .. L-1``, the free objects ``L .. L+O-1`` and, when a part is grasped, that
part last (``L+O``). The pair table lists the pairs of body indices that are
checked; everything else is allowed. Checked are robot link × robot link (the
pairs the SRDF leaves in, one of them moved by a joint), robot link × object,
grasped part × object and grasped part × robot link except the gripper's links
and those it touched when it was grasped. A pair is allowed by name; the group
names ``"robot"`` (every link) and ``"gripper"`` (the hand's links) stand for
their links.

Margins are coal security margins, metres: a pair is in collision when its
bodies come closer than the margin (a negative margin lets them interpenetrate
that deep). The contact margin is ``-tolerance`` between primitive shapes and 0
when a triangle mesh takes part (coal supports no negative margin on meshes).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from thirdhand.arrays import BoolArray, FloatArray, IndexArray

GRIPPER = "gripper"
ROBOT = "robot"

#: Reach of the path kernel's margin levels, configurations on either side (see
#: :func:`path_margin_levels`); a longer stretch is split before it is tested.
PATH_REACH = np.concatenate([[0], 2 ** np.arange(13)]).astype(np.int64)

#: Slack of the test of two fixed bodies against their margin, metres (coal's distances
#: are exact to far better than this).
FIXED_SLACK_M = 1e-6


@dataclass(frozen=True)
class BodyKind:
    """What the pair table needs to know of a body.

    Attributes
    ----------
    name : str
        Link or object name.
    is_mesh : bool
        The geometry is a triangle mesh (no negative margin in coal).
    moves : bool
        The arm moves it: a link on a joint, or the grasped part.
    """

    name: str
    is_mesh: bool = False
    moves: bool = False


@dataclass(frozen=True)
class PairWorld:
    """The bodies of a collision world by name, and what may touch what.

    Attributes
    ----------
    links : tuple of BodyKind
        The robot's collision geometries, in the robot's order (bodies ``0 .. L-1``).
    self_pairs : tuple of (int, int)
        Link index pairs checked against each other (the SRDF's pairs with a moving link).
    gripper_links : frozenset of str
        Link names of the hand (the group ``"gripper"``); the grasped part is not
        checked against them.
    objects : tuple of BodyKind
        Free objects (bodies ``L .. L+O-1``).
    attached : BodyKind or None
        The grasped part (body ``L+O``), or None.
    touch_links : frozenset of str
        Links the grasped part touched when it was grasped (not checked against it).
    allowed : frozenset of frozenset of str
        Pairs of names (or group names) whose collisions are ignored.
    """

    links: tuple[BodyKind, ...]
    self_pairs: tuple[tuple[int, int], ...] = ()
    gripper_links: frozenset[str] = frozenset()
    objects: tuple[BodyKind, ...] = ()
    attached: BodyKind | None = None
    touch_links: frozenset[str] = frozenset()
    allowed: frozenset[frozenset[str]] = field(default_factory=frozenset)

    @property
    def bodies(self) -> tuple[BodyKind, ...]:
        """Every body in index order: links, objects, the grasped part."""
        tail = () if self.attached is None else (self.attached,)
        return self.links + self.objects + tail


@dataclass(frozen=True)
class PairTable:
    """The checked pairs of a world and their contact margins (read-only arrays).

    Attributes
    ----------
    first, second : ndarray of intp, shape (P,)
        Body indices of each checked pair (see the module notes for the order).
    contact : ndarray, shape (P,)
        Contact margin of each pair, metres (:func:`contact_margin`).
    n_moving : ndarray of intp, shape (P,)
        How many of the pair's two bodies the arm moves: 0, 1 or 2.
    """

    first: IndexArray
    second: IndexArray
    contact: FloatArray
    n_moving: IndexArray

    def __len__(self) -> int:
        return len(self.first)


def is_allowed(
    allowed: frozenset[frozenset[str]],
    a: str,
    b: str,
    *,
    a_is_link: bool = False,
    gripper_links: frozenset[str] = frozenset(),
) -> bool:
    """True if the pair ``a``, ``b`` is allowed: by name, or, for a link ``a``, by group.

    A link is covered by ``("robot", b)``, and a link of the hand by ``("gripper", b)``.
    """
    if frozenset((a, b)) in allowed:
        return True
    if a_is_link:
        if frozenset((ROBOT, b)) in allowed:
            return True
        if a in gripper_links and frozenset((GRIPPER, b)) in allowed:
            return True
    return False


def contact_margin(a_is_mesh: bool, b_is_mesh: bool, tolerance: float) -> float:
    """Contact margin of a pair, metres: ``-tolerance``, or 0 when a mesh takes part."""
    return 0.0 if (a_is_mesh or b_is_mesh) else -float(tolerance)


def checked_pairs(world: PairWorld) -> tuple[IndexArray, IndexArray]:
    """Body index pairs that are checked, in a fixed order (see the module notes).

    The order: link × link (the SRDF's order), link × object (by object, then link),
    grasped part × object, grasped part × link.

    Returns
    -------
    first, second : ndarray of intp, shape (P,)
    """
    names = [link.name for link in world.links]
    n_links = len(names)
    al = world.allowed
    first: list[int] = []
    second: list[int] = []
    for i, j in world.self_pairs:
        if frozenset((names[i], names[j])) not in al:
            first.append(i)
            second.append(j)
    grip = world.gripper_links
    for k, obj in enumerate(world.objects):
        for i in range(n_links):
            if not is_allowed(al, names[i], obj.name, a_is_link=True, gripper_links=grip):
                first.append(i)
                second.append(n_links + k)
    if world.attached is not None:
        a_idx = n_links + len(world.objects)
        a_name = world.attached.name
        for k, obj in enumerate(world.objects):
            if frozenset((a_name, obj.name)) not in al:
                first.append(a_idx)
                second.append(n_links + k)
        exempt = grip | world.touch_links
        for i in range(n_links):
            if names[i] not in exempt and not is_allowed(
                al, names[i], a_name, a_is_link=True, gripper_links=grip
            ):
                first.append(a_idx)
                second.append(i)
    return np.array(first, dtype=np.intp), np.array(second, dtype=np.intp)


def pair_table(world: PairWorld, tolerance: float) -> PairTable:
    """The checked pairs of ``world`` with their contact margins and moving-body counts.

    Parameters
    ----------
    world : PairWorld
    tolerance : float
        Penetration depth, metres, below which two primitive shapes only touch.
    """
    first, second = checked_pairs(world)
    bodies = world.bodies
    mesh = np.array([b.is_mesh for b in bodies], dtype=bool)
    moves = np.array([b.moves for b in bodies], dtype=bool)
    contact = np.where(mesh[first] | mesh[second], 0.0, -float(tolerance)).astype(np.float64)
    n_moving = moves[first].astype(np.intp) + moves[second].astype(np.intp)
    for a in (first, second, contact, n_moving):
        a.flags.writeable = False
    return PairTable(first, second, contact, n_moving)


def pair_margins(table: PairTable, clearance: float = 0.0) -> FloatArray:
    """Security margin of every checked pair, metres, shape (P,).

    Without clearance (``clearance <= 0``), the contact margins. With it, a pair
    with one moving body needs ``clearance`` and a pair of two moving bodies twice
    that; pairs of two fixed bodies keep their contact margin.
    """
    if clearance <= 0.0:
        return table.contact.copy()
    return np.where(table.n_moving > 0, clearance * table.n_moving, table.contact)


def near_end_margins(contact: FloatArray, wide: FloatArray, near: BoolArray) -> FloatArray:
    """Margins of a path check: ``wide`` (P,) except the pairs ``near`` (P,) bool at either
    end of the path (a part leaving the table, a hand at its grasp), at ``contact`` (P,)."""
    return np.where(near, contact, wide)


def path_margin_levels(
    base: FloatArray, n_moving: IndexArray, max_step_m: float, reach: IndexArray = PATH_REACH
) -> FloatArray:
    """The path kernel's margin levels for a path interpolated at ``max_step_m``, metres.

    Level ``l`` stands for the ``reach[l]`` configurations on either side of a tested
    one: no point of a moving body is farther than ``reach[l] * max_step_m`` from
    where it is tested, so each moving body adds that much to the margin.

    Parameters
    ----------
    base : ndarray, shape (P,)
        Margins of level 0 (negative ones count as 0).
    n_moving : ndarray of int, shape (P,)
        Moving bodies per pair.
    max_step_m : float
        Interpolation step, metres.
    reach : ndarray of int, shape (L,)

    Returns
    -------
    ndarray, shape (L, P)
    """
    return np.maximum(base, 0.0)[None] + (reach * max_step_m)[:, None] * n_moving


def fixed_pair_flags(distances: FloatArray, margins: FloatArray) -> BoolArray:
    """Which pairs of two fixed bodies are within their margin, shape (F,).

    ``distances`` and ``margins`` (F,), metres; negative margins count as 0 (a
    fixed pair's distance is exact, so it is flagged at contact or closer).
    """
    return np.asarray(distances <= np.maximum(margins, 0.0) + FIXED_SLACK_M, dtype=bool)


def fixed_pairs_touch(distances: FloatArray, margins: FloatArray) -> bool:
    """True if any pair of two fixed bodies is within its margin (:func:`fixed_pair_flags`):
    no configuration of such a world is free."""
    return bool(np.any(fixed_pair_flags(distances, margins)))
