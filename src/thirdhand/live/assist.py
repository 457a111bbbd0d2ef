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
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from thirdhand import se3
from thirdhand.arrays import BoolArray, FloatArray
from thirdhand.live.base_track import RETREATS_M, BaseTrack, route_times
from thirdhand.live.state import Slot
from thirdhand.live.tracker import PlanTracker
from thirdhand.segment.contact import body_box, box_corners

if TYPE_CHECKING:
    from thirdhand.execute.robot import Robot


#: A grasp comes from above when the tool's approach axis has this cosine with straight down.
DOWN_COS = 0.7
#: How much less deep the second try of each grasp from above goes, metres.
SHALLOWER_M = 0.01
#: Most grasp poses tried per assist (each one an IK search).
MAX_GRASPS = 16
#: How far above the hand-over pose its second set of tries is, metres.
HANDOVER_RAISE_M = 0.15
#: A moving base tries the fetch from this many stations at most, the nearest the part first.
MAX_STATIONS = 3
#: Outcomes of a fetch the arm could not do; the assist ends at once and another part is tried.
FAILED = ("unreachable", "no path")
#: The straight lift after a grasp: ``lift_m`` times the first of these that leaves the part
#: touching nothing (two legs lying side by side, tilted, meet 6 cm up).
LIFT_STEPS = (1, 2, 3)
#: A part the arm could not fetch is tried again once it, or a hand or part that was within
#: :data:`RETRY_NEAR_M` of it, moved this far, metres (a hand working beside it, a part
#: lying against it, that blocked its grasp or its lift), and not before
#: :data:`RETRY_AFTER_S` (a hand moving about it would have it planned at every step).
RETRY_MOVED_M = 0.05
RETRY_NEAR_M = 0.3
RETRY_AFTER_S = 0.5
#: The arm plans this far from every tracked part and hand (their boxes grown by it), metres:
#: a path planned to touch nothing grazed a board lying flat whose tracked tilt jitters by
#: ±1° (7 mm at its edge) and was in collision at every other frame (docs/live.md).
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
        arm and its part (docs/live.md: 0.3 m from the root, inside it, met the
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
        the parts at that moment meets their hand (docs/live.md).
    base_track_m : float
        Length of the straight track across the assembly's far side along which the
        arm's base moves (a mobile base, or an arm on a linear axis;
        :mod:`thirdhand.live.base_track`), metres; 0 fixes the base. From one place the
        Panda reaches two of the synthetic chair's four legs (docs/live.md).
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
        #: Parts the arm could not fetch: when, where they were then, and where the hands
        #: and parts near them were (row -> position).
        self._failed: dict[str, tuple[float, FloatArray, dict[int, FloatArray]]] = {}
        self._scene: Any = None
        self._plan_scene: Any = None
        self._attached = False
        self._carried = -1
        self._grasp_index = 0
        #: What the carried part rested on when grasped (the table, parts against it).
        self._resting: tuple[str, ...] = ()
        self._carried_pose: tuple[FloatArray, FloatArray] = (np.zeros(3), np.zeros(4))
        self._robot: Any = None
        self._base = np.zeros(3)
        self._handover: tuple[FloatArray, FloatArray] | None = None
        #: The track the base moves along (None: a fixed base), the station it stands at,
        #: and the arm and both worlds at every place it has stood or been checked at
        #: (key: its x, y in millimetres).
        self._base_track: BaseTrack | None = None
        self._station = 0.0
        self._places: dict[tuple[int, int], tuple[Any, Any, Any]] = {}
        self._place: tuple[int, int] | None = None
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

    # ----------------------------------------------------------------- world
    @property
    def robot(self) -> Robot | None:
        """The simulated arm, placed once the assembly's root was first tracked (else None)."""
        robot: Robot | None = self._robot
        return robot

    def _box(self, i: int) -> tuple[FloatArray, FloatArray]:
        """Box centre (in the part frame) and sides, metres."""
        b = self.boxes.get(i)
        if b is None:
            s = self.options.part_size_m
            return np.zeros(3), np.full(3, s)
        lo, hi = b
        return 0.5 * (lo + hi), np.maximum(hi - lo, 1e-3)

    def _setup(self, pos: FloatArray, quat: FloatArray, valid: BoolArray) -> None:
        opt = self.options
        root = pos[self.root]
        hands = pos[self.fingers][valid[self.fingers]]
        person = hands.mean(axis=0) if len(hands) else root - np.array([0.0, 0.5, 0.0])
        away = root[:2] - person[:2]
        away = away / max(float(np.linalg.norm(away)), 1e-9)
        near = self.reach_m + opt.handover_m[0] + opt.base_beyond_m
        if opt.base_track_m > 0:
            # A moving base: the station nearest the middle of its track where the arm
            # at home touches nothing tracked.
            track = BaseTrack(root[:2] + near * away, away, opt.base_track_m / 2.0, self.table_z)
            self._base_track = track
            for s in track.stations():
                self._stand(track.position(s), pos, quat, valid)
                if self._plan_scene.is_valid(self._robot.home):
                    break
            self._station = float(s)
        else:
            # A fixed base: the first pose, turning about the root from the far side,
            # where the arm at home touches nothing tracked.
            turned = away
            for ang in (0.0, 0.5, -0.5, 1.0, -1.0, 1.4, -1.4):
                c, sn = math.cos(ang), math.sin(ang)
                turned = np.array([c * away[0] - sn * away[1], sn * away[0] + c * away[1]])
                for dist in (near, near + 0.1):
                    base = np.array([*(root[:2] + dist * turned), self.table_z])
                    self._stand(base, pos, quat, valid, facing=-turned)
                    if self._plan_scene.is_valid(self._robot.home):
                        break
                else:
                    continue
                break
            away = turned
        self.initial_base = self._base.copy()
        self._root0 = root.copy()
        side = np.array([-away[1], away[0]])
        up, toward, lateral = opt.handover_m[2], self.reach_m + opt.handover_m[0], opt.handover_m[1]
        hp = np.array([*(root[:2] + toward * away + lateral * side), root[2] + up])
        # Hand-over: gripper pointing down, its x along the arm's reach.
        self._handover = (hp, _down_quat(away))

    def _stand(
        self,
        base: FloatArray,
        pos: FloatArray,
        quat: FloatArray,
        valid: BoolArray,
        facing: FloatArray | None = None,
    ) -> None:
        """Make the arm and both worlds those of the base standing at ``base`` (3,), world.

        ``facing`` (2,): the base's horizontal x axis (default: towards the assembly,
        along the track's). An arm and its worlds are built once per place and kept;
        the tracked bodies are moved to ``pos``, ``quat`` (where ``valid``) when the base
        changes place.
        """
        from thirdhand.execute.robot import Robot

        key = (round(1e3 * float(base[0])), round(1e3 * float(base[1])))
        if key == self._place:
            return
        self._place = key
        if key in self._places:
            self._robot, self._scene, self._plan_scene = self._places[key]
            self._base = np.asarray(base, dtype=np.float64).copy()
            self._track(pos, quat, valid, skip=-1)
            return
        if facing is None:
            assert self._base_track is not None
            base_q = self._base_track.quat
        else:
            yaw = math.atan2(float(facing[1]), float(facing[0]))
            base_q = np.array([0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)])
        self._robot = Robot.load(self.options.robot, base_pose=(base, base_q))
        self._base = np.asarray(base, dtype=np.float64).copy()
        self._build_scene(pos, quat)
        self._places[key] = (self._robot, self._scene, self._plan_scene)

    def _build_scene(self, pos: FloatArray, quat: FloatArray) -> None:
        """The world checked (:attr:`_scene`: the tracked boxes) and the one planned in
        (:attr:`_plan_scene`: the same boxes grown by :data:`PLAN_CLEARANCE_M` on every
        side, so that a path grazing a part does not collide with it at its next, noisy,
        tracked pose)."""
        from thirdhand.execute.scene import CollisionScene

        grow = 2.0 * PLAN_CLEARANCE_M
        scenes = []
        for extra in (0.0, grow):
            scene = CollisionScene(self._robot)
            centre = (float(self._base[0]), float(self._base[1]))
            scene.add_table(height=self.table_z, center=centre)
            ident = np.array([0.0, 0.0, 0.0, 1.0])
            for i in self.parts:
                c, size = self._box(i)
                p = pos[i] if np.all(np.isfinite(pos[i])) else np.array([0.0, 0.0, -10.0])
                q = quat[i] if np.all(np.isfinite(quat[i])) else ident
                scene.add_object(self.names[i], (p, q), size=size + extra, box_center=c)
            s = self.options.hand_size_m + extra
            for i in self.fingers:
                p = pos[i] if np.all(np.isfinite(pos[i])) else np.array([0.0, 0.0, -10.0])
                scene.add_box(self.names[i], (p, ident), (s, s, s))
            scenes.append(scene)
        self._scene, self._plan_scene = scenes
        self._attached = False

    def _track(self, pos: FloatArray, quat: FloatArray, valid: BoolArray, skip: int) -> None:
        """Move every tracked body of both worlds to its pose now (the last one when not seen)."""
        ident = np.array([0.0, 0.0, 0.0, 1.0])
        for scene in (self._scene, self._plan_scene):
            for i in self.parts:
                if i != skip and valid[i]:
                    scene.set_object_pose(self.names[i], (pos[i], quat[i]))
            for i in self.fingers:
                if valid[i]:
                    scene.set_object_pose(self.names[i], (pos[i], ident))

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
                    self._ends(a, t, held, used, tracker)
                return
            self._planner = None
            if a is not None and a.end_s is not None:  # taken while it was planned
                self._release()
                self.active = None
                return
        if self._robot is None:
            if not valid[self.root]:
                return
            args = (pos.copy(), quat.copy(), valid.copy())
            if self.background:  # loading the arm and its world takes ~0.2 s
                self._in_background(self._setup, args, "thirdhand-assist-setup")
                return
            self._setup(*args)
        self._drive(t, pos, quat, valid)
        if a is not None and a.outcome in FAILED:
            # the arm could not fetch that part: another one of the step may do, and
            # this one again once it was moved
            a.end_s = t
            where = self._carried_pose[0].copy()  # where it was tried
            near = {
                i: pos[i].copy()
                for i in (*self.parts, *self.fingers)
                if i != self._carried
                and valid[i]
                and float(np.linalg.norm(pos[i] - where)) < RETRY_NEAR_M
            }
            self._failed[a.part] = (t, where, near)
            self.active = None
            return
        if a is not None:
            if self._ends(a, t, held, used, tracker):
                self._release()
                self.active = None
            else:
                self._check(a, t, pos, quat, valid)
            return
        started = held or tracker.current is not None or tracker.done
        if self.options.wait_for_person and not started:
            return  # the person starts the first step with a part of their own
        # The next part the person will need: the first step not done other than the one
        # in progress, that the plan allows now or once the one in progress is done (the
        # back of a chair waits for its legs: fetched at once, it would be held at the
        # hand-over for a minute, and the arm could fetch nothing else), with a part no
        # hand has held yet (one the person took is theirs: put down a moment while they
        # mount it, it is not fetched from under their hands).
        for step in tracker.coming():
            if step == tracker.current:
                continue
            cands = [c for c in tracker.candidates_for(step) if c not in self._handled]
            idx = [
                i
                for i in (self.names.index(c) for c in cands)
                if valid[i] and self._may_retry(i, t, pos, valid)
            ]
            if not idx:
                continue
            part = min(idx, key=lambda i: self._distance(pos[i]))
            mounting = self._mounting_poses(tracker, held, pos, quat, valid)
            self._start(t, step, part, pos, quat, valid, mounting)
            assert self.active is not None
            self.active.held_at_start = set(held)
            return

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
        k = int(np.searchsorted(d.base_times, t, side="right")) - 1
        self._stand(d.base_route[k], pos, quat, valid)
        d.checked += 1
        self._count(d, self._robot.home)

    def _standing(self) -> FloatArray:
        """Where the base stands (3,), world metres; a moving base: once its drive is done."""
        if self._base_track is None:
            return self._base.copy()
        return self._base_track.position(self._station)

    def _distance(self, p: FloatArray) -> float:
        """Horizontal distance from ``p`` (3,) to where the base stands (:meth:`_standing`),
        metres: the part nearest it is fetched first, so that the base drives only for a
        part out of the arm's reach from there."""
        return float(np.linalg.norm(p[:2] - self._standing()[:2]))

    def _may_retry(self, part: int, t: float, pos: FloatArray, valid: BoolArray) -> bool:
        """Whether the part of row ``part`` may be fetched at ``t`` (``pos``, ``valid``: every
        body now): never failed, or since it failed (at least :data:`RETRY_AFTER_S` ago)
        it or a hand or part that was near it has moved :data:`RETRY_MOVED_M`."""
        failed = self._failed.get(self.names[part])
        if failed is None:
            return True
        when, where, near = failed
        if t - when < RETRY_AFTER_S:
            return False
        moved = [(part, where), *((i, p) for i, p in near.items() if valid[i])]
        return any(float(np.linalg.norm(pos[i] - p)) > RETRY_MOVED_M for i, p in moved)

    def _ends(
        self, a: Assist, t: float, held: set[str], used: set[str], tracker: PlanTracker
    ) -> bool:
        """Whether ``a`` ends at ``t`` (a hand took a part of its kind, or none is needed)."""
        # Interchangeable parts: the robot's part serves whichever step of its kind
        # comes next; the assist ends when a hand takes a new part of that kind.
        parts = set(tracker.candidates_for(a.step)) | {a.part}
        taken = (held & parts) - a.held_at_start - used
        needed = any(
            a.part in tracker.candidates_for(i)
            for i in range(len(tracker.slots))
            if i not in tracker.done
        )
        if needed and not taken:
            return False
        a.end_s = t
        a.taken = ", ".join(sorted(taken))
        if a.outcome == "moving":
            a.outcome = "ready" if a.ready_s is not None and a.ready_s <= t else "late"
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

    def _mounting_poses(
        self,
        tracker: PlanTracker,
        held: set[str],
        pos: FloatArray,
        quat: FloatArray,
        valid: BoolArray,
    ) -> list[tuple[int, FloatArray, FloatArray]]:
        """Where the part the person is mounting may go: ``(row, position, quaternion)`` each.

        While a step is in progress (:attr:`PlanTracker.current`), a part a hand holds
        that no done step uses, at the learned pose in its parent (as tracked now, world
        frame) of every step not done that it may fill and that may come next
        (:meth:`PlanTracker.coming`): an interchangeable leg may go to any free corner.
        Empty when no step is in progress.
        """
        if tracker.current is None:
            return []
        used = tracker.used_children()
        out = []
        for step in tracker.coming():
            slot = tracker.slots[step]
            for p, c in slot.candidates:
                name = self.names[c]
                if name in held and name not in used and valid[p] and c in self.parts:
                    where = pos[p] + se3.quat_rotate(quat[p], slot.pos)
                    out.append((c, where, np.asarray(se3.quat_multiply(quat[p], slot.quat))))
        return out

    def _start(
        self,
        t: float,
        step: int,
        part: int,
        pos: FloatArray,
        quat: FloatArray,
        valid: BoolArray,
        mounting: Sequence[tuple[int, FloatArray, FloatArray]] = (),
    ) -> None:
        """Start the fetch of ``part`` for ``step`` at ``t``; plan it (in the background on a
        real-time stream) around ``mounting`` (:meth:`_mounting_poses`)."""
        a = Assist(step=step, part=self.names[part], start_s=t)
        self.assists.append(a)
        self.active = a
        w0 = time.perf_counter()
        self._track(pos, quat, valid, skip=-1)
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
        mounting: Sequence[tuple[int, FloatArray, FloatArray]],
    ) -> None:
        """Plan the fetch of ``part`` decided at ``t`` (stream clock) and schedule it in ``a``.

        The schedule starts when the planning ends: ``t`` plus the planning's wall time.
        The arm plans around where the part the person is mounting may go
        (:meth:`_mounting_poses`): a path planned through that place meets the part and the
        hand that bring it there (chair 19, docs/live.md). A moving base first tries the
        :data:`MAX_STATIONS` stations nearest the part it can drive to (:meth:`_drives`);
        the first from which the fetch can be done is kept, and the base drives there
        (``a.base_route``) before the arm moves.
        """
        here = self._standing()
        drives = [(self._station, np.zeros((0, 3)))]
        if self._base_track is not None:
            self._stand(here, pos, quat, valid)
            drives = self._drives(part, pos, quat, valid)
        ghosts = [f"{MOUNTING} {k}" for k in range(len(mounting))]
        grow = 2.0 * (PLAN_CLEARANCE_M + self.options.hand_size_m)
        for station, route in drives:
            if len(route):
                self._stand(route[-1], pos, quat, valid)
            scene = self._plan_scene
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
        """The station offsets and the base's routes (each (m, 3), world; one row: it stays)
        to the :data:`MAX_STATIONS` stations nearest
        ``part`` at which the arm at home touches nothing tracked and to which it can drive
        touching nothing (checked every :data:`~thirdhand.live.base_track.STATION_STEP_M`,
        straight along the track or back from it by each of
        :data:`~thirdhand.live.base_track.RETREATS_M` in turn). Leaves the base where it was.
        """
        track = self._base_track
        assert track is not None
        here = self._base.copy()
        out: list[tuple[float, FloatArray]] = []
        try:
            for s in track.by_distance(pos[part][:2]):
                if len(out) == MAX_STATIONS:
                    break
                if abs(s - self._station) < 1e-9:
                    out.append((self._station, here[None]))
                    continue
                for back in RETREATS_M:
                    route = track.route(self._station, float(s), back)
                    if self._clear(route[1:], pos, quat, valid):
                        out.append((float(s), route))
                        break
        finally:
            self._stand(here, pos, quat, valid)
        return out

    def _clear(
        self, route: FloatArray, pos: FloatArray, quat: FloatArray, valid: BoolArray
    ) -> bool:
        """Whether the arm at home touches nothing tracked with its base at every point of
        ``route`` (m, 3), in the world planned in (tracked bodies grown by
        :data:`PLAN_CLEARANCE_M`). The last point first: most routes fail there."""
        for p in route[::-1]:
            self._stand(p, pos, quat, valid)
            if not self._plan_scene.is_valid(self._robot.home):
                return False
        return True

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
        base at the end of ``route`` (m, 3), to which it drives first (m > 1)."""
        from thirdhand.execute.planner import plan_motion

        opt = self.options
        scene = self._plan_scene
        home = self._robot.home
        name = self.names[part]
        scene.allow(name, "gripper")
        self._scene.allow(name, "gripper")
        q_grasp = q_lift = None
        self._resting = ()
        for target in self._grasp_targets(part, pos, quat, self._top_grasp(part, pos, quat)):
            q_grasp = self._robot.ik(target, home, seed=0, accept=scene.is_valid)
            if q_grasp is not None:
                break
        r1 = r2 = None
        q_hand = None
        if q_grasp is not None:
            r1 = plan_motion(
                self._robot,
                scene,
                home,
                q_grasp,
                time_limit=opt.plan_time_s,
                seed=0,
                simplify=True,
            )
            if r1.success:
                # A straight lift first, the only motion in which the part may touch what
                # it rests on (the table, parts lying against it), then a planned path.
                scene.attach(name, q_grasp)
                self._resting = self._resting_on(scene, name, q_grasp)
                q_lift = self._lift_clear(scene, name, q_grasp, self._resting)
                assert self._handover is not None
                if q_lift is not None:
                    t_tool = se3.matrix_from_pose(*self._robot.fk(q_grasp))
                    held = np.linalg.inv(t_tool) @ se3.matrix_from_pose(pos[part], quat[part])
                    targets = self._held_clear(part, held)
                    for target in targets:
                        q_hand = self._robot.ik(
                            target, q_lift, seed=0, n_restarts=16, accept=scene.is_valid
                        )
                        if q_hand is not None:
                            break
                if q_hand is not None and q_lift is not None:
                    r2 = plan_motion(
                        self._robot,
                        scene,
                        q_lift,
                        q_hand,
                        time_limit=opt.plan_time_s,
                        seed=0,
                        simplify=True,
                    )
                scene.detach(name, q_grasp)
        a.plan_ms = 1e3 * (time.perf_counter() - w0)
        a.outcome, a.status = "moving", ""  # this try's, not an earlier station's
        if q_grasp is None or (r1 is not None and r1.success and q_hand is None):
            a.outcome = "unreachable"
            a.status = (
                "no collision-free grasp"
                if q_grasp is None
                else "no clear lift"
                if q_lift is None
                else "no hand-over pose"
            )
            return
        if r1 is None or r2 is None or not r2.success or r1.path is None or r2.path is None:
            a.outcome = "no path"
            a.status = r2.status if r2 is not None else ("" if r1 is None else r1.status)
            return
        path = np.vstack([r1.path, r2.path])  # r2 starts at the lifted configuration
        seg = np.abs(np.diff(path, axis=0)).max(axis=1) / opt.joint_speed
        seg[len(r1.path) - 1] += opt.grasp_s  # closing the gripper between the two paths
        a.path = path
        start = t + a.plan_ms / 1e3
        if self._base_track is not None:  # the base finishes the drive it is on first
            start = max(start, self._base_free_s)
        if len(route) > 1:
            a.base_route = route
            a.base_times = route_times(route, start, opt.base_speed)
            start = float(a.base_times[-1])
        a.times = start + np.concatenate([[0.0], np.cumsum(seg)])
        a.ready_s = float(a.times[-1])
        self._grasp_index = len(r1.path) - 1

    def _held_clear(
        self, part: int, t_tool_part: FloatArray
    ) -> list[tuple[FloatArray, FloatArray]]:
        """The hand-over tool poses (:func:`_handover_targets`) in the order they are tried:
        the part of row ``part``, held as grasped (``t_tool_part`` (4, 4): its frame in the
        tool's), farthest from the sphere the person sweeps turning the assembly over (the
        assembly's reach about the root's first position) first: its nearest box corner
        farthest from the root. The person also lifts and moves the assembly: on chair 16 a
        42-cm back held 3 cm outside the sphere met a leg of the chair turned over above
        the table, 13 cm nearer the arm."""
        assert self._handover is not None
        c, size = self._box(part)
        corners = box_corners((c - size / 2.0, c + size / 2.0))  # part frame
        ranked = []
        for target in _handover_targets(self._handover):
            t_part = se3.matrix_from_pose(*target) @ t_tool_part
            world = corners @ t_part[:3, :3].T + t_part[:3, 3]
            ranked.append((float(np.linalg.norm(world - self._root0, axis=1).min()), target))
        ranked.sort(key=lambda r: -r[0])
        return [target for _, target in ranked]

    def _resting_on(self, scene: Any, name: str, q_grasp: FloatArray) -> tuple[str, ...]:
        """What the part ``name``, grasped at ``q_grasp``, touches as it lies: the table and
        the parts whose boxes it meets there (legs lying side by side). Not a hand: a
        hand on the part is the person's, and it is an obstacle."""
        hands = {self.names[i] for i in self.fingers}
        touching = {b if a == name else a for a, b in scene.collisions(q_grasp) if name in (a, b)}
        return ("table", *sorted(o for o in touching - hands - {"table"} if o in scene.objects))

    def _lift_clear(
        self, scene: Any, name: str, q_grasp: FloatArray, resting: Sequence[str]
    ) -> FloatArray | None:
        """The configuration that has lifted the grasped part straight up until it touches
        nothing (the table, a part lying against it: :meth:`_resting_on`), or None.

        Lifts of ``lift_m`` times each of :data:`LIFT_STEPS` are tried: a part lying
        against a taller one, or one tilted on its side, must rise above it. The
        motion to it is checked densely, the part allowed to touch only what it
        rested on (``resting``): on the synthetic chair of seed 0 a leg lying
        beside the arm's base met the base half-way up a lift whose end was clear.
        """
        grasp_pose = self._robot.fk(q_grasp)
        for k in LIFT_STEPS:
            up = np.array([0.0, 0.0, k * self.options.lift_m])
            q = self._robot.ik(
                (grasp_pose[0] + up, grasp_pose[1]),
                q_grasp,
                seed=0,
                n_restarts=4,
                accept=scene.is_valid,
            )
            if q is None:
                continue
            for o in resting:
                scene.allow(name, o)
            try:
                clear = scene.check_path(np.stack([q_grasp, q]))
            finally:
                for o in resting:
                    scene.disallow(name, o)
            if clear:
                return np.asarray(q, dtype=np.float64)
        return None

    def _top_grasp(
        self, part: int, pos: FloatArray, quat: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """The top-down grasp of ``part``: over its box's centre, 2 cm below the box's top,
        the gripper along the part's x."""
        c, size = self._box(part)
        half = size / 2.0
        top = float(np.max(se3.quat_rotate(quat[part], box_corners((-half, half)))[:, 2]))
        centre = pos[part] + se3.quat_rotate(quat[part], c)
        centre = centre + np.array([0.0, 0.0, max(top - 0.02, 0.0)])
        axis = se3.quat_rotate(quat[part], np.array([1.0, 0.0, 0.0]))
        return centre, _down_quat(axis[:2])

    def _grasp_targets(
        self,
        part: int,
        pos: FloatArray,
        quat: FloatArray,
        first: tuple[FloatArray, FloatArray],
    ) -> list[tuple[FloatArray, FloatArray]]:
        """Tool poses (world) to grasp ``part`` from above, the best first.

        ``first`` (the top-down grasp at the top of the part's box), then the
        execution stage's shape grasps (:func:`~thirdhand.execute.grasps.shape_grasps`)
        whose approach points down by more than :data:`DOWN_COS`, the most vertical
        and central first, each also :data:`SHALLOWER_M` less deep (a flat part's
        grasp can put the fingertips into the table it lies on), at most
        :data:`MAX_GRASPS` of them.
        """
        from thirdhand.execute.grasps import shape_grasps

        c, size = self._box(part)
        t_wp = se3.matrix_from_pose(pos[part], quat[part])
        world_c = pos[part] + se3.quat_rotate(quat[part], c)
        ranked = []
        for g in shape_grasps(c - size / 2.0, c + size / 2.0):
            t = t_wp @ g.pose
            down = -float(t[2, 2])
            if down > DOWN_COS:
                ranked.append((-round(down, 6), float(np.linalg.norm(t[:3, 3] - world_c)), t))
        ranked.sort(key=lambda r: (r[0], r[1]))
        out = [first]
        for _, _, t in ranked[: MAX_GRASPS // 2]:
            q = se3.quat_from_matrix(t[:3, :3])
            out += [(t[:3, 3], q), (t[:3, 3] + np.array([0.0, 0.0, SHALLOWER_M]), q)]
        return out

    def _check(
        self, a: Assist, t: float, pos: FloatArray, quat: FloatArray, valid: BoolArray
    ) -> None:
        """Check the arm's configuration at ``t`` against the hands and parts now (the base's
        drive before it: :meth:`_drive`)."""
        if a.path.shape[0] == 0 or t < a.times[0]:
            return
        k = int(np.searchsorted(a.times, t, side="right")) - 1
        if k >= len(a.times) - 1:
            q = a.path[-1]
        else:
            f = (t - a.times[k]) / max(a.times[k + 1] - a.times[k], 1e-9)
            q = a.path[k] + f * (a.path[k + 1] - a.path[k])
        carrying = k >= self._grasp_index
        name = self.names[self._carried]
        # During the straight lift the part may still touch what it rested on.
        lifting = k == self._grasp_index
        for o in self._resting:
            if lifting:
                self._scene.allow(name, o)
            else:
                self._scene.disallow(name, o)
        if carrying and not self._attached:
            self._scene.set_object_pose(name, self._carried_pose)
            self._scene.attach(name, a.path[self._grasp_index])
            self._attached = True
        self._track(pos, quat, valid, skip=self._carried)
        a.checked += 1
        self._count(a, q)

    def _count(self, a: Assist, q: FloatArray) -> None:
        """Count ``q`` in ``a`` if it is in collision in the world checked, with what it hit."""
        if not self._scene.is_valid(q):
            a.collisions += 1
            for pair in self._scene.collisions(q):
                key = " - ".join(pair)
                a.hits[key] = a.hits.get(key, 0) + 1

    def _release(self) -> None:
        """The person took a part: the arm lets go (the part leaves the simulated world)."""
        if self._attached:
            name = self.names[self._carried]
            self._scene.detach(name, self._robot.home)
            gone = (np.array([0.0, 0.0, -10.0]), np.array([0, 0, 0, 1.0]))
            self._scene.set_object_pose(name, gone)
            self._plan_scene.set_object_pose(name, gone)
            self._attached = False


def assembly_reach(
    slots: Sequence[Slot],
    names: Sequence[str],
    meta: Mapping[str, Any],
    root: str,
    part_size_m: float = 0.05,
) -> float:
    """How far the finished assembly reaches from its root, metres.

    Every plan step's child is put at its learned pose in its parent (composed from
    the root ``root``, :class:`~thirdhand.live.state.Slot`); the result is the largest
    distance of any corner of any part's box from the root's origin. A person turning
    the assembly over about its root sweeps this sphere. Boxes: the stream's
    ``geometry`` of the body that may fill each step (``names``: the stream's bodies,
    by row), a cube of ``part_size_m`` without one.
    """
    ident = np.array([0.0, 0.0, 0.0, 1.0])
    poses: dict[str, tuple[FloatArray, FloatArray]] = {root: (np.zeros(3), ident)}
    body = {root: root}
    pending = list(slots)
    while pending:
        ready = [s for s in pending if s.parent in poses]
        if not ready:
            break  # steps whose parent no step places: not part of the assembly
        for s in ready:
            pp, pq = poses[s.parent]
            if s.child not in poses:
                poses[s.child] = (pp + se3.quat_rotate(pq, s.pos), se3.quat_multiply(pq, s.quat))
                body[s.child] = names[s.candidates[0][1]] if s.candidates else s.child
            pending.remove(s)
    half = np.full(3, part_size_m / 2.0)
    reach = 0.0
    for name, (p, q) in poses.items():
        box = body_box(meta, body[name])
        pts = p + se3.quat_rotate(q, box_corners(box if box is not None else (-half, half)))
        reach = max(reach, float(np.linalg.norm(pts, axis=1).max()))
    return reach


def _handover_targets(
    handover: tuple[FloatArray, FloatArray],
) -> list[tuple[FloatArray, FloatArray]]:
    """The hand-over pose, then turned about the vertical and raised (a large part held
    at the first may touch the assembly or the person): yaw 0, ±90°, 180° at the
    pose's height and :data:`HANDOVER_RAISE_M` above it."""
    pos, quat = handover
    out = []
    for dz in (0.0, HANDOVER_RAISE_M):
        for yaw in (0.0, 0.5 * math.pi, -0.5 * math.pi, math.pi):
            turn = np.array([0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)])
            out.append((pos + np.array([0.0, 0.0, dz]), np.asarray(se3.quat_multiply(turn, quat))))
    return out


def _down_quat(direction: FloatArray) -> FloatArray:
    """A gripper orientation pointing down (tool z = −world z), tool x along ``direction`` (2,)."""
    d = np.asarray(direction, dtype=np.float64)
    n = float(np.linalg.norm(d))
    x = np.array([1.0, 0.0, 0.0]) if n < 1e-9 else np.array([d[0] / n, d[1] / n, 0.0])
    z = np.array([0.0, 0.0, -1.0])
    y = np.cross(z, x)
    return np.asarray(se3.quat_from_matrix(np.stack([x, y, z], axis=1)), dtype=np.float64)


__all__ = ["Assist", "AssistOptions", "RobotAssist"]
