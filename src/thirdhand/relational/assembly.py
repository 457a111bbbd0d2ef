"""Reward and policy of an assembly task learned from demonstrated plans (RCSI).

The demonstrations' plans are relational trajectories
(:mod:`thirdhand.relational.domains.plans`); RCSI learns a relational reward from
them (and random one-step transitions); value iteration on that reward then
plans the assembly of objects never demonstrated, such as a bench (no back) or a
chair with another number of legs.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from thirdhand.relational.csi import RCSIModel, fit_rcsi
from thirdhand.relational.data import random_pairs, wait_kind
from thirdhand.relational.domains.plans import (
    PlanModel,
    Trajectory,
    assembled_reward,
    expert_pairs_of,
    parts_of,
    trajectory_from_plan,
    trajectory_from_steps,
)
from thirdhand.relational.evaluate import perf_of_reward
from thirdhand.relational.logic import Atom, RelationalError
from thirdhand.relational.mdp import GroundMDP, greedy, value_iteration

GAMMA = 0.9


@dataclass
class AssemblyModel:
    """The plan types and the learned RCSI model."""

    plans: PlanModel
    rcsi: RCSIModel


#: States the relational MDP may enumerate (:func:`thirdhand.relational.mdp` default).
MAX_STATES = 500_000
#: Longest plan ``irl learn`` takes: its states are the sets of steps done, up to
#: ``2**steps``, checked before any work (2**18 = 262,144 <= :data:`MAX_STATES`).
MAX_PLAN_STEPS = 18


def load_trajectory(path: str | os.PathLike[str]) -> Trajectory:
    """The plan of a task file (``thirdhand.task/2``) as a relational trajectory.

    Raises
    ------
    TaskFileError
        If the file is not a valid task file.
    RelationalError
        If its plan is empty.
    """
    from thirdhand.task.store import load_task

    task = load_task(path)
    if not task.plan:
        raise RelationalError(
            f"{os.fspath(path)}: the task has no plan (expected at least one step)"
        )
    if len(task.plan) > MAX_PLAN_STEPS:
        raise RelationalError(
            f"{os.fspath(path)}: the plan has {len(task.plan)} steps; the relational MDP "
            f"holds every set of steps done (up to 2^{len(task.plan)} states, limit "
            f"{MAX_STATES}), so irl learn takes plans of at most {MAX_PLAN_STEPS} steps"
        )
    return trajectory_from_plan(task.plan, source=os.fspath(path))


def synth_trajectories(scene: str, seeds: Sequence[int]) -> list[Trajectory]:
    """Ground-truth plans of synthetic demonstrations (``thirdhand.synth.make_scene``)."""
    from thirdhand.synth import make_scene

    out = []
    for s in seeds:
        demo = make_scene(scene, seed=s, sensor=None)
        steps = [
            {"parent": p.parent, "child": p.child, "symbol": p.symbol} for p in demo.labels.plan
        ]
        out.append(trajectory_from_steps(steps, source=f"synth {scene} seed {s}"))
    return out


def learn_assembly(
    trajectories: Sequence[Trajectory],
    *,
    n_random: int = 300,
    reward_depth: int = 4,
    n_trees: int = 40,
    seed: int = 0,
) -> AssemblyModel:
    """Learn the reward (RCSI) from demonstrated plans.

    Demonstrations over the same objects share one grounded MDP; each MDP also
    gives ``n_random`` random one-step transitions.
    """
    plans = PlanModel.from_trajectories(trajectories)
    rng = np.random.default_rng(seed)
    mdps: dict[tuple[str, ...], GroundMDP] = {}
    expert: list[tuple[GroundMDP, np.ndarray]] = []
    for tr in trajectories:
        key = tuple(sorted(parts_of(tr)))
        if key not in mdps:
            mdps[key] = plans.ground(key)[0]
        expert.append((mdps[key], expert_pairs_of(plans, mdps[key], tr)))
    random = [(m, random_pairs(m, n_random, rng)) for m in mdps.values()]
    model = fit_rcsi(
        expert,
        random,
        gamma=GAMMA,
        n_trees=n_trees,
        reward_depth=reward_depth,
        max_vars=2,
        seed=seed,
    )
    return AssemblyModel(plans, model)


def part_names(counts: Mapping[str, int]) -> list[str]:
    """Object names for ``{type: count}``: the type alone when one, else numbered."""
    out: list[str] = []
    for t, n in counts.items():
        out += [t] if n == 1 and t != "leg" else [f"{t}{i + 1}" for i in range(n)]
    return out


@dataclass
class RewardPlan:
    """A plan made with a learned reward.

    Attributes
    ----------
    parts : list of str
    steps : list of str
        ``action(parent,child,symbol)`` up to the first wait.
    complete : bool
        Every part attached at the end.
    perf : float
        perf of the learned reward against "every part attached" (1000 states from P_state).
    """

    parts: list[str]
    steps: list[str]
    complete: bool
    perf: float


def plan_with_reward(
    model: AssemblyModel, parts: Sequence[str], *, max_steps: int = 100
) -> RewardPlan:
    """Plan with the learned reward: value iteration over the objects ``parts``.

    Raises
    ------
    RelationalError
        If ``parts`` holds fewer than two parts (nothing to attach, so no plan
        to measure), or no sampled state can reach the assembled goal (perf
        undefined).
    """
    if len(set(parts)) < 2:
        raise RelationalError(
            f"reward: a part set needs at least two parts to assemble, got {list(parts)}"
        )
    mdp, s = model.plans.ground(parts)
    reward = model.rcsi.reward_of(mdp)
    _, q = value_iteration(mdp, reward, GAMMA)
    pi = greedy(mdp, q)
    steps: list[Atom] = []
    wait = wait_kind(mdp)
    for _ in range(max_steps):
        p = int(pi[s])
        if mdp.pair_kind[p] == wait:
            break
        steps.append(mdp.action(p))
        s = int(mdp.pair_next[p])
    truth = assembled_reward(mdp)
    states = mdp.sample_states(1000, np.random.default_rng(0))
    perf = perf_of_reward(mdp, reward, truth, GAMMA, states)
    if not np.isfinite(perf):
        raise RelationalError(
            f"reward: no state of the part set {list(parts)} can reach the assembled goal "
            "(perf undefined)"
        )
    return RewardPlan(list(parts), [str(a) for a in steps], bool(truth[mdp.ptr[s]] > 0), perf)
