"""``thirdhand execute TASK.json``: run a task's plan on the simulated arm.

Prints, per step, the grasp (and whether it came from the demonstration or the
part's shape), how the part was placed (along the learned primitive or straight
in, and whether a regrasp was needed: the part put down near the arm and picked
again), the planning time, the executed path's length and whether it succeeded;
``--record OUT`` writes a replay (``OUT.parquet``, viewable with ``thirdhand review
TASK --demo OUT.parquet``) and the joint trajectory (``OUT.json``). Exits 1 when a
step fails.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.console import Console
from rich.table import Table

from thirdhand.config import ConfigOption, load_settings
from thirdhand.errors import ThirdhandError
from thirdhand.execute.robot import ROBOTS
from thirdhand.execute.settings import ExecuteSettings

if TYPE_CHECKING:
    from thirdhand.task.model import TaskFile


def execute_command(
    task: Annotated[Path, typer.Argument(help="Task file (thirdhand.task/2 JSON).")],
    robot: Annotated[
        str | None,
        typer.Option(
            help="Simulated robot: panda or baxter [default: the task's stages.execution, "
            "else panda]."
        ),
    ] = None,
    online: Annotated[
        bool, typer.Option("--online", help="Re-plan from the observed scene before each step.")
    ] = False,
    record: Annotated[
        Path | None,
        typer.Option(help="Write the replay (OUT.parquet) and the trajectory (OUT.json)."),
    ] = None,
    seed: Annotated[int, typer.Option(help="Seed of the start layout and the planner.")] = 0,
    demo: Annotated[
        Path | None,
        typer.Option(help="A demonstration whose fingers give the grasps (default: the task's)."),
    ] = None,
    person: Annotated[
        list[str] | None,
        typer.Option(help="Online: a simulated person does this constraint's step (repeatable)."),
    ] = None,
    force: Annotated[
        bool, typer.Option(help="Replace existing --record files (kept as numbered .bak).")
    ] = False,
    config: ConfigOption = None,
) -> None:
    """Execute a task's plan on a simulated robot arm with a motion planner.

    Settings (``[execute]`` of ``--config``; ``thirdhand config execute``): time limits,
    grasps and goals tried, step order, base placement, start layout, regrasp, extra
    mesh folders.
    """
    from thirdhand import io, options
    from thirdhand.execute.executor import (
        ExecutionOptions,
        Executor,
        person_does,
        task_defaults,
    )
    from thirdhand.execute.record import record_paths, write_run
    from thirdhand.fileops import check_outputs
    from thirdhand.task.store import load_task

    options.seed(seed)
    cfg = load_settings(config, "execute", ExecuteSettings)
    meshes = [Path(m) for m in cfg.meshes]
    for folder in meshes:
        if not folder.is_dir():
            raise ThirdhandError(f"[execute] meshes {folder}: not a folder of part meshes")
    if record is not None:
        inputs = [task, *([demo] if demo else []), *([config] if config else [])]
        replay, run = record_paths(record)
        check_outputs([("--record", replay), ("--record", run)], force=force, inputs=inputs)
    console = Console()
    t = load_task(task)
    if not t.plan:
        raise ThirdhandError(
            f"{task}: the task has no plan, nothing to execute "
            "(learn one first: thirdhand learn RECORDINGS -o TASK.json)"
        )
    search = [str(m) for m in meshes]
    opts = ExecutionOptions(
        sample_free_dofs=cfg.free_dofs, step_time_limit=cfg.step_time,
        plan_time_limit=cfg.plan_time, order=cfg.order, max_grasps=cfg.max_grasps,
        n_goal_samples=cfg.goals, placement=cfg.placement, start_grasps=cfg.start_grasps,
        regrasp=cfg.regrasp,
    )  # fmt: skip
    d = io.load(demo) if demo is not None else None
    if d is not None:
        problem = t.foreign_recording_problem(d.body_names)
        if problem is not None:
            raise ThirdhandError(f"--demo {demo}: {problem}")
    if robot is not None and robot not in ROBOTS:
        raise ThirdhandError(f"--robot {robot}: unknown (expected one of {', '.join(ROBOTS)})")
    robot, assembly_xy = task_defaults(t, robot, cfg.assembly_at)
    ex = Executor.for_task(
        t, robot, seed=seed, options=opts, task_path=task, search=search, demo=d,
        assembly_xy=assembly_xy,
    )  # fmt: skip
    from thirdhand.task.meshes import missing_mesh_note

    note = missing_mesh_note(t, task, search)
    if note is not None:
        console.print(f"note: {note}")
    arm = ex.robot
    ids = {c.id for c in t.constraints}
    for cid in person or []:
        if cid not in ids:
            raise ThirdhandError(f"--person {cid}: no constraint with that id in {task}")
    if online:
        events = {1 + k: [person_does(t, cid, seed + k)] for k, cid in enumerate(person or [])}
        result = ex.run_online(seed=seed, events=events)
    else:
        if person:
            raise ThirdhandError("--person needs --online (offline planning shares no task)")
        result = ex.run_offline(seed=seed)
    table = Table(title=f"{task.name} on {robot} ({'online' if online else 'offline'})")
    cols = ("step", "action", "grasp", "place", "planning s", "path rad", "tool m", "collisions",
            "status")  # fmt: skip
    for col in cols:
        table.add_column(col)
    for r in result.steps:
        table.add_row(
            str(r.index),
            f"{r.child} → {r.parent} ({r.constraint})",
            f"{r.grasp} ({r.grasp_source})" if r.grasp_source else "",
            r.place_motion + (" after a regrasp" if r.regrasp else ""),
            f"{r.planning_time_s:.2f}",
            f"{r.joint_length_rad:.2f}",
            f"{r.tool_length_m:.2f}",
            str(r.n_collisions),
            ("[green]" if r.success else "[red]") + r.status,
        )
    console.print(table)
    for e in result.events:
        console.print(f"event: {e}")
    for r in result.steps:
        if r.regrasp is not None:
            g = r.regrasp
            console.print(
                f"step {r.index} ({r.constraint}) regrasp: {r.child} put down at "
                f"({g.spot[0]:.2f}, {g.spot[1]:.2f}) m, {g.distance_m:.2f} m from the arm"
                f"{', face down' if g.face_down else ''}, and picked again; without it: "
                f"{g.plain_status}"
            )
        if r.success:
            continue
        n = r.tried
        if n.grasps or n.goals or n.plans:
            console.print(
                f"step {r.index} ({r.constraint}) tried: {n.grasps} grasps "
                f"({n.grasp_ik_failed} IK failed, {n.grasp_in_collision} in collision), "
                f"{n.goals} goals ({n.place_ik_failed} IK failed, {n.place_in_collision} in "
                f"collision), {n.plans_failed}/{n.plans} plans failed"
            )
        for a, b, k in r.collision_pairs:
            console.print(f"step {r.index} ({r.constraint}) colliding: {a} – {b} ({k} times)")
    if record is not None:
        replay, traj = write_run(arm, result, record, task_name=task.stem)
        console.print(f"wrote {replay} and {traj}")
    verdict = "every step succeeded" if result.success else "some steps failed"
    console.print(f"{verdict}; {result.n_collisions} configurations in collision (dense check)")
    if not result.success:
        recorded = t.stages.grasps is not None
        if demo is None and not recorded and (source := learned_from(t, task)) is not None:
            console.print(
                f"hint: no grasp came from a demonstration; the task was learned from {source}: "
                f"--demo {source} takes the grasps from its fingers"
            )
        failed = [r for r in result.steps if not r.success]
        what = ", ".join(f"{r.constraint}: {r.status}" for r in failed[:5])
        more = ", …" if len(failed) > 5 else ""
        raise ThirdhandError(
            f"{task}: {len(failed)} of {len(result.steps)} steps failed ({what}{more})"
            if failed
            else f"{task}: the plan was not completed"
        )


def learned_from(t: TaskFile, task: Path) -> Path | None:
    """The first recording the task's provenance lists that is still there, or None.

    Only where the task says: a relative path beside the task file (not from the
    current folder), an absolute one as written; a regular file or folder of a
    recording format whose content has the SHA-256 the provenance recorded (an
    input recorded without one is taken as found). A file changed since is not
    the recording the task was learned from.
    """
    from thirdhand import io
    from thirdhand.task.model import InputFile

    for inp in t.provenance.inputs:
        raw = Path(inp.path)
        p = raw if raw.is_absolute() else task.parent / raw
        if not (p.is_file() or p.is_dir()):
            continue
        try:
            io.detect(p)
        except ThirdhandError:
            continue
        if inp.sha256 is not None and InputFile.from_path(p).sha256 != inp.sha256:
            continue
        return p
    return None
