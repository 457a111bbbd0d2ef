"""The HTML report of ``thirdhand learn``: segmentation, keyframes, constraints, plan.

One self-contained ``index.html`` (figures embedded as PNG data) per run:
the constraint-state plot (per part pair, ``p(constrained)`` over time, and the
hands' interaction phases when segmentation ran), the keyframe strip (small 3D
snapshots of every part at each keyframe), the constraint table and the plan with
its relational trajectory. matplotlib is imported lazily.
"""

from __future__ import annotations

import base64
import html
import io
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from thirdhand import se3
from thirdhand.demonstration import DOF_NAMES
from thirdhand.fileops import atomic_write_bytes

if TYPE_CHECKING:
    from thirdhand.plan.learn import Learned


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


def _strip(learned: Learned, k: int, max_frames: int = 8) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    kfs = learned.keyframes[k][:max_frames]
    parts = {n for i in learned.detections[k].instances for n in (i.parent, i.child)}
    if not kfs:
        return ""
    fig = plt.figure(figsize=(2.2 * len(kfs), 2.4))
    for j, kf in enumerate(kfs):
        ax = fig.add_subplot(1, len(kfs), j + 1, projection="3d")
        half = 0.15
        shown = [p for n, (p, _) in kf.poses.items() if n in parts]
        if shown:
            mid = np.mean(shown, axis=0)
            half = max(0.15, float(np.max(np.abs(np.asarray(shown) - mid))) + 0.05)
            ax.set_xlim(mid[0] - half, mid[0] + half)
            ax.set_ylim(mid[1] - half, mid[1] + half)
            ax.set_zlim(mid[2] - half, mid[2] + half)
        for name, (p, q) in kf.poses.items():
            if name not in parts:
                continue
            m = se3.matrix_from_quat(q)
            for c, col in enumerate(("r", "g", "b")):
                e = p + 0.2 * half * m[:, c]
                ax.plot([p[0], e[0]], [p[1], e[1]], [p[2], e[2]], col, lw=1)
            hl = name in (kf.parent, kf.child)
            ax.scatter(*p, s=18 if hl else 6, c="k" if hl else "grey")
            if hl:
                ax.text(p[0], p[1], p[2], name, fontsize=6)
        ax.set_box_aspect((1, 1, 1))
        # The constraints made so far, as parent–child links.
        for done in learned.keyframes[k][: j + 1]:
            if done.parent in kf.poses and done.child in kf.poses:
                a, b = kf.poses[done.parent][0], kf.poses[done.child][0]
                ax.plot([a[0], b[0]], [a[1], b[1]], [a[2], b[2]], "k-", lw=0.8)
        ax.set_title(f"{kf.time:.1f} s\n{kf.child} → {kf.parent}", fontsize=7)
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_zticks([])
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


def write_report(learned: Learned, folder: str | Path) -> Path:
    """Write ``index.html`` into ``folder`` (created) and return its path.

    Parameters
    ----------
    learned : thirdhand.plan.learn.Learned
    folder : path-like
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
        strip = _strip(learned, k)
        if strip:
            parts.append(f"<h3>Keyframes</h3><img src='data:image/png;base64,{strip}'>")
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
