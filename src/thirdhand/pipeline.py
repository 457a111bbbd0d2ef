"""The main job: a synthetic chair assembly through every stage that exists.

Each stage reads the previous stage's output and writes its own files into the
output folder; the returned summary lists what was written and the key figures.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from thirdhand import io
from thirdhand.demonstration import ConstraintEvent, Demonstration, Labels


def run_demo(output: str | os.PathLike[str], *, seed: int = 0) -> dict[str, Any]:
    """Generate the default chair demonstration and run every stage on it.

    Parameters
    ----------
    output : path-like
        Folder for the outputs; created if needed. Files in it are replaced, each
        previous version kept as ``<name>.bak``.
    seed : int
        Seed of the synthetic demonstration.

    Returns
    -------
    dict
        ``lines``: human-readable summary lines; ``files``: written paths; and one
        block of figures per stage.
    """
    from thirdhand.synth import SensorModel, make_scene

    out = Path(output)
    out.mkdir(parents=True, exist_ok=True)
    summary: dict[str, Any] = {"lines": [], "files": [], "seed": seed}

    demo = make_scene("chair", seed=seed, sensor=SensorModel())
    demo_path = out / "demonstration.parquet"
    io.save(demo, demo_path)  # a previous run's file is kept as a numbered backup
    summary["files"].append(str(demo_path))
    summary["demonstration"] = _demo_figures(demo)
    summary["lines"].append(
        f"demonstration: {len(demo)} bodies, {demo.n_frames} frames, "
        f"{demo.duration:.1f} s at {demo.rate:.0f} Hz, "
        f"{len(demo.labels.interactions)} labelled interactions, "
        f"{len(demo.labels.constraints)} constraints → {demo_path}"
    )
    phases = _run_segmentation(demo, out, summary)
    task = _run_plan(demo, out, summary, phases)
    if task is not None:
        _run_primitives(demo, task, out, summary)
        _run_reward(out, summary)
        _run_execution(out, summary, seed=seed)
    return summary


def _demo_figures(demo: Demonstration) -> dict[str, Any]:
    return {
        "bodies": demo.body_names,
        "n_frames": demo.n_frames,
        "duration_s": demo.duration,
        "rate_hz": demo.rate,
        "missing": {n: demo.missing_fraction(n) for n in demo.body_names},
        "plan": [f"action({s.parent}, {s.child}, {s.symbol})" for s in demo.labels.plan],
    }


def _run_segmentation(demo: Demonstration, out: Path, summary: dict[str, Any]) -> Any:
    try:
        from thirdhand.segment.pipeline import run_stage
    except ImportError:
        return None
    return run_stage(demo, out, summary)


def _run_plan(demo: Demonstration, out: Path, summary: dict[str, Any], phases: Any) -> Any:
    """Constraints, keyframes and the assembly plan → ``task.json`` and the HTML report."""
    try:
        from thirdhand.plan.learn import run_stage
    except ImportError:
        return None
    return run_stage(demo, out, summary, phases=phases)


def learned_constraint_events(task: Any) -> tuple[ConstraintEvent, ...]:
    """The task file's learned constraints as constraint events on the demonstration's clock.

    Later stages consume constraint events; feeding them the learned ones (not the
    synthetic ground truth) keeps the main job honest.
    """
    events = []
    for c in task.constraints:
        if c.time is None:
            continue
        events.append(
            ConstraintEvent(
                time=float(c.time),
                parent=c.parent,
                child=c.child,
                type=c.type,
                pos=tuple(c.pos),
                quat=tuple(c.quat),
                free_dofs=tuple(tuple(r) for r in c.free_dof_array().tolist()),
                symbol=c.symbol,
            )
        )
    return tuple(sorted(events, key=lambda e: e.time))


def _run_primitives(demo: Demonstration, task: Any, out: Path, summary: dict[str, Any]) -> None:
    """Motor primitives per learned constraint, stored in the task file's stages."""
    try:
        from thirdhand.primitives.stage import primitives_stage
    except ImportError:
        return
    from thirdhand.taskfile import load_task, save_task

    events = learned_constraint_events(task)
    if not events:
        return
    learned = demo.replace(labels=Labels(constraints=events))
    block = primitives_stage([learned])
    path = out / "task.json"
    current = load_task(path)
    current.stages["primitives"] = block
    save_task(current, path, backup=False)  # this run wrote it moments ago
    n = len(block.get("constraints", {}))
    summary["primitives"] = {"constraints": sorted(block.get("constraints", {}))}
    summary["lines"].append(
        f"primitives: {n} constraint motions (quaternion DMP + ProMP) → {path} stages.primitives"
    )


#: Part sets the learned reward plans for, to show it transfers to other sizes.
REWARD_TARGETS: dict[str, dict[str, int]] = {
    "bench": {"seating": 1, "leg": 4},
    "chair with 3 legs": {"seating": 1, "leg": 3, "back": 1},
    "chair with 5 legs": {"seating": 1, "leg": 5, "back": 1},
}


def _run_reward(out: Path, summary: dict[str, Any]) -> None:
    """Relational IRL on the learned plan; plans for other part sets, in ``stages.reward``."""
    try:
        from thirdhand.relational.assembly import (
            learn_assembly,
            load_trajectory,
            part_names,
            plan_assembly,
        )
    except ImportError:
        return
    from thirdhand.taskfile import load_task, save_task

    path = out / "task.json"
    model = learn_assembly([load_trajectory(path)], seed=0)
    plans: dict[str, Any] = {}
    for label, counts in REWARD_TARGETS.items():
        plan = plan_assembly(model, part_names(counts))
        plans[label] = {
            "complete": plan.complete,
            "perf": plan.perf,
            "steps": list(plan.steps),
        }
    current = load_task(path)
    current.stages["reward"] = {
        "method": "RCSI (relational cascaded supervised IRL) on the learned plan",
        "reward_tree": str(model.rcsi.reward),
        "plans": plans,
    }
    save_task(current, path, backup=False)  # this run wrote it moments ago
    complete = [label for label, p in plans.items() if p["complete"]]
    summary["reward"] = {"complete": complete, "targets": list(REWARD_TARGETS)}
    summary["lines"].append(
        f"reward: relational IRL on the plan; complete plans for {len(complete)}/"
        f"{len(plans)} new part sets ({', '.join(complete)}) → {path} stages.reward"
    )


def _run_execution(out: Path, summary: dict[str, Any], *, seed: int) -> None:
    """The learned plan executed offline on a simulated Panda; replay and trajectory files.

    Part meshes are looked up along ``THIRDHAND_MESH_PATH``; without them the
    parts are their bounding boxes.
    """
    try:
        from thirdhand.execute.executor import Executor
        from thirdhand.execute.record import write_run
    except ImportError:
        return
    from thirdhand.taskfile import load_task

    path = out / "task.json"
    executor = Executor.for_task(load_task(path), "panda", seed=seed, task_path=path)
    result = executor.run_offline(seed=seed)
    arm = executor.robot
    replay, trajectory = write_run(arm, result, out / "execution.parquet", task_name="chair")
    summary["files"] += [str(replay), str(trajectory)]
    done = sum(r.success for r in result.steps)
    planning = sum(r.planning_time_s for r in result.steps)
    along_primitive = sum(getattr(r, "place_motion", "") == "primitive" for r in result.steps)
    summary["execution"] = {
        "along_primitive": along_primitive,
        "robot": "panda",
        "steps": len(result.steps),
        "succeeded": done,
        "collisions": result.n_collisions,
        "planning_time_s": planning,
        "failed": [f"{r.child} ({r.status})" for r in result.steps if not r.success],
    }
    summary["lines"].append(
        f"execution: Panda, offline, {done}/{len(result.steps)} steps done, "
        f"{along_primitive} placed along their learned primitive, "
        f"{result.n_collisions} configurations in collision (dense check), "
        f"planning {planning:.1f} s → {replay} (view: thirdhand review {path} --demo {replay})"
    )
