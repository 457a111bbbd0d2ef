"""The assembly tree of detected constraints: rigid groups, root, parents, instances."""

from __future__ import annotations

import numpy as np

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.constraints.detect_dofs import _free_spin, _joint_dofs
from thirdhand.constraints.detect_runs import _Run, _run_pose
from thirdhand.constraints.detect_types import ConstraintInstance, DetectOptions, PairTracks


def _assign_parents(
    tracks: PairTracks,
    candidates: list[_Run],
    th_p: FloatArray,
    t_end: float,
    motion: dict[str, float],
    opt: DetectOptions,
    noise: tuple[float, float],
) -> tuple[list[ConstraintInstance], str | None]:
    """Keep, in time order, the runs that join two rigid groups of parts.

    The groups at a moment are the connected components of the direct constraints
    active then (started, not yet removed), so a part taken off and put back joins
    again. The root is the part with most direct constraints at the end of the
    recording (then most overall; a short spurious constraint, made and removed,
    must not make a leg the base); among equals, the one that travelled least in
    the world (the base stays put while parts are brought to it). ``noise`` is the
    constraint-state noise the HMM learned (metres, radians): a run starts where its
    parts settle (:func:`_settled_start`).
    """
    pairs, times = tracks.pairs, tracks.times
    n_steps = times.size
    direct: list[_Run] = []
    degree: dict[str, int] = {}

    def groups(t: float) -> dict[str, int]:
        parent: dict[str, str] = {}

        def root_of(n: str) -> str:
            while parent.get(n, n) != n:
                n = parent[n]
            return n

        for c in direct:
            active = c.start <= t + 1e-9 and (c.hi >= n_steps - 1 or times[c.hi - 1] > t)
            if active:
                a, b = pairs[c.k]
                ra, rb = root_of(a), root_of(b)
                if ra != rb:
                    parent[rb] = ra
        names = {n for pr in pairs for n in pr}
        roots = sorted({root_of(n) for n in names})
        return {n: roots.index(root_of(n)) for n in names}

    # Runs starting within ``simultaneity`` seconds of each other are decided together.
    batches: list[list[_Run]] = []
    for c in candidates:
        if batches and c.start - batches[-1][0].start <= opt.simultaneity:
            batches[-1].append(c)
        else:
            batches.append([c])
    for batch in batches:
        t0 = max(c.start for c in batch)
        group = groups(t0)
        # The hub counts the constraints active now (a removed spurious one does not).
        active_degree: dict[str, int] = {}
        for d in direct:
            if d.hi >= n_steps - 1 or times[d.hi - 1] > t0:
                for n in pairs[d.k]:
                    active_degree[n] = active_degree.get(n, 0) + 1
        # Among runs joining the same two groups: the hub among the near parts.
        options: dict[tuple[int, int], list[tuple[float, int, _Run]]] = {}
        for c in batch:
            a, b = pairs[c.k]
            ga, gb = group[a], group[b]
            if ga != gb:
                hub = max(active_degree.get(a, 0), active_degree.get(b, 0))
                dist = float(np.linalg.norm(th_p[c.k]))
                options.setdefault((min(ga, gb), max(ga, gb)), []).append((dist, hub, c))
        best: dict[tuple[int, int], _Run] = {}
        for key, opts in options.items():
            near = min(o[0] for o in opts) * opt.near_ratio + 0.01
            pick = min((o for o in opts if o[0] <= near), key=lambda o: (-o[1], o[0], o[2].k))
            best[key] = pick[2]
        for _, c in sorted(best.items()):
            a, b = pairs[c.k]
            group = groups(t0)
            if group[a] == group[b]:
                continue
            direct.append(c)
            for n in (a, b):
                degree[n] = degree.get(n, 0) + 1
    if not direct:
        return [], None
    final: dict[str, int] = {}
    for c in direct:
        if c.hi >= n_steps - 1:
            for n in pairs[c.k]:
                final[n] = final.get(n, 0) + 1
    root = min(sorted(degree), key=lambda n: (-final.get(n, 0), -degree[n], motion.get(n, 0.0)))
    parent_of = _orient([pairs[c.k] for c in direct], root)
    out = []
    for c in direct:
        a, b = pairs[c.k]
        child = b if parent_of.get(b) == a else a
        parent = a if child == b else b
        out.append(_instance(tracks, c, parent, child, th_p, t_end, opt, noise))
    return out, root


#: A run's parts hold its pose within this many constraint-noise levels (the HMM's
#: per-axis sigma): the 97th percentile of the norm of 3-d Gaussian noise.
SETTLED_SIGMA = 3.0


def _settled_start(
    p: FloatArray,
    q: FloatArray,
    lo: int,
    hi: int,
    pos: FloatArray,
    quat: FloatArray,
    noise: tuple[float, float],
    n_hold: int,
) -> int:
    """First step of a fixed-pose run from which its parts hold the run's pose.

    The HMM's smoother may open a run where the parts first pass through the pose
    while they still slide along each other (a real toolbox's boards: 1.5 s, 3 cm
    either way), and a brief pass joins the run as the same pose. The run starts at
    its first valid step that lies within :data:`SETTLED_SIGMA` noise levels of the
    run's pose ``pos``, ``quat`` (in position and in rotation), and whose next
    ``n_hold`` steps do so in the median (so that one noisy step neither delays nor
    advances the start); at ``lo`` when there is none.

    Parameters
    ----------
    p : ndarray, shape (n_steps, 3), metres
    q : ndarray, shape (n_steps, 4), x y z w
        The pair's relative pose per step, in the frame ``pos``, ``quat`` is in.
    lo, hi : int
        The run's steps ``[lo, hi)``.
    noise : tuple of (float, float)
        Constraint-state noise per axis, metres and radians.
    n_hold : int
        Steps the pose must hold.
    """
    dp = np.linalg.norm(p[lo:hi] - pos, axis=1) / noise[0]
    dr = se3.quat_angle(q[lo:hi], np.broadcast_to(quat, (hi - lo, 4))) / noise[1]
    dev = np.maximum(dp, dr)  # NaN where a part is not tracked
    for s in np.flatnonzero(dev <= SETTLED_SIGMA):
        if np.nanmedian(dev[s : s + n_hold]) <= SETTLED_SIGMA:
            return lo + int(s)
    return lo


def _orient(edges: list[tuple[str, str]], root: str) -> dict[str, str]:
    """Parent of each part in the tree of direct constraints, by breadth-first search."""
    adj: dict[str, list[str]] = {}
    for a, b in edges:
        adj.setdefault(a, []).append(b)
        adj.setdefault(b, []).append(a)
    parent: dict[str, str] = {}
    seen = {root}
    frontier = [root]
    while frontier:
        nxt = []
        for n in frontier:
            for m in sorted(adj.get(n, [])):
                if m not in seen:
                    seen.add(m)
                    parent[m] = n
                    nxt.append(m)
        frontier = nxt
    # Components without the root: each edge oriented as the pair is named.
    for a, b in edges:
        if a not in seen and b not in seen:
            parent[b] = a
            seen |= {a, b}
    return parent


def _instance(
    tracks: PairTracks,
    c: _Run,
    parent: str,
    child: str,
    th_p: FloatArray,
    t_end: float,
    opt: DetectOptions,
    noise: tuple[float, float],
) -> ConstraintInstance:
    k, lo, hi = c.k, c.lo, c.hi
    rel_p, rel_q, times = tracks.rel_p, tracks.rel_q, tracks.times
    a, _ = tracks.pairs[k]
    p_run, q_run = rel_p[k], rel_q[k]
    pos, quat = _run_pose(p_run[lo:hi], q_run[lo:hi], th_p[k], c.held[lo:hi])
    if not c.joint:
        n_hold = max(1, round(opt.min_duration / tracks.step))
        lo = _settled_start(p_run, q_run, lo, hi, pos, quat, noise, n_hold)
    if parent != a:
        pos, quat = se3.pose_invert(pos, quat)
        p_run, q_run = se3.pose_invert(rel_p[k], rel_q[k])
    step = tracks.step
    start = float(times[lo] - 0.5 * step)
    end = None if hi >= times.size - 1 else float(times[hi - 1] + 0.5 * step)
    frame_p = np.zeros(3)
    joint = _joint_dofs(p_run[lo:hi], q_run[lo:hi]) if c.joint else None
    runner_up = None
    if joint is not None:
        typ, frame_p, frame_q, ranges, runner_up = joint
        spin = 0.0
    else:
        raw = None
        if tracks.demo is not None and tracks.edges is not None:
            rp, rq, valid = tracks.demo.relative_pose(parent, child)
            raw = (tracks.demo.t[valid], rp[valid], rq[valid], tracks.edges)
        frame_q, ranges, spin = _free_spin(p_run, q_run, lo, pos, quat, opt, raw=raw)
        typ = "revolute" if np.any(ranges[3:, 1] > ranges[3:, 0]) else "fixed"
    return ConstraintInstance(
        parent=parent,
        child=child,
        type=typ,
        start=max(start, float(times[0])),
        end=None if end is None or end >= t_end else end,
        pos=pos,
        quat=quat,
        frame_pos=frame_p,
        frame_quat=frame_q,
        ranges=ranges,
        confidence=c.conf,
        spin=spin,
        runner_up=runner_up,
    )
