"""Order and part choice as planning: partial order, interchangeable parts, re-planning."""

from __future__ import annotations

import numpy as np
import pytest

from thirdhand import se3
from thirdhand.execute import Robot
from thirdhand.execute.executor import ExecutionOptions, Executor, StepPlan, StepReport
from thirdhand.execute.layout import make_workcell, start_layout
from thirdhand.execute.scene import CollisionScene, SceneError
from thirdhand.execute.step_order import (
    identical_parts,
    plan_binds_order,
    predecessors,
    slot_difficulty,
)
from thirdhand.execute.step_plan import SearchCounts
from thirdhand.execute.step_search import first_valid_ik
from thirdhand.task.stages import PlanBlock, Stages


@pytest.fixture(scope="module")
def chair():
    from thirdhand.synth import make_scene
    from thirdhand.synth.task import truth_task

    return truth_task(make_scene("chair", seed=0))


def test_identical_parts_are_the_legs(chair) -> None:
    same = identical_parts(chair)
    legs = sorted(o.name for o in chair.objects if o.name.startswith("leg"))
    assert len(legs) == 4
    for leg in legs:
        assert sorted(same[leg]) == legs
    assert same["back"] == ["back"]
    assert chair.constraints[0].parent not in same  # the base is nobody's child


def test_order_binds_only_parents_unless_several_demos(chair) -> None:
    ex_steps = [(i, s, next(c for c in chair.constraints if c.id == s.constraint))
                for i, s in enumerate(chair.plan)]  # fmt: skip
    free = predecessors(ex_steps, use_plan=False)
    assert all(not pre for pre in free.values())  # every part goes onto the base
    strict = predecessors(ex_steps, use_plan=True)
    ids = [c.id for _, _, c in ex_steps]
    for k, cid in enumerate(ids):
        assert strict[cid] == set(ids[:k])  # a total order, closed transitively
    one = chair.model_copy(update={"stages": Stages(plan=PlanBlock(n_demos=1))})
    two = chair.model_copy(update={"stages": Stages(plan=PlanBlock(n_demos=3))})
    assert not plan_binds_order(one, "auto") and plan_binds_order(two, "auto")
    assert plan_binds_order(one, "plan") and not plan_binds_order(two, "parents")
    with pytest.raises(SceneError, match="order 'random'"):
        plan_binds_order(one, "random")


def test_slot_difficulty_far_and_low_first() -> None:
    def at(x, z):
        t = np.eye(4)
        t[:3, 3] = [x, 0.0, z]
        return t

    assert slot_difficulty(at(0.6, 0.8), (0.0, 0.0), 0.75) > slot_difficulty(
        at(0.4, 0.8), (0.0, 0.0), 0.75
    )
    assert slot_difficulty(at(0.5, 0.78), (0.0, 0.0), 0.75) > slot_difficulty(
        at(0.5, 0.9), (0.0, 0.0), 0.75
    )


class _BoxedIn(Executor):
    """Planning stand-in: the ``boxed`` slot fails once any other slot is filled before it.

    Steps succeed without motions (their plans have no segments), so only the
    executor's choice of order, parts and re-planning is exercised here.
    """

    boxed = ""
    calls: list[tuple[str, str, int]]

    def plan_step(self, world, index, constraint, q_start, seed, part=None):
        filled = sum(1 for c, _ in self.calls_done if c != constraint.id)
        self.calls.append((constraint.id, part or constraint.child, filled))
        ok = constraint.id != self.boxed or filled == 0
        rep = StepReport(index, constraint.parent, part or constraint.child, constraint.id, ok,
                         "planned" if ok else "no reachable goal: boxed in")  # fmt: skip
        rep.tried = SearchCounts(grasps=3, grasps_reachable=1 if ok else 0, place_reachable=0)
        return StepPlan(rep)

    def _execute(self, world, plan, q, trajectory):
        self.calls_done.append((plan.report.constraint, plan.report.child))
        return q

    def new_world(self, poses=None):
        self.calls_done: list[tuple[str, str]] = []
        return super().new_world(poses)


def _boxed(chair, **options) -> _BoxedIn:
    cell = make_workcell(chair)
    robot = Robot.load("panda", base_pose=(cell.robot_base[:3, 3], [0.0, 0.0, 0.0, 1.0]))
    start = start_layout(chair, cell, 0)
    ex = _BoxedIn(robot, chair, cell, start, ExecutionOptions(**options))
    ex.calls = []
    return ex


def test_boxed_in_last_slot_solved_by_reordering(chair) -> None:
    # the learned order puts the boxed-in slot last, and it is not the one the
    # geometric ranking puts first: only re-planning can save it
    ex = _boxed(chair, order="plan")
    last = chair.plan[-2].constraint  # the last leg (the back's step comes after)
    ex.boxed = last
    res = ex.run_offline()
    assert not all(r.success for r in res.steps)  # the plan's order binds: it fails
    assert next(r for r in res.steps if r.constraint == last).status.endswith("boxed in")

    ex = _boxed(chair, order="parents")
    ex.boxed = last
    res = ex.run_offline()
    assert all(r.success for r in res.steps), [r.status for r in res.steps]
    assert res.steps[0].constraint == last  # done first
    assert next(c for c, _ in ex.calls_done) == last
    assert any(e.startswith(f"re-plan: {last} failed after") for e in res.events) or (
        ex.calls[0][0] == last
    )
    assert sorted(r.constraint for r in res.steps) == sorted(s.constraint for s in chair.plan)


def test_a_failing_part_is_replaced_by_an_identical_one(chair) -> None:
    leg_slot = next(c for c in chair.constraints if c.child == "leg1")

    def run(max_parts):
        ex = _boxed(chair, order="parents", max_parts=max_parts)

        def plan_step(world, index, constraint, q_start, seed, part=None):
            part = part or constraint.child
            ex.calls.append((constraint.id, part, 0))
            ok = not (part == "leg1" and constraint.id == leg_slot.id)  # its own slot fails
            rep = StepReport(index, constraint.parent, part, constraint.id, ok,
                             "planned" if ok else "no reachable grasp")  # fmt: skip
            rep.tried = SearchCounts(grasps=3, grasps_reachable=0)
            return StepPlan(rep)

        ex.plan_step = plan_step  # type: ignore[method-assign]
        return ex, ex.run_offline()

    # one part per slot: leg1's slot fails, even when planned first
    ex, res = run(1)
    by_slot = {r.constraint: r for r in res.steps}
    assert not by_slot[leg_slot.id].success
    ex, res = run(2)  # the slot takes another leg (re-planned with it first if none was free)
    # whether a re-plan is needed depends on where the layout puts the slot in the order
    assert all(e.startswith(f"re-plan: {leg_slot.id} failed") for e in res.events)
    assert (leg_slot.id, "leg1", 0) in ex.calls  # its own part was tried first and failed
    by_slot = {r.constraint: r for r in res.steps}
    assert all(r.success for r in res.steps), [r.status for r in res.steps]
    assert by_slot[leg_slot.id].child != "leg1"
    parts = [r.child for r in res.steps]
    assert len(set(parts)) == len(parts) and "leg1" in parts  # leg1 went into another slot
    assert ex.bind[leg_slot.id] == by_slot[leg_slot.id].child
    bound = {c.id: c.child for c in ex.bound_task().constraints}
    assert bound == {r.constraint: r.child for r in res.steps}


def test_ik_failures_say_unreachable_or_colliding_and_with_what() -> None:
    robot = Robot.load("panda", base_pose=([0.0, 0.0, 0.75], [0, 0, 0, 1]))
    scene = CollisionScene(robot)
    scene.add_table(height=0.75)
    down = np.diag([1.0, -1.0, -1.0, 1.0])
    far, inside, ok = down.copy(), down.copy(), down.copy()
    far[:3, 3] = [2.0, 0.0, 1.0]  # 2 m out: no start converges
    inside[:3, 3] = [0.5, 0.0, 0.70]  # 5 cm under the table top: converges, collides
    ok[:3, 3] = [0.5, 0.0, 1.0]
    why: dict = {}
    sols = first_valid_ik(robot, scene, np.stack([far, inside, ok]), robot.home, seed=0, why=why)
    assert sols[0] is None and sols[1] is None and sols[2] is not None
    assert why["ik_failed"] == 1 and why["in_collision"] == 1
    (a, b), _ = why["pairs"].most_common(1)[0]
    assert "table" in (a, b)


def test_roll_twins_dropped_and_end_grasps_kept() -> None:
    from thirdhand.execute.grasps import shape_grasps
    from thirdhand.execute.step_search import drop_twins

    all_ = shape_grasps([0.0, -0.02, -0.02], [0.28, 0.02, 0.02])
    kept = drop_twins(all_)
    assert len(all_) == 5 * 12 * 2 + 2 * 4 and len(kept) == 5 * 12 + 2 * 2
    assert sum(g.label == "end" for g in kept) == 4
    for i, a in enumerate(kept):  # no two kept grasps are half a turn apart
        for b in kept[i + 1 :]:
            same_place = np.linalg.norm(a.pose[:3, 3] - b.pose[:3, 3]) < 1e-3
            assert not (same_place and a.pose[:3, 2] @ b.pose[:3, 2] > 0.999
                        and a.pose[:3, 1] @ b.pose[:3, 1] < -0.999)  # fmt: skip


def test_grasps_ranked_by_reach_at_pick_and_place() -> None:
    from thirdhand.execute.grasps import shape_grasps
    from thirdhand.execute.step_search import drop_twins, rank_by_reach

    robot = Robot.load("panda", base_pose=([0.0, 0.0, 0.75], [0, 0, 0, 1]))
    scene = CollisionScene(robot)
    scene.add_table(height=0.75)
    lo, hi = np.array([0.0, -0.02, -0.02]), np.array([0.28, 0.02, 0.02])
    scene.add_box("leg", se3.pose_from_matrix(np.eye(4)), hi - lo)
    part = np.eye(4)
    part[:3, 3] = [0.45, -0.25, 0.77]  # lying on the table, its axis along x
    scene.set_object_pose("leg", se3.pose_from_matrix(part @ _centre(lo, hi)))
    goal = np.eye(4)
    goal[:3, :3] = [[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]  # standing up
    goal[:3, 3] = [0.5, 0.2, 0.78]
    grasps = drop_twins(shape_grasps(lo, hi))
    ranked, n_both = rank_by_reach(robot, scene, grasps, "leg", part, goal[None], robot.home,
                                   seed=0)  # fmt: skip
    assert sorted(map(id, ranked)) == sorted(map(id, grasps))
    assert 0 < n_both < len(grasps)
    # with many more restarts: the first ones reach both, the last reach no goal or no pick
    for g in ranked[:3]:
        for t in (part, goal):
            q = first_valid_ik(robot, scene, (t @ g.pose)[None], robot.home, seed=1)[0]
            assert q is not None
    g = ranked[-1]
    reach = [
        first_valid_ik(robot, scene, (t @ g.pose)[None], robot.home, seed=1)[0] is not None
        for t in (part, goal)
    ]
    assert not all(reach)


def _centre(lo, hi):
    t = np.eye(4)
    t[:3, 3] = (lo + hi) / 2
    return t
