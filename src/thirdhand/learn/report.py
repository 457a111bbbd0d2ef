"""The HTML report of ``thirdhand learn``: segmentation, keyframes, constraints, plan.

One self-contained ``index.html`` (figures embedded as PNG data) per run:
the constraint-state plot (per part pair, ``p(constrained)`` over time, and the
hands' interaction phases when segmentation ran), a 3D view of every keyframe
(the parts' meshes or boxes, the step's pair coloured), the constraint table and the plan with
its relational trajectory. matplotlib is imported lazily.
"""

from __future__ import annotations

import base64
import html
import io
import math
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from thirdhand import se3
from thirdhand.demonstration import DOF_NAMES
from thirdhand.fileops import atomic_write_bytes

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from thirdhand.learn.results import Learned
    from thirdhand.task.model import TaskFile

    FloatArray = NDArray[np.float64]


def _png(fig: Any) -> str:
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=80, bbox_inches="tight")
    plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _timeline(learned: Learned, k: int) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    det = learned.detections[k]
    phases = learned.phases[k]
    hands = [] if phases is None else [h for h in phases.hands if h.intervals]
    direct = {frozenset((i.parent, i.child)) for i in det.instances}
    rows = [(a, b) for a, b in det.pairs if frozenset((a, b)) in direct]
    n = len(rows) + len(hands)
    fig, ax = plt.subplots(figsize=(10, 0.35 * max(n, 3) + 1))
    for r, (a, b) in enumerate(rows):
        p = det.pair_posterior(a, b)
        ax.fill_between(det.times, r, r + 0.8 * p, step="mid", color="tab:blue", linewidth=0)
    for r, h in enumerate(hands, start=len(rows)):
        for s, e in h.intervals:
            ax.broken_barh([(s, e - s)], (r, 0.8), color="tab:orange")
    for inst in det.instances:
        ax.axvline(inst.start, color="k", lw=0.6, ls=":")
    labels = [f"{b} in {a}" for a, b in rows] + [f"{h.hand} holds {h.object}" for h in hands]
    ax.set_yticks(np.arange(n) + 0.4, labels, fontsize=7)
    ax.set_xlabel("time (s)")
    ax.set_title("p(constrained) per part pair (blue), hand phases (orange), keyframes (dotted)")
    return _png(fig)


#: Colours of the keyframe views: the step's child, its parent, parts already
#: assembled, parts not yet used (drawn faint).
CHILD, PARENT, DONE, LOOSE = "#e66101", "#2166ac", "#9e9e9e", "#d9d9d9"


def part_shapes(
    learned: Learned,
    k: int,
    task: TaskFile | None = None,
    task_path: str | os.PathLike[str] | None = None,
) -> dict[str, FloatArray]:
    """Each part's triangles in its body frame (metres): the task's meshes, else boxes.

    Parameters
    ----------
    learned : thirdhand.learn.results.Learned
    k : int
        The demonstration.
    task : TaskFile, optional
        Its objects' meshes (looked up beside ``task_path`` and along the mesh
        search path) or bounding boxes; without it, the recording's own geometry
        (``meta["geometry"]`` of synthetic scenes and native files).

    Returns
    -------
    dict of str to ndarray, shape (n_triangles, 3, 3)
        Parts with a known shape only.
    """
    from thirdhand.task.meshes import object_geometry, object_triangles
    from thirdhand.task.model import TaskObject

    if task is not None:
        objects = list(task.objects)
    else:
        objects = [
            TaskObject.model_validate({"name": name, **geo})
            for name, geo in object_geometry(learned.demos[k]).items()
        ]
    shapes = {}
    for obj in objects:
        tri = object_triangles(obj, task_path)
        if tri is not None:
            shapes[obj.name] = tri
    return shapes


def _keyframe_views(
    learned: Learned, k: int, shapes: dict[str, FloatArray], columns: int = 3
) -> str:
    """Every keyframe as a 3D view of the parts (meshes or boxes), the step's pair coloured.

    The step's child is orange, its parent blue, the parts assembled by earlier
    steps grey, the others faint; a black line joins the pair's origins. Views
    share one scale so that the assembly's growth reads from left to right.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    kfs = learned.keyframes[k]
    if not kfs:
        return ""
    parts = {n for i in learned.detections[k].instances for n in (i.parent, i.child)}
    parts |= {n for n in shapes if n in learned.demos[k].body_names}

    def world(name: str, pose: tuple[FloatArray, FloatArray]) -> FloatArray:
        p, q = pose
        if name in shapes:
            return shapes[name] @ se3.matrix_from_quat(q).T + p
        return np.asarray(p, float)[None, None]

    # One box around the assembly (each step's pair at its keyframe; world frame,
    # metres), so that the views share a scale and the assembly fills them.
    points = [
        world(n, kf.poses[n]).reshape(-1, 3)
        for kf in kfs
        for n in (kf.parent, kf.child)
        if n in kf.poses
    ]
    allp = np.concatenate(points)
    lo, hi = allp.min(axis=0), allp.max(axis=0)
    mid = 0.5 * (lo + hi)
    half = max(0.05, 0.5 * float(np.max(hi - lo))) * 1.1
    rows = math.ceil(len(kfs) / columns)
    fig = plt.figure(figsize=(4.2 * min(columns, len(kfs)), 4.2 * rows))
    for j, kf in enumerate(kfs):
        ax = fig.add_subplot(rows, min(columns, len(kfs)), j + 1, projection="3d")
        done = {n for e in kfs[:j] for n in (e.parent, e.child)}
        for name, (p, q) in kf.poses.items():
            if name not in parts:
                continue
            if name == kf.child:
                colour, alpha = CHILD, 0.95
            elif name == kf.parent:
                colour, alpha = PARENT, 0.9
            elif name in done:
                colour, alpha = DONE, 0.6
            else:
                colour, alpha = LOOSE, 0.25
            tri = world(name, (p, q))
            if np.any(np.abs(tri.reshape(-1, 3) - mid).max(axis=0) > half):
                continue  # lying outside the assembly's view
            if name in shapes:
                ax.add_collection3d(
                    Poly3DCollection(
                        tri,
                        facecolors=colour,
                        edgecolors=colour,
                        linewidths=0.0,
                        alpha=alpha,
                        shade=True,
                    )
                )
            else:
                ax.scatter(*p, s=30, c=colour, alpha=alpha)
        if kf.parent in kf.poses and kf.child in kf.poses:
            a, b = kf.poses[kf.parent][0], kf.poses[kf.child][0]
            ax.plot([a[0], b[0]], [a[1], b[1]], [a[2], b[2]], "k-", lw=1.2)
        ax.set_xlim(mid[0] - half, mid[0] + half)
        ax.set_ylim(mid[1] - half, mid[1] + half)
        ax.set_zlim(mid[2] - half, mid[2] + half)
        ax.set_box_aspect((1, 1, 1))
        ax.view_init(elev=25, azim=-60)
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_zticks([])
        ax.set_title(f"step {j + 1} at {kf.time:.1f} s\n{kf.child} → {kf.parent}", fontsize=11)
    return _png(fig)


def _constraint_table(learned: Learned) -> str:
    rows = []
    for k, det in enumerate(learned.detections):
        for i in det.instances:
            rng = ", ".join(
                f"{n} [{lo:.2f}, {hi:.2f}]"
                for n, (lo, hi) in zip(DOF_NAMES, i.ranges, strict=True)
                if hi > lo
            )
            rows.append(
                "<tr>"
                + "".join(
                    f"<td>{html.escape(str(v))}</td>"
                    for v in (
                        learned.names[k],
                        i.symbol or "-",
                        i.parent,
                        i.child,
                        i.type,
                        f"{i.start:.2f}",
                        "-" if i.end is None else f"{i.end:.2f}",
                        ", ".join(f"{v:.4f}" for v in i.pos),
                        ", ".join(f"{v:.3f}" for v in i.quat),
                        rng or "all locked",
                        f"{math.degrees(i.spin):.0f}°",
                        f"{i.confidence:.2f}",
                    )
                )
                + "</tr>"
            )
    head = "".join(
        f"<th>{h}</th>"
        for h in (
            "demo", "symbol", "parent", "child", "type", "start (s)", "removed (s)",
            "pos (m, parent)", "quat x y z w", "free DOFs", "spin seen", "confidence",
        )
    )  # fmt: skip
    return f"<table><tr>{head}</tr>{''.join(rows)}</table>"


def write_report(
    learned: Learned,
    folder: str | Path,
    task: TaskFile | None = None,
    task_path: str | os.PathLike[str] | None = None,
) -> Path:
    """Write ``index.html`` into ``folder`` (created) and return its path.

    Parameters
    ----------
    learned : thirdhand.learn.results.Learned
    folder : path-like
    task, task_path : TaskFile and its path, optional
        Where the parts' meshes come from (see :func:`part_shapes`).
    """
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    parts = ["<h1>thirdhand: learned assembly task</h1>"]
    parts.append(
        f"<p>{len(learned.demos)} demonstration(s): "
        + ", ".join(html.escape(n) for n in learned.names)
        + f". Root of the assembly: <b>{html.escape(str(learned.plan.root))}</b>.</p>"
    )
    parts.append("<h2>Plan</h2><ol>")
    for s in learned.plan.steps:
        dep = f" <small>after {', '.join(str(j + 1) for j in s.after)}</small>" if s.after else ""
        parts.append(f"<li><code>{html.escape(str(s))}</code>{dep}</li>")
    parts.append("</ol><h3>Relational trajectory</h3><ol start='0'>")
    for st in learned.plan.relational_trajectory():
        atoms = ", ".join(sorted(st)) or "∅"
        parts.append(f"<li><code>{html.escape(atoms)}</code></li>")
    parts.append("</ol>")
    inter = learned.plan.interchangeable()
    if inter:
        parts.append(
            "<p>Interchangeable steps: " + ", ".join(f"{i + 1}↔{j + 1}" for i, j in inter) + "</p>"
        )
    plan = learned.plan
    for k in plan.silent:
        parts.append(
            f"<p>{html.escape(learned.names[k])}: no constraint found; it does not vote on "
            "the steps.</p>"
        )
    for symbol, seen in plan.left_out.items():
        parts.append(
            f"<p>Slot <code>{html.escape(symbol)}</code> seen in {seen} of {plan.voters} "
            "recordings: not a step.</p>"
        )
    parts.append("<h2>Constraints</h2>" + _constraint_table(learned))
    for k, name in enumerate(learned.names):
        parts.append(f"<h2>{html.escape(name)}</h2>")
        parts.append(
            f"<h3>Segmentation</h3><img src='data:image/png;base64,{_timeline(learned, k)}'>"
        )
        views = _keyframe_views(learned, k, part_shapes(learned, k, task, task_path))
        if views:
            parts.append(
                "<h3>Keyframes</h3><p>At each step's keyframe: the part placed "
                f"<b style='color:{CHILD}'>(child)</b>, the part it is placed on "
                f"<b style='color:{PARENT}'>(parent)</b>, parts assembled before "
                f"<b style='color:{DONE}'>(grey)</b>.</p>"
                f"<img src='data:image/png;base64,{views}' style='max-width:100%'>"
            )
    style = (
        "<style>body{font-family:sans-serif;margin:2em}table{border-collapse:collapse;"
        "font-size:80%}td,th{border:1px solid #ccc;padding:2px 6px}</style>"
    )
    doc = (
        "<!doctype html><html><head><meta charset='utf-8'><title>thirdhand task</title>"
        f"{style}</head><body>{''.join(parts)}</body></html>"
    )
    path = out / "index.html"
    atomic_write_bytes(path, doc.encode("utf-8"))
    return path
