"""The robot assist: fetch the next step's part and hold it where the person works.

Once the person has started (a part in hand or a step done: the first part is
theirs), when the plan's next step (an available step, :mod:`thirdhand.live.tracker`)
has no part in the person's hands, the simulated arm (the execution stage's
:class:`~thirdhand.execute.robot.Robot`, :class:`~thirdhand.execute.scene.CollisionScene`
and :func:`~thirdhand.execute.planner.plan_motion`) picks one of the step's
parts (one no hand has held yet, the nearest to the arm) with a top-down
grasp and brings it to a hand-over pose beside the assembly, on the arm's side:
just beyond the *reach of the finished assembly* (:func:`assembly_reach`, the
farthest corner of any part's box from the root with every plan step's part at
its learned pose: the sphere the person sweeps turning the assembly over), and
the arm's base beyond that, free to drive along a track there
(:mod:`thirdhand.live.base_track`) to a place from which the part is in reach. The
world it plans in holds the table, every other part at its tracked pose and the
person's tracked fingers as boxes of ``hand_size_m``.

Timing: the arm starts when the assist is decided (stream clock), spends the
measured planning time, waits for the base to finish a drive it is on, lets the base
drive (``base_speed``), then moves along the planned joint path at
``joint_speed`` rad/s (the largest joint's motion sets each segment's
duration), ``grasp_s`` to close the gripper. While it moves and while it holds
the part, the configuration it has at each latent step is checked against the
fingers and parts **as tracked at that moment** (they moved since planning):
every such configuration in collision is counted. The assist ends when a hand
takes a part of that step (the CRF's hand phases); its outcome is ``ready``
when the part was at the hand-over pose before that, else ``late``;
``unreachable`` / ``no path`` when the arm could not do it.

The recording does not know about the robot: the person still picks their own
part. What is measured is whether the robot's part would have been waiting.

:class:`RobotAssist` keeps the arm, its worlds, the planning thread and what happened;
each decision is a pure function of its own module: which part to fetch and when,
a retry, the end of an assist (:mod:`thirdhand.live.fetch`); where the base stands
(:mod:`thirdhand.live.base_place`); the grasp and the lift (:mod:`thirdhand.live.grasp`);
the hand-over (:mod:`thirdhand.live.handover`); the planning of a fetch
(:mod:`thirdhand.live.fetch_plan`) and its schedule (:mod:`thirdhand.live.schedule`).
"""

from __future__ import annotations

import functools
import math
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from thirdhand.arrays import BoolArray, FloatArray
from thirdhand.live.arm_world import ArmWorlds
from thirdhand.live.base_place import (
    away_from_person,
    base_distance,
    fetch_drives,
    first_fixed_place,
    first_station,
    fixed_places,
    standing,
    track_for,
)
from thirdhand.live.base_track import BaseTrack
from thirdhand.live.fetch import (
    FAILED,
    FailedFetch,
    Mounting,
    assist_end,
    failed_fetch,
    mounting_poses,
    next_fetch,
    person_started,
)
from thirdhand.live.fetch_plan import fetch_outcome, plan_fetch
from thirdhand.live.grasp import part_box
from thirdhand.live.handover import assembly_reach, handover_pose
from thirdhand.live.schedule import configuration_at, route_index, schedule_fetch
from thirdhand.live.tracker import PlanTracker
from thirdhand.segment.contact import body_box

if TYPE_CHECKING:
    from thirdhand.execute.robot import Robot
    from thirdhand.execute.scene import CollisionScene

Pose = tuple[FloatArray, FloatArray]


#: The arm plans this far from every tracked part and hand (their boxes grown by it), metres:
#: a path planned to touch nothing grazed a board lying flat whose tracked tilt jitters by
#: ±1° (7 mm at its edge) and was in collision at every other frame (research/notes/live.md).
PLAN_CLEARANCE_M = 0.005
#: The obstacles the arm plans around where the part being mounted may go (its box at each
#: free slot's learned pose in its parent, grown by a hand on every side): the person
#: brings it there.
MOUNTING = "being mounted"


@dataclass(frozen=True)
class AssistOptions:
    """How the simulated arm assists (defaults: what was measured on the synthetic chair).

    Attributes
    ----------
    robot : str
        ``"panda"``.
    handover_m : tuple of 3 floats
        Hand-over point relative to the root's first position: towards the arm beyond
        the finished assembly's reach (:func:`assembly_reach`), sideways, up, metres.
        Outside that sphere the person turning the assembly over does not sweep the
        arm and its part (research/notes/live.md: 0.3 m from the root, inside it, met the
        chair's legs).
    base_beyond_m : float
        The arm's base stands this far beyond the hand-over point, on the side away
        from the person, metres.
    joint_speed : float
        Largest joint speed of the executed motion, rad/s.
    grasp_s : float
        Seconds to close the gripper on the part.
    lift_m : float
        Straight lift after the grasp, metres; twice or three times it when the part
        still touches something there (:data:`LIFT_STEPS`).
    plan_time_s : float
        Time limit of each planning query, seconds.
    hand_size_m : float
        Side of the box that stands for each tracked finger, metres.
    part_size_m : float
        Side of the box of a part without a known bounding box, metres.
    wait_for_person : bool
        Fetch nothing until the person has a part in hand or a step is done: at the
        start the person takes the first part themselves, and an arm reaching into
        the parts at that moment meets their hand (research/notes/live.md).
    base_track_m : float
        Length of the straight track across the assembly's far side along which the
        arm's base moves (a mobile base, or an arm on a linear axis;
        :mod:`thirdhand.live.base_track`), metres; 0 fixes the base. From one place the
        Panda reaches two of the synthetic chair's four legs (research/notes/live.md).
    base_speed : float
        Speed of the base along its route, m/s.
    """

    robot: str = "panda"
    handover_m: tuple[float, float, float] = (0.07, 0.0, 0.35)
    base_beyond_m: float = 0.15
    joint_speed: float = 1.5
    grasp_s: float = 0.5
    lift_m: float = 0.06
    plan_time_s: float = 1.0
    hand_size_m: float = 0.06
    part_size_m: float = 0.05
    wait_for_person: bool = True
    base_track_m: float = 1.2
    base_speed: float = 0.5


@dataclass
class Assist:
    """One assist of the robot.

    Attributes
    ----------
    step : int
    part : str
    start_s, ready_s, end_s : float or None
        Stream clock: decided, part at the hand-over pose, a hand took a part of
        the step (None while unknown).
    outcome : str
    plan_ms : float
        Wall-clock planning time.
    checked, collisions : int
        Configurations checked along the execution against the tracked hands and
        parts, and how many of them collided.
    path : ndarray, shape (m, dof)
    times : ndarray, shape (m,)
        Stream time at which the arm reaches each waypoint.
    base_route : ndarray, shape (k, 3)
        The base's drive before the arm moves (world, metres; empty: it did not move).
    base_times : ndarray, shape (k,)
        Stream time at which the base is at each point of ``base_route``.
    grasp_index : int
        The waypoint of ``path`` at which the gripper closes (the next one ends the lift).
    resting : tuple of str
        What the part rested on when grasped (the table, parts against it): during the
        lift it may touch them.
    """

    step: int
    part: str
    start_s: float
    ready_s: float | None = None
    end_s: float | None = None
    outcome: str = "moving"
    status: str = ""
    plan_ms: float = 0.0
    checked: int = 0
    collisions: int = 0
    held_at_start: set[str] = field(default_factory=set)
    taken: str = ""
    hits: dict[str, int] = field(default_factory=dict)
    path: FloatArray = field(default_factory=lambda: np.zeros((0, 7)))
    times: FloatArray = field(default_factory=lambda: np.zeros(0))
    base_route: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    base_times: FloatArray = field(default_factory=lambda: np.zeros(0))
    grasp_index: int = 0
    resting: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """JSON-able record."""

        def r(v: float | None) -> float | None:
            return None if v is None else round(v, 4)

        return {
            "step": self.step + 1,
            "part": self.part,
            "start": r(self.start_s),
            "ready": r(self.ready_s),
            "end": r(self.end_s),
            "outcome": self.outcome,
            "taken": self.taken,
            "status": self.status,
            "plan_ms": round(self.plan_ms, 1),
            "checked": self.checked,
            "collisions": self.collisions,
            "colliding_pairs": self.hits,
            "base_travel_m": round(
                float(np.linalg.norm(np.diff(self.base_route, axis=0), axis=1).sum()), 3
            ),
        }


class RobotAssist:
    """The simulated arm that fetches parts, driven by the live loop.

    Parameters
    ----------
    names : sequence of str
        The stream's bodies (rows).
    kinds : sequence of str
        Their kinds (``part``, ``finger``...).
    meta : mapping
        The stream's metadata (``geometry`` boxes, ``table_z_m``).
    root : str
        The assembly's root part (where the person works).
    options : AssistOptions, optional
    reach_m : float, optional
        The finished assembly's reach from the root, metres (:func:`assembly_reach`;
        default: that of the root alone).

    Attributes
    ----------
    background : bool
        Plan each fetch in a background thread (default; a real-time stream), or in the
        caller's (a replay as fast as possible: :meth:`LiveLoop.run` sets it).
    """

    def __init__(
        self,
        names: Sequence[str],
        kinds: Sequence[str],
        meta: Mapping[str, Any],
        root: str,
        options: AssistOptions | None = None,
        *,
        reach_m: float | None = None,
    ) -> None:
        self.options = AssistOptions() if options is None else options
        self.names = list(names)
        self.parts = [i for i, k in enumerate(kinds) if k in ("part", "tool")]
        self.fingers = [i for i, k in enumerate(kinds) if k in ("finger", "hand")]
        self.root = self.names.index(root)
        self.table_z = float(meta.get("table_z_m", 0.75) or 0.75)
        self.boxes = {i: body_box(meta, self.names[i]) for i in self.parts}
        if reach_m is None:
            reach_m = assembly_reach((), self.names, meta, root, self.options.part_size_m)
        #: The finished assembly's reach from the root, metres.
        self.reach_m = reach_m
        self.assists: list[Assist] = []
        self.active: Assist | None = None
        #: Parts a hand has held since the stream began.
        self._handled: set[str] = set()
        #: Parts the arm could not fetch, by name.
        self._failed: dict[str, FailedFetch] = {}
        #: The arm and its worlds at every place the base has stood or been checked at.
        self._arm = ArmWorlds(
            self.options.robot,
            self.names,
            self.parts,
            self.fingers,
            self._box,
            table_z=self.table_z,
            hand_size_m=self.options.hand_size_m,
            clearance_m=PLAN_CLEARANCE_M,
        )
        self._carried = -1
        self._carried_pose: Pose = (np.zeros(3), np.zeros(4))
        self._handover: Pose | None = None
        #: The track the base moves along (None: a fixed base) and the station it stands at.
        self._base_track: BaseTrack | None = None
        self._station = 0.0
        #: The assist whose base is driving (it drives on when the assist has ended) and
        #: when the base is free again (stream clock): the next fetch waits for it.
        self._driving: Assist | None = None
        self._base_free_s = -math.inf
        #: Where the base stood when the arm was set up (world, metres).
        self.initial_base = np.zeros(3)
        #: The root's position then (world, metres): the centre of the sphere the person
        #: sweeps turning the assembly over.
        self._root0 = np.zeros(3)
        #: Plan in a background thread (a real-time stream: the frames keep coming while
        #: the arm's motion is planned); False plans in the caller's thread (a replay as
        #: fast as possible, whose clock the planning time is added to).
        self.background = True
        self._planner: threading.Thread | None = None
        self._error: BaseException | None = None

    # ----------------------------------------------------------------- state
    @property
    def robot(self) -> Robot | None:
        """The simulated arm, placed once the assembly's root was first tracked (else None)."""
        robot: Robot | None = self._arm.robot
        return robot

    @property
    def base(self) -> FloatArray:
        """Where the arm's base is now, shape (3,), world metres (during a drive: the last
        point of its route passed)."""
        return np.asarray(self._arm.base, dtype=np.float64).copy()

    @property
    def handover(self) -> Pose | None:
        """The hand-over tool pose, world (None until the arm is set up)."""
        return self._handover

    @property
    def driving(self) -> Assist | None:
        """The assist whose base is on its drive (it drives on once the assist ended)."""
        return self._driving

    @property
    def plan_scene(self) -> CollisionScene | None:
        """The world the arm plans in where its base is now: the tracked bodies grown by
        :data:`PLAN_CLEARANCE_M` on every side (None until the arm is set up)."""
        scene: CollisionScene | None = self._arm.planned
        return scene

    @property
    def planning(self) -> bool:
        """Whether a set-up or a plan started in the background has not been collected yet
        (by :meth:`update` once it is done, or :meth:`finish`)."""
        return self._planner is not None

    # ----------------------------------------------------------------- world
    def setup(self, pos: FloatArray, quat: FloatArray, valid: BoolArray) -> None:
        """Place the arm and build its worlds from the bodies as tracked (:meth:`update`
        does it, in the background on a real-time stream, once the root is tracked).

        The base stands beyond the assembly's reach on the far side from the person
        (:mod:`thirdhand.live.base_place`): a moving base at the station nearest the
        middle of its track, a fixed one at the first place turned about the root, where
        the arm at home touches nothing tracked. The hand-over pose lies between
        (:func:`~thirdhand.live.handover.handover_pose`).
        """
        opt = self.options
        root = pos[self.root]
        away = away_from_person(root, pos[self.fingers][valid[self.fingers]])
        near = base_distance(self.reach_m, opt.handover_m[0], opt.base_beyond_m)
        if opt.base_track_m > 0:
            track = track_for(root, away, near, opt.base_track_m, self.table_z)
            self._base_track = track
            self._station = first_station(track, self._clear_check(pos, quat, valid))
        else:

            def clear(base: FloatArray, turned: FloatArray) -> bool:
                return self._clear_at(base, pos, quat, valid, facing=-turned)

            _, away = first_fixed_place(fixed_places(root, away, near, self.table_z), clear)
        self.initial_base = self._arm.base.copy()
        self._root0 = root.copy()
        self._handover = handover_pose(root, away, self.reach_m, opt.handover_m)

    def _clear_check(
        self, pos: FloatArray, quat: FloatArray, valid: BoolArray
    ) -> Callable[[FloatArray], bool]:
        """:meth:`_clear_at` of the bodies ``pos``, ``quat``, ``valid`` as a function of the
        base's position (3,)."""
        return functools.partial(self._clear_at, pos=pos, quat=quat, valid=valid)

    def _clear_at(
        self,
        base: FloatArray,
        pos: FloatArray,
        quat: FloatArray,
        valid: BoolArray,
        facing: FloatArray | None = None,
    ) -> bool:
        """Stand at ``base`` (:meth:`_stand`); whether the arm at home touches nothing there
        in the world planned in."""
        self._stand(base, pos, quat, valid, facing)
        return self._arm.home_clear()

    def _stand(
        self,
        base: FloatArray,
        pos: FloatArray,
        quat: FloatArray,
        valid: BoolArray,
        facing: FloatArray | None = None,
    ) -> None:
        """Make the arm and both worlds those of the base standing at ``base`` (3,), world
        (:meth:`ArmWorlds.stand`); ``facing`` (2,): the base's horizontal x axis (default:
        towards the assembly, along the track's)."""

        def base_quat() -> FloatArray:
            if facing is None:
                assert self._base_track is not None
                return self._base_track.quat
            yaw = math.atan2(float(facing[1]), float(facing[0]))
            return np.array([0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)])

        self._arm.stand(base, base_quat, pos, quat, valid)

    def _box(self, i: int) -> tuple[FloatArray, FloatArray]:
        """Box centre (in the part frame) and sides of the part of row ``i``, metres."""
        return part_box(self.boxes.get(i), self.options.part_size_m)

    # ----------------------------------------------------------------- loop
    def update(
        self,
        t: float,
        pos: FloatArray,
        quat: FloatArray,
        valid: BoolArray,
        tracker: PlanTracker,
        holding: Mapping[tuple[str, str], bool],
    ) -> None:
        """One latent step: start, follow or end an assist."""
        held = {obj for (_, obj), h in holding.items() if h}
        self._handled |= held
        used = tracker.used_children()
        a = self.active
        self._raise_error()
        if self._planner is not None:
            # set up or planning in the background: the arm and the scene are that
            # thread's until it is done
            if self._planner.is_alive():
                if a is not None and a.end_s is None:
                    self._end(a, t, held, used, tracker)
                return
            self._planner = None
            if a is not None and a.end_s is not None:  # taken while it was planned
                self._release()
                self.active = None
                return
        if self._arm.robot is None:
            if not valid[self.root]:
                return
            args = (pos.copy(), quat.copy(), valid.copy())
            if self.background:  # loading the arm and its world takes ~0.2 s
                self._in_background(self.setup, args, "thirdhand-assist-setup")
                return
            self.setup(*args)
        self._drive(t, pos, quat, valid)
        if a is not None and a.outcome in FAILED:
            # the arm could not fetch that part: another one of the step may do, and
            # this one again once it was moved
            a.end_s = t
            where = self._carried_pose[0].copy()  # where it was tried
            rows = (*self.parts, *self.fingers)
            self._failed[a.part] = failed_fetch(t, where, pos, valid, rows, self._carried)
            self.active = None
            return
        if a is not None:
            if self._end(a, t, held, used, tracker):
                self._release()
                self.active = None
            else:
                self._check(a, t, pos, quat, valid)
            return
        if self.options.wait_for_person and not person_started(held, tracker):
            return  # the person starts the first step with a part of their own
        here = standing(self._base_track, self._station, self._arm.base)
        choice = next_fetch(
            tracker,
            self.names,
            handled=self._handled,
            failed=self._failed,
            t=t,
            pos=pos,
            valid=valid,
            base=here,
        )
        if choice is None:
            return
        step, part = choice
        mounting = mounting_poses(
            tracker, self.names, self.parts, held=held, pos=pos, quat=quat, valid=valid
        )
        self.start_fetch(t, step, part, pos, quat, valid, mounting)
        assert self.active is not None
        self.active.held_at_start = set(held)

    def _drive(self, t: float, pos: FloatArray, quat: FloatArray, valid: BoolArray) -> None:
        """Follow the base's drive at ``t``: the arm at home with the base at the last point
        of the route passed is checked against the hands and parts now (counted in the
        assist that drives, even once it has ended: the base finishes its drive)."""
        d = self._driving
        if d is None or t < d.base_times[0]:
            return
        if t >= d.base_times[-1]:
            self._stand(d.base_route[-1], pos, quat, valid)
            self._driving = None
            return
        self._stand(d.base_route[route_index(d.base_times, t)], pos, quat, valid)
        d.checked += 1
        self._count(d, self._arm.robot.home)

    def _end(
        self, a: Assist, t: float, held: set[str], used: set[str], tracker: PlanTracker
    ) -> bool:
        """End ``a`` at ``t`` if it ends (:func:`~thirdhand.live.fetch.assist_end`); whether
        it did."""
        end = assist_end(
            step=a.step,
            part=a.part,
            held_at_start=a.held_at_start,
            ready_s=a.ready_s,
            outcome=a.outcome,
            t=t,
            held=held,
            used=used,
            tracker=tracker,
        )
        if end is None:
            return False
        a.end_s = t
        a.taken = end.taken
        a.outcome = end.outcome
        return True

    def _in_background(self, target: Any, args: tuple[Any, ...], name: str) -> None:
        """Run ``target(*args)`` in :attr:`_planner`; an error it raises is raised again
        by the next :meth:`update` (or :meth:`finish`), in the loop's thread."""

        def run() -> None:
            try:
                target(*args)
            except BaseException as exc:  # handed to the loop's thread
                self._error = exc

        self._planner = threading.Thread(target=run, name=name, daemon=True)
        self._planner.start()

    def _raise_error(self) -> None:
        if self._error is not None:
            exc, self._error = self._error, None
            raise exc

    def finish(self) -> None:
        """Wait for a planning still running in the background (the end of a stream)."""
        if self._planner is not None:
            self._planner.join()
            self._planner = None
        self._raise_error()

    def start_fetch(
        self,
        t: float,
        step: int,
        part: int,
        pos: FloatArray,
        quat: FloatArray,
        valid: BoolArray,
        mounting: Sequence[Mounting] = (),
    ) -> None:
        """Start the fetch of the part of row ``part`` for ``step`` at ``t`` (:attr:`active`);
        plan it (in the background when :attr:`background`) around ``mounting``
        (:func:`~thirdhand.live.fetch.mounting_poses`). :meth:`update` decides it
        (:func:`~thirdhand.live.fetch.next_fetch`) once the arm is set up."""
        a = Assist(step=step, part=self.names[part], start_s=t)
        self.assists.append(a)
        self.active = a
        w0 = time.perf_counter()
        self._arm.track(pos, quat, valid, skip=-1)
        self._carried = part
        self._carried_pose = (pos[part].copy(), quat[part].copy())
        args = (a, t, part, pos.copy(), quat.copy(), valid.copy(), w0, tuple(mounting))
        if self.background:
            self._in_background(self._plan, args, "thirdhand-assist-plan")
        else:
            self._plan(*args)

    def _plan(
        self,
        a: Assist,
        t: float,
        part: int,
        pos: FloatArray,
        quat: FloatArray,
        valid: BoolArray,
        w0: float,
        mounting: Sequence[Mounting],
    ) -> None:
        """Plan the fetch of ``part`` decided at ``t`` (stream clock) and schedule it in ``a``.

        The schedule starts when the planning ends: ``t`` plus the planning's wall time.
        The arm plans around where the part the person is mounting may go
        (``mounting``): a path planned through that place meets the part and the hand
        that bring it there (chair 19, research/notes/live.md). A moving base first tries the
        stations nearest the part it can drive to
        (:func:`~thirdhand.live.base_place.fetch_drives`); the first from which the fetch
        can be done is kept, and the base drives there (``a.base_route``) before the arm
        moves.
        """
        here = standing(self._base_track, self._station, self._arm.base)
        drives = [(self._station, np.zeros((0, 3)))]
        if self._base_track is not None:
            self._stand(here, pos, quat, valid)
            drives = self._drives(part, pos, quat, valid)
        ghosts = [f"{MOUNTING} {k}" for k in range(len(mounting))]
        grow = 2.0 * (PLAN_CLEARANCE_M + self.options.hand_size_m)
        for station, route in drives:
            if len(route):
                self._stand(route[-1], pos, quat, valid)
            scene = self._arm.planned
            for ghost, (row, where, turn) in zip(ghosts, mounting, strict=True):
                c, size = self._box(row)
                scene.add_object(ghost, (where, turn), size=size + grow, box_center=c)
            try:
                self._plan_fetch(a, t, part, pos, quat, w0, route)
            finally:
                for ghost in ghosts:
                    scene.remove_object(ghost)
            if a.outcome not in FAILED:
                if len(a.base_route):
                    self._station = station
                    self._driving = a
                    self._base_free_s = float(a.base_times[-1])
                return
        if drives and len(drives[-1][1]):  # nothing worked: the base stays where it is
            self._stand(here, pos, quat, valid)
        if not drives:
            a.outcome, a.status = "unreachable", "no station to drive to"

    def _drives(
        self, part: int, pos: FloatArray, quat: FloatArray, valid: BoolArray
    ) -> list[tuple[float, FloatArray]]:
        """:func:`~thirdhand.live.base_place.fetch_drives` to ``part`` from where the base
        stands, checked in the world planned in; leaves the base where it was."""
        track = self._base_track
        assert track is not None
        here = self._arm.base.copy()
        try:
            clear = self._clear_check(pos, quat, valid)
            return fetch_drives(track, self._station, here, pos[part][:2], clear)
        finally:
            self._stand(here, pos, quat, valid)

    def _plan_fetch(
        self,
        a: Assist,
        t: float,
        part: int,
        pos: FloatArray,
        quat: FloatArray,
        w0: float,
        route: FloatArray,
    ) -> None:
        """:meth:`_plan` in the world as it is (the part being mounted added, if any), the
        base at the end of ``route`` (m, 3), to which it drives first (m > 1):
        :func:`~thirdhand.live.fetch_plan.plan_fetch`, then
        :func:`~thirdhand.live.schedule.schedule_fetch`."""
        opt = self.options
        name = self.names[part]
        self._arm.planned.allow(name, "gripper")
        self._arm.checked.allow(name, "gripper")
        assert self._handover is not None
        plan = plan_fetch(
            self._arm.robot,
            self._arm.planned,
            name=name,
            part_pose=(pos[part], quat[part]),
            box=self._box(part),
            handover=self._handover,
            root0=self._root0,
            hands={self.names[i] for i in self.fingers},
            lift_m=opt.lift_m,
            plan_time_s=opt.plan_time_s,
        )
        a.resting = plan.resting
        a.plan_ms = 1e3 * (time.perf_counter() - w0)
        a.outcome, a.status = "moving", ""  # this try's, not an earlier station's
        failed = fetch_outcome(plan)
        if failed is not None:
            a.outcome, a.status = failed
            return
        assert plan.to_grasp is not None and plan.to_grasp.path is not None
        assert plan.to_hand is not None and plan.to_hand.path is not None
        s = schedule_fetch(
            plan.to_grasp.path,
            plan.to_hand.path,
            start_s=t + a.plan_ms / 1e3,
            base_free_s=None if self._base_track is None else self._base_free_s,
            route=route,
            joint_speed=opt.joint_speed,
            grasp_s=opt.grasp_s,
            base_speed=opt.base_speed,
        )
        a.path, a.times, a.grasp_index = s.path, s.times, s.grasp_index
        a.base_route, a.base_times = s.base_route, s.base_times
        a.ready_s = s.ready_s

    def _check(
        self, a: Assist, t: float, pos: FloatArray, quat: FloatArray, valid: BoolArray
    ) -> None:
        """Check the arm's configuration at ``t`` against the hands and parts now (the base's
        drive before it: :meth:`_drive`)."""
        if a.path.shape[0] == 0 or t < a.times[0]:
            return
        k, q = configuration_at(a.path, a.times, t)
        carrying = k >= a.grasp_index
        name = self.names[self._carried]
        # During the straight lift the part may still touch what it rested on.
        lifting = k == a.grasp_index
        checked = self._arm.checked
        for o in a.resting:
            if lifting:
                checked.allow(name, o)
            else:
                checked.disallow(name, o)
        if carrying and not self._arm.attached:
            self._arm.attach(name, self._carried_pose, a.path[a.grasp_index])
        self._arm.track(pos, quat, valid, skip=self._carried)
        a.checked += 1
        self._count(a, q)

    def _count(self, a: Assist, q: FloatArray) -> None:
        """Count ``q`` in ``a`` if it is in collision in the world checked, with what it hit."""
        checked = self._arm.checked
        if not checked.is_valid(q):
            a.collisions += 1
            for pair in checked.collisions(q):
                key = " - ".join(pair)
                a.hits[key] = a.hits.get(key, 0) + 1

    def _release(self) -> None:
        """The person took a part: the arm lets go (the part leaves the simulated world)."""
        self._arm.release(self.names[self._carried])


__all__ = ["PLAN_CLEARANCE_M", "Assist", "AssistOptions", "RobotAssist"]
