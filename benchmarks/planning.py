"""Motion planning per query, and collision checks per second against pinocchio's own loop.

Planning: ours (RRT-Connect over the sphere layer, ``planner="rrtconnect"``) and the
planner before it (OMPL's RRT-Connect over the exact checks, ``"ompl_rrtconnect"``) on
the same seeded pick/place-like queries for a Panda mounted on the table
(top at z = 0.75 m): four chair legs lying on both sides of a 40 cm high
screen and a seat next to the robot (the real 3rdHand meshes, or boxes of the
same size when the data folder is absent); each query goes from 12 cm above
one leg to 12 cm above the next one, across the screen, tool pointing down with
a random turn of the hand. Prints, per planner, the median planning time, the success
rate, the median number of collision checks per query, checks per second, the median
path length and the configurations in collision by coal's exact dense check of the
path; the first "planning time median" line is ours.

Collision checks: the same random configurations of that world checked by the
sphere layer alone (``CollisionScene.sphere_free_mask``: conservative, numba), by
``CollisionScene.valid_mask`` (the spheres as broad phase, coal's narrow phase on
the pairs they cannot clear), by ``valid_mask(exact=True)`` (bounding boxes and coal,
the check before this layer) and by ``pinocchio.computeCollisions`` over a
``GeometryModel`` holding exactly the same bodies and pairs
(``CollisionScene.to_pinocchio``), stopping at the first collision, in one run;
prints both rates, their ratio, and that the verdicts agree.

Steps: the synthetic chair's ground-truth task executed offline (Panda, start layouts
of ``--step-seeds``), the median and mean planning time per step (grasp × goal search,
IK, planning) and the median executed path length per step.

VAMP (``vamp-planner``) and mplib, the peers the issue names, are reported first: when
they cannot be imported the script says why instead of timing them (see
``research/notes/execution.md``, "VAMP").

Usage: ``python benchmarks/planning.py [--queries 20] [--configs 2000] [--time-limit 5]
[--step-seeds 0,1,2] [--scene chair]``
"""

from __future__ import annotations

import argparse
import itertools
import os
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

from thirdhand import se3
from thirdhand.execute import CollisionScene, Robot, plan_motion
from thirdhand.execute.collision_check import warm_up

MESHES = Path(os.environ.get("THIRDHAND_DATA", Path(__file__).parents[2] / "shared" / "data"))
MESHES = MESHES / "3rdhand" / "meshes"
TABLE_Z = 0.75
PEERS = {
    "rrtconnect": "thirdhand RRT-Connect over the sphere layer (ours)",
    "ompl_rrtconnect": "OMPL RRT-Connect over the exact checks (before)",
}
DOWN = np.array([1.0, 0.0, 0.0, 0.0])


def build_world(robot: Robot, seed: int) -> tuple[CollisionScene, list[np.ndarray]]:
    """A table with four legs lying down and a seat; returns the scene and the part positions."""
    rng = np.random.default_rng(seed)
    scene = CollisionScene(robot)
    scene.add_table(height=TABLE_Z)
    leg, seat = MESHES / "chair_leg.stl", MESHES / "chair_seating.stl"
    have = leg.is_file() and seat.is_file()
    seat_pos = np.array([0.25, 0.0, TABLE_Z])
    scene.add_box("screen", ([0.6, 0.0, TABLE_Z + 0.2], se3.quat_identity()), (0.3, 0.04, 0.4))
    if have:
        scene.add_object("seat", (seat_pos, se3.quat_identity()), mesh_path=seat)
    else:
        scene.add_object(
            "seat", (seat_pos, se3.quat_identity()), size=(0.3, 0.3, 0.02), box_center=(0, 0, 0.01)
        )
    parts = []
    lying = se3.quat_multiply(
        [0, 0, np.sin(0.0), 1.0], [0, np.sin(np.pi / 4), 0, np.cos(np.pi / 4)]
    )
    for k in range(4):
        side = -1 if k % 2 == 0 else 1
        pos = np.array([rng.uniform(0.4, 0.7), side * rng.uniform(0.25, 0.5), TABLE_Z + 0.04])
        yaw = rng.uniform(-np.pi, np.pi)
        quat = se3.quat_multiply([0, 0, np.sin(yaw / 2), np.cos(yaw / 2)], lying)
        if have:
            scene.add_object(f"leg{k}", (pos, quat), mesh_path=leg)
        else:
            scene.add_object(
                f"leg{k}", (pos, quat), size=(0.08, 0.08, 0.28), box_center=(0, 0, 0.14)
            )
        parts.append(pos)
    return scene, parts


def queries(
    robot: Robot, scene: CollisionScene, spots: list[np.ndarray], rng: np.random.Generator
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Valid configurations 12 cm above each spot; pairs of consecutive ones."""
    above = []
    for target in spots:
        yaw = rng.uniform(-np.pi / 2, np.pi / 2)
        quat = se3.quat_multiply([0, 0, np.sin(yaw / 2), np.cos(yaw / 2)], DOWN)
        above.append(
            robot.ik((target + np.array([0.0, 0.0, 0.12]), quat), seed=rng, accept=scene.is_valid)
        )
    return [(a, b) for a, b in itertools.pairwise(above) if a is not None and b is not None]


def bench_planning(robot: Robot, n_queries: int, time_limit: float) -> None:
    """Ours (RRT-Connect over the sphere layer) and today's (OMPL's) on the same queries."""
    rows: dict[str, dict[str, list[float]]] = {p: {} for p in PEERS}
    statuses: dict[str, dict[str, int]] = {p: {} for p in PEERS}
    seed = 0
    done = 0
    while done < n_queries:
        scene, spots = build_world(robot, seed)
        for qa, qb in queries(robot, scene, spots, np.random.default_rng(seed)):
            if done >= n_queries:
                break
            for planner in PEERS:
                # before: OMPL over the checks as they were (bounding boxes, then coal)
                scene.use_spheres = planner == "rrtconnect"
                res = plan_motion(robot, scene, qa, qb, seed=seed, time_limit=time_limit,
                                  planner=planner)  # fmt: skip
                scene.use_spheres = True
                r = rows[planner]
                bad = 0
                if res.success and res.path is not None:
                    # the exact dense check: coal alone, twice the planner's density
                    dense = scene.interpolate(res.path, max_step_m=0.005, max_step_rad=0.01)
                    bad = int(np.count_nonzero(~scene.valid_mask(dense, exact=True)))
                    r.setdefault("length", []).append(res.joint_length_rad)
                r.setdefault("time", []).append(res.planning_time_s)
                r.setdefault("checks", []).append(res.n_checks)
                r.setdefault("ok", []).append(float(res.success))
                r.setdefault("bad", []).append(bad)
                key = res.status.split(":")[0]
                statuses[planner][key] = statuses[planner].get(key, 0) + 1
            done += 1
        seed += 1
    print(
        f"planning: {done} queries, Panda, table + screen + 4 legs + seat, RRT-Connect, "
        f"{time_limit} s limit"
    )
    for planner, label in PEERS.items():
        r = rows[planner]
        t = np.array(r["time"])
        rate = np.sum(r["checks"]) / np.sum(t)
        length = np.median(r["length"]) if r.get("length") else float("nan")
        head = "" if planner == "rrtconnect" else "OMPL "
        print(f"  {label}")
        print(f"    success {int(sum(r['ok']))}/{done}   outcomes {statuses[planner]}")
        print(
            f"    {head}planning time median {np.median(t) * 1e3:.0f} ms   "
            f"p90 {np.percentile(t, 90) * 1e3:.0f} ms   max {t.max() * 1e3:.0f} ms"
        )
        print(
            f"    collision checks per query median {int(np.median(r['checks']))}   "
            f"{rate:.0f} checks/s   path median {length:.2f} rad   "
            f"configurations in collision (exact dense check) {int(sum(r['bad']))}"
        )
    t_new = np.median(rows["rrtconnect"]["time"])
    t_old = np.median(rows["ompl_rrtconnect"]["time"])
    print(f"  ratio OMPL / ours (median query time) {t_old / t_new:.1f}")


def bench_checks(robot: Robot, n_configs: int) -> None:
    scene, _ = build_world(robot, 0)
    qs = robot.random_q(np.random.default_rng(1), n_configs)
    gm, gd = scene.to_pinocchio()
    best = {"spheres": np.inf, "ours": np.inf, "exact": np.inf, "peer": np.inf}
    single_best = np.inf
    scene.sphere_free_mask(qs[:10])  # compile (or load the compiled kernels)
    for _ in range(3):
        t0 = time.perf_counter()
        free = scene.sphere_free_mask(qs)
        best["spheres"] = min(best["spheres"], time.perf_counter() - t0)
        t0 = time.perf_counter()
        ours = scene.valid_mask(qs)
        best["ours"] = min(best["ours"], time.perf_counter() - t0)
        t0 = time.perf_counter()
        exact = scene.valid_mask(qs, exact=True)
        best["exact"] = min(best["exact"], time.perf_counter() - t0)
        t0 = time.perf_counter()
        for q in qs[: n_configs // 4]:
            scene.is_valid(q)
        single_best = min(single_best, (time.perf_counter() - t0) / (n_configs // 4))
        t0 = time.perf_counter()
        peer = np.array(
            [not pin.computeCollisions(robot.model, robot.data, gm, gd, q, True) for q in qs]
        )
        best["peer"] = min(best["peer"], time.perf_counter() - t0)
    n_pairs = len(gm.collisionPairs)
    print(
        f"collision checks: {n_configs} random configurations, {n_pairs} active pairs, "
        f"{ours.mean():.0%} valid, verdicts agree on {np.mean(ours == peer):.1%}"
    )
    rate = {k: n_configs / v for k, v in best.items()}
    print(
        f"  sphere layer alone (batched, numba)  {rate['spheres']:10.0f} checks/s   "
        f"{free.mean():.0%} proven free, {int(np.sum(free & ~exact))} of them in collision"
    )
    print(f"  thirdhand valid_mask (batched)      {rate['ours']:10.0f} checks/s")
    print(f"  bounding boxes + coal (before)      {rate['exact']:10.0f} checks/s")
    print(f"  thirdhand is_valid (one at a time)  {1.0 / single_best:10.0f} checks/s")
    print(f"  pinocchio computeCollisions loop    {rate['peer']:10.0f} checks/s")
    print(f"  ratio thirdhand batched / pinocchio {rate['ours'] / rate['peer']:.2f}")
    print(f"  ratio sphere layer / pinocchio      {rate['spheres'] / rate['peer']:.1f}")


def bench_steps(scene: str, seeds: list[int]) -> None:
    """Execute the synthetic task offline per seed; planning time per step."""
    from thirdhand.execute.executor import ExecutionOptions, Executor
    from thirdhand.execute.layout import make_workcell, start_layout
    from thirdhand.synth import make_scene
    from thirdhand.synth.task import truth_task

    search = [str(MESHES)] if MESHES.is_dir() else []
    task = truth_task(make_scene(scene, seed=0))
    cell = make_workcell(task, search=search)
    robot = Robot.load("panda", base_pose=(cell.robot_base[:3, 3], [0.0, 0.0, 0.0, 1.0]))
    times, lengths, ok = [], [], 0
    for seed in seeds:
        start = start_layout(task, cell, seed, search=search)
        ex = Executor(robot, task, cell, start, ExecutionOptions(), search=search)
        result = ex.run_offline(seed=seed)
        times += [r.planning_time_s for r in result.steps]
        lengths += [r.joint_length_rad for r in result.steps]
        ok += sum(r.success for r in result.steps)
    t = np.array(times)
    print(f"steps: {scene}, seeds {seeds}, offline, Panda: {ok}/{len(times)} steps succeeded")
    print(
        f"  planning time per step median {np.median(t):.2f} s   mean {t.mean():.2f} s   "
        f"max {t.max():.2f} s   executed path median {np.median(lengths):.1f} rad"
    )


def vamp_status() -> str:
    """One line: whether the VAMP peer can be benchmarked here, and if not, why."""
    import importlib.util
    import sys

    if importlib.util.find_spec("vamp") is not None:
        return "VAMP: importable, but not benchmarked (our world is not given to it as spheres)"
    py = f"{sys.version_info.major}.{sys.version_info.minor}"
    return (
        f"VAMP: not installed; vamp-planner 0.6.4 ships wheels for the cp312 stable ABI only, "
        f"so on Python {py} pip must build its C++ from the sdist "
        "(research/notes/execution.md, VAMP)"
    )


def mplib_status() -> str:
    """One line: whether mplib can be benchmarked here, and if not, why."""
    import importlib.util

    if importlib.util.find_spec("mplib") is not None:
        return "mplib: importable, but not benchmarked (its world is not built from ours yet)"
    return (
        f"mplib: not installed; mplib 0.2.1 has a cp311 wheel but requires numpy < 2.0 "
        f"(here numpy {np.__version__}); OMPL 2.0.1 is the 'before' planner below"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--queries", type=int, default=20)
    parser.add_argument("--configs", type=int, default=2000)
    parser.add_argument("--time-limit", type=float, default=5.0)
    parser.add_argument("--step-seeds", default="0,1,2", help="Start layouts ('' to skip).")
    parser.add_argument("--scene", default="chair", choices=["chair", "bench"])
    args = parser.parse_args()
    robot = Robot.load("panda", base_pose=([0.0, 0.0, TABLE_Z], [0.0, 0.0, 0.0, 1.0]))
    print(vamp_status())
    print(mplib_status())
    print(f"meshes: {'real STL' if (MESHES / 'chair_leg.stl').is_file() else 'boxes (no data)'}")
    # Compile (fresh checkout) or load the kernels before any clock runs: a compile inside a
    # query would be counted as planning time, and can even time the query out.
    t0 = time.perf_counter()
    warm_up()
    print(f"kernels compiled or loaded in {time.perf_counter() - t0:.1f} s (not timed below)")
    if args.configs > 0:
        bench_checks(robot, args.configs)
    if args.queries > 0:
        bench_planning(robot, args.queries, args.time_limit)
    if args.step_seeds:
        bench_steps(args.scene, [int(v) for v in args.step_seeds.split(",")])


if __name__ == "__main__":
    main()
