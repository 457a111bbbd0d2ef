"""The pair table and the margins: pure functions checked against tables worked out by hand."""

from __future__ import annotations

import numpy as np
import pytest

from thirdhand.execute.pair_table import (
    GRIPPER,
    ROBOT,
    BodyKind,
    PairWorld,
    checked_pairs,
    contact_margin,
    fixed_pair_flags,
    fixed_pairs_touch,
    is_allowed,
    near_end_margins,
    pair_margins,
    pair_table,
    path_margin_levels,
)
from thirdhand.execute.scene import resting_links

TOL = 1e-3


def _pair(a: str, b: str) -> frozenset[str]:
    return frozenset((a, b))


def _world(**changes: object) -> PairWorld:
    """Bodies 0..6: base (fixed), l1, l2 (mesh), hand (the gripper), table, leg (mesh), and
    the grasped seat (mesh), which touched l2 when it was grasped."""
    fields: dict[str, object] = {
        "links": (
            BodyKind("base"),
            BodyKind("l1", moves=True),
            BodyKind("l2", is_mesh=True, moves=True),
            BodyKind("hand", moves=True),
        ),
        "self_pairs": ((0, 2), (1, 3), (0, 3)),
        "gripper_links": frozenset({"hand"}),
        "objects": (BodyKind("table"), BodyKind("leg", is_mesh=True)),
        "attached": BodyKind("seat", is_mesh=True, moves=True),
        "touch_links": frozenset({"l2"}),
        "allowed": frozenset(
            {
                _pair("base", "table"),
                _pair(GRIPPER, "table"),
                _pair("l1", "hand"),
                _pair("seat", "leg"),
            }
        ),
    }
    fields.update(changes)
    return PairWorld(**fields)  # type: ignore[arg-type]


# By hand: link x link (SRDF order): (0,2); (1,3) allowed by name; (0,3).
# link x table: base allowed by name, hand by the gripper group: (1,4), (2,4).
# link x leg: all four. seat x objects: (6,4); seat x leg allowed.
# seat x links: hand (gripper) and l2 (touched) exempt: (6,0), (6,1).
FIRST = [0, 0, 1, 2, 0, 1, 2, 3, 6, 6, 6]
SECOND = [2, 3, 4, 4, 5, 5, 5, 5, 4, 0, 1]
# 0 when a mesh takes part (l2, leg, seat), else -tolerance
CONTACT = [0.0, -TOL, -TOL, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
# moving bodies: l1, l2, hand, seat
N_MOVING = [1, 1, 1, 1, 0, 1, 1, 1, 1, 1, 2]


def test_the_pair_table_of_a_small_world_is_the_one_worked_out_by_hand() -> None:
    table = pair_table(_world(), TOL)
    np.testing.assert_array_equal(table.first, FIRST)
    np.testing.assert_array_equal(table.second, SECOND)
    np.testing.assert_array_equal(table.contact, CONTACT)
    np.testing.assert_array_equal(table.n_moving, N_MOVING)
    assert len(table) == 11
    assert table.first.dtype == np.intp and not table.first.flags.writeable
    assert [b.name for b in _world().bodies] == [
        "base", "l1", "l2", "hand", "table", "leg", "seat"
    ]  # fmt: skip


def test_without_a_grasped_part_its_pairs_go_and_the_rest_stay() -> None:
    first, second = checked_pairs(_world(attached=None, touch_links=frozenset()))
    np.testing.assert_array_equal(first, FIRST[:8])
    np.testing.assert_array_equal(second, SECOND[:8])


def test_the_robot_group_allows_every_link_and_the_part_still_meets_the_objects() -> None:
    allowed = frozenset({_pair(ROBOT, "leg"), _pair(ROBOT, "seat")})
    first, second = checked_pairs(_world(allowed=allowed))
    # link x link (0,2), (1,3), (0,3); link x table: all four; nothing with the leg;
    # seat x table, seat x leg; no seat x link
    assert list(zip(first.tolist(), second.tolist(), strict=True)) == [
        (0, 2), (1, 3), (0, 3), (0, 4), (1, 4), (2, 4), (3, 4), (6, 4), (6, 5)
    ]  # fmt: skip


def test_allowed_pairs_by_name_and_by_group() -> None:
    allowed = frozenset({_pair("a", "b"), _pair(GRIPPER, "part"), _pair(ROBOT, "wall")})
    grip = frozenset({"finger"})
    assert is_allowed(allowed, "b", "a")  # either order
    assert not is_allowed(allowed, "a", "c")
    # the gripper group covers its links, only as links
    assert is_allowed(allowed, "finger", "part", a_is_link=True, gripper_links=grip)
    assert not is_allowed(allowed, "finger", "part", gripper_links=grip)
    assert not is_allowed(allowed, "elbow", "part", a_is_link=True, gripper_links=grip)
    # the robot group covers every link
    assert is_allowed(allowed, "elbow", "wall", a_is_link=True, gripper_links=grip)
    assert not is_allowed(allowed, "elbow", "wall", gripper_links=grip)


def test_contact_margin_is_minus_the_tolerance_between_primitives_only() -> None:
    assert contact_margin(False, False, 0.002) == -0.002
    assert contact_margin(True, False, 0.002) == 0.0
    assert contact_margin(False, True, 0.002) == 0.0
    assert contact_margin(True, True, 0.002) == 0.0


def test_clearance_margins_scale_with_the_moving_bodies() -> None:
    table = pair_table(_world(), TOL)
    np.testing.assert_array_equal(pair_margins(table), CONTACT)
    np.testing.assert_array_equal(pair_margins(table, -0.5), CONTACT)  # no clearance
    # 5 mm per moving body; base x leg (both fixed) keeps its contact margin
    want = [0.005, 0.005, 0.005, 0.005, 0.0, 0.005, 0.005, 0.005, 0.005, 0.005, 0.010]
    np.testing.assert_allclose(pair_margins(table, 0.005), want, rtol=0, atol=1e-15)
    # a pair near an end of the path keeps its contact margin
    near = np.zeros(11, dtype=bool)
    near[[1, 10]] = True
    got = near_end_margins(pair_margins(table), pair_margins(table, 0.005), near)
    want[1], want[10] = -TOL, 0.0
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-15)


def test_path_levels_add_the_reach_per_moving_body() -> None:
    base = np.array([-0.001, 0.005, 0.0, 0.010])
    n_moving = np.array([1, 1, 0, 2])
    got = path_margin_levels(base, n_moving, 0.01, np.array([0, 1, 4]))
    want = [
        [0.0, 0.005, 0.0, 0.010],  # level 0: the base, negative margins as 0
        [0.01, 0.015, 0.0, 0.030],  # one step either side per moving body
        [0.04, 0.045, 0.0, 0.090],  # four steps
    ]
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-15)


@pytest.mark.parametrize(
    ("distances", "margins", "flags"),
    [
        ([0.0, 0.002, 0.0005], [-0.001, 0.001, 0.0], [True, False, False]),
        ([0.0011, 0.001], [0.001, 0.001], [False, True]),
        ([], [], []),
    ],
)
def test_fixed_pairs_are_flagged_at_their_margin_or_closer(distances, margins, flags) -> None:
    got = fixed_pair_flags(np.array(distances, dtype=float), np.array(margins, dtype=float))
    np.testing.assert_array_equal(got, np.array(flags, dtype=bool))
    assert fixed_pairs_touch(np.array(distances), np.array(margins)) == any(flags)


def test_links_rest_on_the_table_when_no_joint_lifts_them_and_they_stand_on_it() -> None:
    # table top at 0.75, 5 cm thick: underside 0.70, a link may reach 1 cm below it
    bottom = np.array([0.70, 0.74, 0.5, 0.8, 0.685])
    fixed = np.array([True, True, True, False, True])
    got = resting_links(bottom, fixed, 0.75, 0.05)
    np.testing.assert_array_equal(got, [True, True, False, False, False])


def test_a_scene_checks_the_pairs_its_allowances_leave() -> None:
    """The scene's checker builds its table from the scene: a box meets every link until the
    gripper is allowed to touch it, then every link but the hand's; disallowing brings the
    same table back."""
    from thirdhand.execute import CollisionScene, Robot

    panda = Robot.load("panda", base_pose=([0.0, 0.0, 0.75], [0, 0, 0, 1]))
    scene = CollisionScene(panda)
    scene.add_box("box", ([0.5, 0.0, 1.0], [0, 0, 0, 1]), (0.05, 0.05, 0.05))
    links = [link.name for link in scene.checks.bodies.links]
    box = len(links)

    def met_by_box() -> list[str]:
        table = scene.checks.pair_table()
        return [links[a] for a, b in zip(table.first, table.second, strict=True) if b == box]

    assert met_by_box() == links
    before = scene.checks.pair_table()
    scene.allow(GRIPPER, "box")
    hand = set(panda.gripper_links)
    assert met_by_box() == [n for n in links if n not in hand] and hand & set(links)
    scene.disallow(GRIPPER, "box")
    assert scene.checks.pair_table() is before
    gm, _ = scene.to_pinocchio()
    assert len(gm.collisionPairs) == len(before)
