"""One seeded episode: planned, simulated, judged and, when kept, recorded.

Episode ``i`` of a run with seed ``S`` draws its start layout and plans with seed
``S + i`` (:func:`~thirdhand.simulate.plan.plan_offline`, as ``thirdhand
execute`` does), then runs the plan in MuJoCo. It is kept when every step is
``done``; then it is simulated once more with :class:`~.record.FrameRecorder`
as the frame sink (the physics is deterministic: the same run, now recorded),
so an episode that fails costs no rendering.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from thirdhand.errors import OptionError, ThirdhandError
from thirdhand.generate.record import GRIPPER, POSE_COLUMNS, FrameRecorder, Recording
from thirdhand.generate.settings import GenerateSettings
from thirdhand.lerobot.episode import Episode
from thirdhand.simulate.settings import SimulateSettings
from thirdhand.task.model import TaskFile

if TYPE_CHECKING:
    from thirdhand.simulate.plan import RunPlan
    from thirdhand.simulate.runner import SimulationResult

STATE = "observation.state"
ACTION = "action"
ENVIRONMENT = "observation.environment_state"
FRONT = "observation.images.front"
WRIST = "observation.images.wrist"
STEP = "annotation.step"


@dataclass(frozen=True)
class EpisodeJob:
    """Everything a worker needs to make one episode.

    Attributes
    ----------
    task : TaskFile
    task_path : str or None
        Where the task file lies (its meshes are found beside it).
    name : str
        The assembly's name in the task text (``chair``).
    seed : int
        Seed of the start layout and the planner.
    robot : str or None
        The robot (None: the task's, else panda).
    search : tuple of str
        Folders searched for part meshes.
    simulate : SimulateSettings
        The physics.
    settings : GenerateSettings
        Frame rate and image size.
    """

    task: TaskFile
    task_path: str | None
    name: str
    seed: int
    robot: str | None = None
    search: tuple[str, ...] = ()
    simulate: SimulateSettings = field(default_factory=lambda: SimulateSettings.model_validate({}))
    settings: GenerateSettings = field(default_factory=lambda: GenerateSettings.model_validate({}))


@dataclass(frozen=True)
class EpisodeOutcome:
    """What became of one seed.

    Attributes
    ----------
    seed : int
    recording : Recording or None
        The frames of a kept episode; None otherwise.
    reasons : tuple of str
        Why it was not kept (``leg2 slipped``, ``planning: …``); empty when kept.
    timings : dict of str to float
        Wall-clock seconds: ``planning``, ``physics`` (model building and
        stepping, both runs), ``rendering``.
    """

    seed: int
    recording: Recording | None
    reasons: tuple[str, ...]
    timings: dict[str, float]

    @property
    def kept(self) -> bool:
        """Every step done: the episode goes into the dataset."""
        return self.recording is not None


def task_text(task: TaskFile, name: str) -> str:
    """The episodes' task in words: ``assemble the chair: leg2 into the seating, …``."""
    steps = ", ".join(f"{s.child} into the {s.parent}" for s in task.plan)
    return f"assemble the {name}: {steps}" if steps else f"assemble the {name}"


def check_settings(settings: GenerateSettings, simulate: SimulateSettings) -> None:
    """Refuse a frame rate that is no whole number of physics steps, or odd image sizes.

    Raises
    ------
    OptionError
    """
    steps = 1.0 / (settings.fps * simulate.timestep)
    if not math.isclose(steps, round(steps), rel_tol=0.0, abs_tol=1e-6):
        raise OptionError(
            f"[generate] fps {settings.fps}: a frame every 1/{settings.fps} s is not a whole "
            f"number of [simulate] timestep {simulate.timestep:g} s physics steps ({steps:.3g})"
        )
    for key in ("width", "height"):
        if getattr(settings, key) % 2:
            raise OptionError(f"[generate] {key} {getattr(settings, key)}: must be even (H.264)")


def _reasons(result: SimulationResult, plan: RunPlan) -> tuple[str, ...]:
    """Why a run is not kept: each step not done, with its status (or the planner's verdict)."""
    planned = {p.index: p for p in plan.steps}
    out = []
    for o in sorted(result.steps, key=lambda o: o.index):
        if o.status == "done":
            continue
        p = planned.get(o.index)
        if p is not None and not p.planned:
            # the planner's verdict without its counts, so that episodes add up
            out.append(f"{o.child} not planned ({p.status.split(':', 1)[0]})")
        else:
            out.append(f"{o.child} {o.status}")
    return tuple(out)


def run_episode(job: EpisodeJob) -> EpisodeOutcome:
    """Plan, simulate and judge one seed; record it when every step is done.

    A module-level function of one picklable record, for
    :func:`~thirdhand.batch.parallel_map`.
    """
    from thirdhand.execute.layout import base_part
    from thirdhand.simulate.plan import plan_offline
    from thirdhand.simulate.run import simulate_run
    from thirdhand.simulate.video import cell_lookat

    sim = job.simulate.model_copy(update={"fps": job.settings.fps})
    timings = {"planning": 0.0, "physics": 0.0, "rendering": 0.0}
    t0 = time.perf_counter()
    try:
        plan = plan_offline(
            job.task, task_path=job.task_path, robot=job.robot, seed=job.seed,
            search=job.search, rate=sim.rate,
        )  # fmt: skip
    except ThirdhandError as exc:
        timings["planning"] = time.perf_counter() - t0
        return EpisodeOutcome(job.seed, None, (f"planning: {' '.join(str(exc).split())}",), timings)
    timings["planning"] = time.perf_counter() - t0
    t1 = time.perf_counter()
    first = simulate_run(job.task, plan, sim, task_path=job.task_path, search=job.search)
    timings["physics"] = time.perf_counter() - t1
    if not first.result.success:
        return EpisodeOutcome(job.seed, None, _reasons(first.result, plan), timings)
    objects = [o.name for o in job.task.objects]
    parts = [n for n in objects if n in plan.start] + sorted(set(plan.start) - set(objects))
    lookat = cell_lookat(plan.robot_base, plan.start.get(base_part(job.task)))
    recorders: list[FrameRecorder] = []

    def make_sink(model: object) -> FrameRecorder:
        rec = FrameRecorder(
            model, robot=plan.robot, parts=parts, lookat=lookat, width=job.settings.width,
            height=job.settings.height,
        )  # fmt: skip
        recorders.append(rec)
        return rec

    t2 = time.perf_counter()
    try:
        second = simulate_run(
            job.task, plan, sim, task_path=job.task_path, search=job.search, make_sink=make_sink
        )
    finally:
        for rec in recorders:
            rec.close()
    render = sum(r.render_time for r in recorders)
    timings["rendering"] = render
    timings["physics"] += time.perf_counter() - t2 - render
    if not second.result.success:  # the physics is deterministic; never trust it blindly
        return EpisodeOutcome(job.seed, None, _reasons(second.result, plan), timings)
    return EpisodeOutcome(job.seed, recorders[0].recording(), (), timings)


def episode_of(recording: Recording, *, fps: int, task: str) -> Episode:
    """A recorded episode as a LeRobot episode (the features of ``docs/how-to/generate.md``)."""
    arm = tuple(recording.joints)
    env = tuple(f"{p}.{c}" for p in recording.parts for c in POSE_COLUMNS)
    return Episode(
        fps=fps,
        task=task,
        features={
            STATE: recording.state.astype(np.float32),
            ACTION: recording.action.astype(np.float32),
            ENVIRONMENT: recording.environment.astype(np.float32),
        },
        names={STATE: (*arm, GRIPPER), ACTION: (*arm, GRIPPER), ENVIRONMENT: env},
        videos={FRONT: recording.front, WRIST: recording.wrist},
        annotations={STEP: recording.labels},
    )
