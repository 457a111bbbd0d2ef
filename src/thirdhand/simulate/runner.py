"""Run a planned run in MuJoCo and measure every step (the stateful shell over the model).

:class:`Simulation` steps the physics through the phases of
:func:`~thirdhand.simulate.schedule.schedule`: the arm's servos track the planned
joint trajectory, the fingers close with the gripper's force limit (or, with the
weld grasp, the part is welded to the hand once they closed), a part placed by
its ``insert`` segment is held at the segment's end until it is seated (at most
``seat_time`` s), joined to its parent where it stands (a weld: the person
fastening it) and let go, and the assembly rests at the end. Per step it
measures what :mod:`~thirdhand.simulate.measure` judges.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import mujoco
import numpy as np

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.execute.robot import ROBOTS
from thirdhand.simulate.aim import (
    blend,
    integrate_offset,
    joint_step,
    pose_twist,
    shifted,
    tool_correction,
)
from thirdhand.simulate.measure import (
    PoseError,
    displacement_mm,
    pose_error,
    slip_mm,
    step_status,
)
from thirdhand.simulate.model import ARM_SPEED, FINGER_OPEN, FINGERS, HAND, TOOL
from thirdhand.simulate.plan import RunPlan
from thirdhand.simulate.schedule import Phase, schedule
from thirdhand.simulate.settings import SimulateSettings
from thirdhand.task.constraint import Constraint

#: Seconds between two measurements (slip, forces, tracking).
MEASURE_PERIOD = 0.01

#: Simulated seconds over which a re-aim is blended in (at most half the motion).
AIM_BLEND_S = 1.0

#: A re-aim moves a joint at most this fast on top of its planned motion, rad/s (about
#: half the Panda's joint speed: a part turned in the hand is brought back over a few
#: tenths of a second instead of flinging the wrist).
AIM_RATE = 1.0

#: A re-aim keeps every joint this far inside its range, degrees (the planner may run a
#: joint up to its limit; the other six joints of the redundant arm make up for it).
LIMIT_MARGIN_DEG = 1.0

#: A part is seated once it is this close to its planned goal, metres and degrees.
SEAT_TOLERANCE_M = 0.001
SEAT_TOLERANCE_DEG = 1.0

#: ``sink(model, data, label)`` called at every video frame.
FrameSink = Callable[[mujoco.MjModel, mujoco.MjData, str], None]


@dataclass
class StepOutcome:
    """What one step did in the simulation.

    Attributes
    ----------
    index : int
    constraint, parent, child : str
    status : str
        ``done``, ``slipped``, ``dropped``, ``jammed`` or ``failed``.
    grasp : str or None
        The planner's grasp.
    planner_status : str
    position_error_mm, angle_error_deg : float or None
        The part against its learned constraint when it was fastened.
    slip_mm : float
        Largest slip in the hand during the carry (lift and transport).
    peak_force_n : float
        Largest normal contact force on the part from anything but the fingers, N.
    tracking_error_deg : float
        Largest joint tracking error of the arm during the step, degrees.
    tool_error_mm : float
        Largest distance of the tool point from the planned one during the step, mm.
    joint_speed : float
        Largest joint speed of the arm during the step, as a share of that joint's
        speed limit (:data:`~thirdhand.simulate.model.ARM_SPEED`; above 1: faster
        than the real arm moves).
    held : bool
        The part was between the fingers at the end of the carry.
    blocked : bool
        When placed, the part touched a body other than the hand.
    """

    index: int
    constraint: str
    parent: str
    child: str
    status: str = "failed"
    grasp: str | None = None
    planner_status: str = ""
    position_error_mm: float | None = None
    angle_error_deg: float | None = None
    slip_mm: float = 0.0
    peak_force_n: float = 0.0
    tracking_error_deg: float = 0.0
    tool_error_mm: float = 0.0
    joint_speed: float = 0.0
    held: bool = False
    blocked: bool = False


@dataclass
class SimulationResult:
    """The outcome of a simulated run.

    Attributes
    ----------
    steps : list of StepOutcome
    grasp : str
        ``friction`` or ``weld``.
    sim_time_s, wall_time_s : float
        Simulated seconds and the wall-clock seconds the stepping took.
    rest_displacement_mm : float
        Largest move of any part's corners during the final rest.
    rest_part : str or None
        The part that moved most then.
    render_time_s : float
        Wall-clock seconds spent in the frame sink (rendering, encoding).
    """

    steps: list[StepOutcome]
    grasp: str
    sim_time_s: float = 0.0
    wall_time_s: float = 0.0
    rest_displacement_mm: float = 0.0
    rest_part: str | None = None
    render_time_s: float = 0.0
    timings: dict[str, float] = field(default_factory=dict)

    @property
    def success(self) -> bool:
        """Every step done."""
        return all(s.status == "done" for s in self.steps)


def _pose(data: mujoco.MjData, body: int) -> FloatArray:
    t = np.eye(4)
    t[:3, :3] = data.xmat[body].reshape(3, 3)
    t[:3, 3] = data.xpos[body]
    return t


def _weld_relpose(eq: int, model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """Set weld ``eq`` to hold its two bodies as they are now (body2 in body1's frame)."""
    b1, b2 = model.eq_obj1id[eq], model.eq_obj2id[eq]
    rel = se3.transform_invert(_pose(data, b1)) @ _pose(data, b2)
    x, y, z, w = se3.quat_from_matrix(rel[:3, :3])
    model.eq_data[eq, :3] = 0.0
    model.eq_data[eq, 3:6] = rel[:3, 3]
    model.eq_data[eq, 6:10] = [w, x, y, z]
    model.eq_data[eq, 10] = 1.0
    data.eq_active[eq] = 1


class Simulation:
    """One run of a plan in a compiled model.

    Parameters
    ----------
    model : mujoco.MjModel
        From :func:`~thirdhand.simulate.model.build_spec`.
    plan : RunPlan
    constraints : dict of str to Constraint
        The task's constraints by id.
    corners : dict of str to ndarray (8, 3)
        Each part's bounding-box corners, body frame, metres.
    settings : SimulateSettings
    tool_planned : ndarray, shape (n, 3), optional
        The planned tool point at each of ``plan.t`` (world, metres), for the tool error.
    sink : callable, optional
        Called at every video frame.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        plan: RunPlan,
        constraints: Mapping[str, Constraint],
        corners: Mapping[str, FloatArray],
        settings: SimulateSettings,
        *,
        tool_planned: FloatArray | None = None,
        sink: FrameSink | None = None,
    ) -> None:
        self.model = model
        self.data = mujoco.MjData(model)
        self.plan = plan
        self.constraints = constraints
        self.corners = corners
        self.settings = settings
        self.tool_planned = tool_planned
        self.sink = sink
        names = ROBOTS[plan.robot].arm_joints
        self._qadr = np.array([model.jnt_qposadr[model.joint(n).id] for n in names])
        self._vadr = np.array([model.jnt_dofadr[model.joint(n).id] for n in names])
        self._arm_act = np.array([model.actuator(n).id for n in names])
        rng = np.array([model.jnt_range[model.joint(n).id] for n in names])
        margin = np.deg2rad(LIMIT_MARGIN_DEG)
        self._q_lo, self._q_hi = rng[:, 0] + margin, rng[:, 1] - margin
        self._finger_act = np.array([model.actuator(n).id for n in FINGERS])
        self._finger_q = np.array([model.jnt_qposadr[model.joint(n).id] for n in FINGERS])
        self._kv_over_kp = settings.damping / settings.stiffness
        self._tool = model.body(TOOL).id
        self._hand = model.body(HAND).id
        robot_bodies = [model.body(b).id for b in range(model.nbody) if model.body(b).name
                        .startswith("panda_")]  # fmt: skip
        self._robot_bodies = set(robot_bodies)
        self._pads = {model.geom("pad_left").id, model.geom("pad_right").id}
        self._geom_body = np.asarray(model.geom_bodyid)
        self._eq = {model.equality(i).name: i for i in range(model.neq)}
        self._every = max(1, round(MEASURE_PERIOD / settings.timestep))
        self._frame_every = max(1, round(1.0 / settings.fps / settings.timestep))
        self._n = 0
        self.render_time = 0.0
        self._label = ""
        self._scratch = mujoco.MjData(model)
        self._jacp = np.zeros((3, model.nv))
        self._jacr = np.zeros((3, model.nv))
        self._delta = np.zeros(len(names))
        self._aim_to = np.zeros(len(names))
        self._speed = np.asarray(ARM_SPEED, dtype=np.float64)
        self._offset = np.zeros(6)
        self._grip: FloatArray | None = None

    # -- state -------------------------------------------------------------------------

    def reset(self) -> None:
        """Arm at the plan's first configuration, fingers open, parts at their start."""
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        d.qpos[self._qadr] = self.plan.q[0]
        d.qpos[self._finger_q] = FINGER_OPEN
        for name, pose in self.plan.start.items():
            b = m.body(name)
            if m.body_jntnum[b.id] == 0:
                continue
            adr = m.jnt_qposadr[m.body_jntadr[b.id]]
            x, y, z, w = se3.quat_from_matrix(pose[:3, :3])
            d.qpos[adr : adr + 7] = [*pose[:3, 3], w, x, y, z]
        d.ctrl[self._arm_act] = self.plan.q[0]
        d.ctrl[self._finger_act] = self.settings.gripper_force
        mujoco.mj_forward(m, d)

    def body_pose(self, name: str) -> FloatArray:
        """World pose (4, 4) of a body now."""
        return _pose(self.data, self.model.body(name).id)

    def touching(self, part: str) -> tuple[bool, bool, float]:
        """Whether ``part`` touches a finger pad, another body than the hand, and the force.

        Returns
        -------
        pads : bool
        other : bool
            A contact with a body outside the robot (a part, the table, the world).
        force : float
            Largest normal force of those other contacts, N.
        """
        d = self.data
        n = d.ncon
        if n == 0:
            return False, False, 0.0
        b = self.model.body(part).id
        geoms = d.contact.geom[:n]
        bodies = self._geom_body[geoms]
        mine = (bodies[:, 0] == b) | (bodies[:, 1] == b)
        if not mine.any():
            return False, False, 0.0
        other_body = np.where(bodies[:, 0] == b, bodies[:, 1], bodies[:, 0])
        pads = np.isin(geoms, list(self._pads)).any(axis=1) & mine
        robot = np.isin(other_body, list(self._robot_bodies))
        rest = mine & ~robot
        force = 0.0
        if rest.any():
            adr = d.contact.efc_address[:n][rest]
            adr = adr[adr >= 0]
            if len(adr):
                force = float(np.max(np.abs(d.efc_force[adr])))
        return bool(pads.any()), bool(rest.any()), force

    # -- re-aiming ----------------------------------------------------------------------

    def _tool_at(self, q: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The tool's world pose (4, 4) and Jacobian (6, dof) at arm configuration ``q``."""
        m, x = self.model, self._scratch
        x.qpos[self._qadr] = q
        mujoco.mj_kinematics(m, x)
        mujoco.mj_comPos(m, x)
        mujoco.mj_jacBody(m, x, self._jacp, self._jacr, self._tool)
        jac = np.vstack([self._jacp[:, self._vadr], self._jacr[:, self._vadr]])
        return _pose(x, self._tool), jac

    def _aim(self, q: FloatArray, correction: FloatArray) -> FloatArray:
        """Joint change (dof,) that moves the tool from its pose at ``q`` by ``correction``."""
        target = self._tool_at(q)[0] @ correction
        dq = np.zeros_like(q)
        lo, hi = self._q_lo, self._q_hi
        free = np.ones(q.shape[0], dtype=bool)
        for _ in range(4):
            pose, jac = self._tool_at(q + dq)
            dq = dq + joint_step(jac, pose_twist(pose, target), free=free)
            free &= (q + dq > lo) & (q + dq < hi)
            dq = np.clip(q + dq, np.minimum(lo, q), np.maximum(hi, q)) - q
        return dq

    def _in_hand(self, part: str) -> FloatArray:
        """The part's pose (4, 4) in the tool frame now (what the cell's tracking measures)."""
        return se3.transform_invert(_pose(self.data, self._tool)) @ self.body_pose(part)

    # -- the run -----------------------------------------------------------------------

    def _advance(
        self,
        ctrl: FloatArray,
        on_tick: Callable[[int], None],
        adjust: Callable[[int], FloatArray] | None = None,
    ) -> None:
        """Step once per row of ``ctrl`` (k, dof), measuring every few steps.

        ``adjust(k)``, called every measurement period, returns the joint change
        (dof,) wanted on top of the control from row ``k`` on; the change applied
        (``_delta``) moves towards it at most :data:`AIM_RATE` rad/s.
        """
        m, d = self.model, self.data
        step = AIM_RATE * self.settings.timestep
        for k in range(ctrl.shape[0]):
            if adjust is not None and k % self._every == 0:
                self._aim_to = adjust(k)
            self._delta = self._delta + np.clip(self._aim_to - self._delta, -step, step)
            d.ctrl[self._arm_act] = ctrl[k] + self._delta
            mujoco.mj_step(m, d)
            self._n += 1
            if self._n % self._every == 0:
                on_tick(k)
            if self.sink is not None and self._n % self._frame_every == 0:
                t0 = time.perf_counter()
                self.sink(m, d, self._label)
                self.render_time += time.perf_counter() - t0

    def _seat(
        self,
        part: str,
        goal: FloatArray,
        qr: FloatArray,
        tick: Callable[[int], None],
        adjust: Callable[[int], FloatArray],
    ) -> None:
        """Hold the end of an insertion, still re-aiming, until the part is at ``goal``.

        A part that stopped short of its goal (a leg on the rim of its pocket, a
        millimetre or two aside) is held pressed where the plan ends while the re-aim
        moves it across its insertion axis, until it is within
        :data:`SEAT_TOLERANCE_M` and :data:`SEAT_TOLERANCE_DEG` of its planned goal
        (4, 4; world) or ``seat_time`` s have passed.

        Parameters
        ----------
        qr : ndarray, shape (k, dof)
            The insertion's reference joint positions; its last row is held.
        tick, adjust : callable
            The insertion's measurement and re-aim, called with its last row's index.
        """
        s = self.settings
        last = qr.shape[0] - 1
        rows = np.repeat(qr[-1:], self._every, axis=0)
        for _ in range(round(s.seat_time / (self._every * s.timestep))):
            error = pose_twist(self.body_pose(part), goal)
            if np.linalg.norm(error[:3]) < SEAT_TOLERANCE_M and np.linalg.norm(
                error[3:]
            ) < np.deg2rad(SEAT_TOLERANCE_DEG):
                return
            self._advance(rows, lambda k: tick(last), lambda k: adjust(last))

    def _reference(self, phase: Phase) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Per physics step of a move: times (k,), reference q (k, dof), control (k, dof)."""
        dt = self.settings.timestep
        k = max(1, int(np.ceil(phase.duration / dt)))
        slow = self.settings.slowdown
        tau = phase.t_start + dt * np.arange(1, k + 1) / slow
        tau = np.minimum(tau, phase.t_end)
        t, q = self.plan.t, self.plan.q
        qd = np.gradient(q, t, axis=0) / slow
        qr = np.stack([np.interp(tau, t, q[:, j]) for j in range(q.shape[1])], axis=1)
        vr = np.stack([np.interp(tau, t, qd[:, j]) for j in range(q.shape[1])], axis=1)
        return tau, qr, qr + self._kv_over_kp * vr

    def _adjuster(
        self, phase: Phase, qr: FloatArray, planned_grip: Mapping[str, FloatArray]
    ) -> Callable[[int], FloatArray] | None:
        """How a move re-aims the arm (the ``aim`` setting); None: as planned.

        During a part's transport and insertion the tool is re-aimed so that the part,
        as it sits in the hand now, follows its planned path (blended in over the first
        :data:`AIM_BLEND_S` s of the transport), with an offset that makes up for the
        arm's lag (:func:`~thirdhand.simulate.aim.integrate_offset`). Once the part
        touches anything but the hand (its parent, as it goes in), the measured grasp
        is kept as it was (contact moves the part in the hand on purpose), and during
        the insertion the offset grows only across the insertion axis: a part that came
        in aside is moved over the pocket without being pushed harder into its rim. A
        part the fingers lost is not aimed at. The next motion without a
        part blends the arm's last change out.
        """
        s = self.settings
        dt = s.timestep
        part = phase.part
        ramp = min(AIM_BLEND_S, 0.5 * phase.duration)
        if s.aim and part is not None and part in planned_grip:
            g_plan = planned_grip[part]
            if phase.segment in ("transport", "insert"):
                insert = phase.segment == "insert"
                axis = None
                if insert:  # the part's planned path in, world frame
                    axis = (self._tool_at(qr[-1])[0] @ g_plan)[:3, 3] - (
                        self._tool_at(qr[0])[0] @ g_plan
                    )[:3, 3]

                def follow(k: int) -> FloatArray:
                    tool = self._tool_at(qr[k])[0]
                    pads, other, _ = self.touching(part)
                    if not pads and s.grasp == "friction":  # lost: aim no more
                        return self._delta
                    free = not other
                    if free:  # the part touches only the hand: aim it
                        self._offset = integrate_offset(
                            self._offset, tool @ g_plan, self.body_pose(part)
                        )
                        self._grip = self._in_hand(part)
                    else:
                        if self._grip is None:
                            self._grip = self._in_hand(part)
                        if axis is not None:  # on its way in: aim across the axis only
                            self._offset = integrate_offset(
                                self._offset, tool @ g_plan, self.body_pose(part), across=axis
                            )
                    aimed = se3.transform_invert(tool) @ shifted(tool @ g_plan, self._offset)
                    w = 1.0 if insert else blend(k * dt, ramp)
                    return self._aim(qr[k], tool_correction(aimed, self._grip, w))

                return follow
        if not np.any(self._delta) and not np.any(self._aim_to):
            return None
        last = self._delta.copy()
        return lambda k: (1.0 - blend(k * dt, ramp)) * last

    def run(self) -> SimulationResult:
        """Run every phase; the per-step outcomes and the rest displacement."""
        s = self.settings
        m, d = self.model, self.data
        self.reset()
        outcomes = {
            p.index: StepOutcome(p.index, p.constraint, p.parent, p.child, grasp=p.grasp,
                                 planner_status=p.status)
            for p in self.plan.steps
        }  # fmt: skip
        grip0: dict[str, FloatArray] = {}
        planned_grip: dict[str, FloatArray] = {}
        hold_q = self.plan.q[0].copy()
        rest_start: dict[str, FloatArray] = {}
        wall0 = time.perf_counter()
        for phase in schedule(self.plan.spans, s):
            out = outcomes.get(phase.step)
            step_name = "" if out is None else f"step {out.index}: {out.child} -> {out.parent}"
            self._label = f"{step_name} ({phase.segment})" if step_name else phase.segment
            if phase.kind == "move":
                tau, qr, ctrl = self._reference(phase)
                tool = None
                if self.tool_planned is not None:
                    tool = np.stack(
                        [np.interp(tau, self.plan.t, self.tool_planned[:, j]) for j in range(3)],
                        axis=1,
                    )
                carry = phase.part is not None and phase.segment in ("lift", "transport")

                def tick(k: int, out: StepOutcome | None = out, qr: FloatArray = qr,
                         tool: FloatArray | None = tool, carry: bool = carry,
                         part: str | None = phase.part) -> None:  # fmt: skip
                    if out is None:
                        return
                    err = float(np.max(np.abs(d.qpos[self._qadr] - qr[k] - self._delta)))
                    speed = float(np.max(np.abs(d.qvel[self._vadr]) / self._speed))
                    out.joint_speed = max(out.joint_speed, speed)
                    out.tracking_error_deg = max(out.tracking_error_deg, float(np.rad2deg(err)))
                    if tool is not None:
                        e = float(np.linalg.norm(d.xpos[self._tool] - tool[k]) * 1e3)
                        out.tool_error_mm = max(out.tool_error_mm, e)
                    if part is not None:
                        _, _, f = self.touching(part)
                        out.peak_force_n = max(out.peak_force_n, f)
                        if carry and part in grip0:
                            rel = se3.transform_invert(_pose(d, self._tool)) @ self.body_pose(part)
                            out.slip_mm = max(
                                out.slip_mm, slip_mm(rel, grip0[part], self.corners[part])
                            )

                adjust = self._adjuster(phase, qr, planned_grip)
                self._advance(ctrl, tick, adjust)
                if phase.segment == "insert" and adjust is not None and phase.part is not None:
                    self._label = f"{step_name} (seat)"
                    goal = self._tool_at(qr[-1])[0] @ planned_grip[phase.part]
                    self._seat(phase.part, goal, qr, tick, adjust)
                hold_q = qr[-1]  # _advance adds the re-aim (_delta)
                if phase.segment == "transport" and out is not None and phase.part is not None:
                    pads, _, _ = self.touching(phase.part)
                    out.held = pads or s.grasp == "weld"
                continue
            k = max(1, round(phase.duration / s.timestep))
            ctrl = np.repeat(hold_q[None], k, axis=0)
            part = phase.part
            if phase.kind == "close" and part is not None:
                # The grasp the planner meant: the part where the plan put it (its start,
                # before its first pick; where it is, before a regrasp).
                where = self.plan.start[part] if part not in grip0 else self.body_pose(part)
                planned_grip[part] = se3.transform_invert(self._tool_at(hold_q)[0]) @ where
                self._offset = np.zeros(6)
                self._grip = None
                d.ctrl[self._finger_act] = -s.gripper_force
                self._advance(ctrl, lambda k: None)
                if s.grasp == "weld":
                    _weld_relpose(self._eq[f"grasp:{part}"], m, d)
                grip0[part] = se3.transform_invert(_pose(d, self._tool)) @ self.body_pose(part)
            elif phase.kind == "fasten" and part is not None and out is not None:
                c = self.constraints[out.constraint]
                err = pose_error(self.body_pose(out.parent), self.body_pose(part), c)
                out.position_error_mm, out.angle_error_deg = err.position_mm, err.angle_deg
                _, out.blocked, _ = self.touching(part)
                eq = self._eq.get(f"fasten:{part}")
                if eq is not None:
                    _weld_relpose(eq, m, d)
                self._advance(ctrl, lambda k: None)
            elif phase.kind == "open":
                d.ctrl[self._finger_act] = s.gripper_force
                if part is not None and f"grasp:{part}" in self._eq:
                    d.eq_active[self._eq[f"grasp:{part}"]] = 0
                self._advance(ctrl, lambda k: None)
            elif phase.kind == "rest":
                rest_start = {n: self.body_pose(n) for n in self.plan.start}
                self._label = "rest"
                self._advance(ctrl, lambda k: None)
        wall = time.perf_counter() - wall0
        moved = {
            n: displacement_mm(p, self.body_pose(n), self.corners[n]) for n, p in rest_start.items()
        }
        for o in outcomes.values():
            verdict: PoseError | None = None
            if o.position_error_mm is not None and o.angle_error_deg is not None:
                verdict = PoseError(o.position_error_mm, o.angle_error_deg)
            planned = next(p.planned for p in self.plan.steps if p.index == o.index)
            o.status = step_status(
                planned=planned, held=o.held, slip=o.slip_mm, error=verdict, blocked=o.blocked,
                position_tolerance=s.position_tolerance, angle_tolerance=s.angle_tolerance,
                slip_tolerance=s.slip_tolerance, drop_distance=s.drop_distance,
            )  # fmt: skip
        worst = max(moved, key=moved.__getitem__) if moved else None
        return SimulationResult(
            steps=list(outcomes.values()),
            grasp=s.grasp,
            sim_time_s=float(d.time),
            wall_time_s=wall - self.render_time,
            rest_displacement_mm=moved[worst] if worst is not None else 0.0,
            rest_part=worst,
            render_time_s=self.render_time,
        )
