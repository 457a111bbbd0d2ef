"""The main job: a synthetic chair assembly through every stage.

Make the scene, learn the task in memory (:func:`thirdhand.learn.run.learn_task`:
phases, constraints, plan, primitives, relational reward, grasps), execute it on a
simulated Panda, and write each output once into the output folder; the
returned summary lists what was written and the key figures.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from thirdhand import io, jsontext
from thirdhand.demonstration import Demonstration
from thirdhand.fileops import atomic_output, write_text
from thirdhand.learn.results import LearnedTask
from thirdhand.learn.run import learn_task

#: Part sets the learned reward plans for, to show it transfers to other sizes.
REWARD_TARGETS: dict[str, list[str]] = {
    "bench": ["seating", "leg1", "leg2", "leg3", "leg4"],
    "chair with 3 legs": ["seating", "leg1", "leg2", "leg3", "back"],
    "chair with 5 legs": ["seating", "leg1", "leg2", "leg3", "leg4", "leg5", "back"],
}


def run_demo(output: str | os.PathLike[str], *, seed: int = 0) -> dict[str, Any]:
    """Generate the default chair demonstration and run every stage on it.

    Parameters
    ----------
    output : path-like
        Folder for the outputs; created if needed. Files in it are replaced, each
        previous version kept as a numbered backup.
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
    learned = learn_task([demo], reward_plans=REWARD_TARGETS, seed=0, inputs=[demo_path])
    phases = learned.learned.phases[0]
    assert phases is not None  # segmented: learn_task was not told to skip it
    _write_segmentation(phases, out, summary)
    path = _write_task(learned, out, summary)
    _run_execution(learned, path, out, summary, seed=seed)
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


def _write_segmentation(result: Any, out: Path, summary: dict[str, Any]) -> None:
    """``phases.json`` (and ``phases.png`` with the plot extra) and the segmentation figures."""
    import importlib.util

    from thirdhand.segment.pipeline import scores_by_kind

    path = out / "phases.json"
    write_text(path, jsontext.dumps(result.to_dict(), what=str(path)))
    summary["files"].append(str(path))
    scores = scores_by_kind(result)
    n_int = sum(len(p.intervals) for p in result.pairs)
    summary["segmentation"] = {
        "pairs": len(result.pairs),
        "hands": len(result.hands),
        "intervals": n_int,
        "scores": scores,
    }
    line = f"segmentation: {len(result.pairs)} pairs, {n_int} interaction intervals"
    if scores:
        line += " (frame F1 " + ", ".join(f"{k} {v['frame_f1']:.3f}" for k, v in scores.items())
        line += ")"
    summary["lines"].append(f"{line} → {path}")
    if not scores:
        return
    if importlib.util.find_spec("matplotlib") is None:
        summary["lines"].append(
            "segmentation plot: not drawn (matplotlib is not installed: "
            "pip install 'thirdhand[plot]')"
        )
        return
    from thirdhand.segment.plot import plot_phases

    png = out / "phases.png"
    with atomic_output(png) as tmp:
        plot_phases(result, tmp)
    summary["files"].append(str(png))


def _write_task(learned: LearnedTask, out: Path, summary: dict[str, Any]) -> Path:
    """``task.json`` (every stage block), the HTML report, and each stage's figures."""
    from thirdhand.learn.figures import plan_figures
    from thirdhand.learn.report import write_report
    from thirdhand.task.meshes import anchor_meshes, missing_mesh_note
    from thirdhand.taskfile import save_task

    path = out / "task.json"
    task = anchor_meshes(learned.task, path)
    save_task(task, path)
    note = missing_mesh_note(task, path)
    if note is not None:
        summary["lines"].append(note)
    summary["files"].append(str(path))
    block, line = plan_figures(learned.learned)
    summary["plan"] = block
    summary["lines"].append(f"{line} → {path}")
    index = write_report(learned.learned, out / "report", learned.task, path)
    summary["files"].append(str(index))
    summary["lines"].append(f"plan report → {index}")
    if learned.primitives is not None:
        keys = sorted(learned.primitives.constraints)
        summary["primitives"] = {"constraints": keys}
        summary["lines"].append(
            f"primitives: {len(keys)} constraint motions (quaternion DMP + ProMP) "
            f"→ {path} stages.primitives"
        )
        lib = learned.primitives.skill_library
        if lib is not None:
            seqs = {
                k: " ".join(str(s.skill) for s in c.skills[0].steps)
                for k, c in learned.primitives.constraints.items()
                if c.skills
            }
            summary["primitives"]["skills"] = seqs
            kinds = "; ".join(
                f"{s.id}: {s.typical_speed_m_s:.2g} m/s, {s.typical_angular_speed_rad_s:.2g} rad/s"
                for s in lib.summary
            )
            summary["lines"].append(
                f"skills: {lib.n_skills} library skills ({kinds}) explain the constraint "
                "motions ("
                + "; ".join(f"{k}: {v}" for k, v in sorted(seqs.items()))
                + ") → stages.primitives.skill_library"
            )
    if learned.reward is not None:
        plans = learned.reward.plans
        complete = [label for label, p in plans.items() if p.complete]
        summary["reward"] = {"complete": complete, "targets": list(plans)}
        summary["lines"].append(
            f"reward: relational IRL on the plan; complete plans for {len(complete)}/"
            f"{len(plans)} new part sets ({', '.join(complete)}) → {path} stages.reward"
        )
    for reason in learned.skipped:
        summary["lines"].append(reason)
    return path


def _run_execution(
    learned: LearnedTask, path: Path, out: Path, summary: dict[str, Any], *, seed: int
) -> None:
    """The learned plan executed offline on a simulated Panda; replay and trajectory files.

    The task is read back from ``path``: its meshes are those it recorded (found
    along ``THIRDHAND_MESH_PATH`` when learned); without them the parts are their
    bounding boxes.
    """
    from thirdhand.execute.executor import Executor
    from thirdhand.execute.record import write_run
    from thirdhand.taskfile import load_task

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
