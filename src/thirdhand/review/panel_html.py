"""The review panel's pieces of HTML and labels: pure functions of the task and the view.

:class:`~thirdhand.review.panels.Panels` puts them into viser widgets; tests read
them without a browser. Lengths are shown in cm, angles in degrees.
"""

from __future__ import annotations

import html
import math
from collections.abc import Mapping, Sequence
from typing import Any

from thirdhand.review import dofs as dofs_mod
from thirdhand.review.edits import pose_values
from thirdhand.review.playback import HAND_RGB, ROBOT_RGB, Timeline
from thirdhand.review.primitive_edit import PrimitivePath
from thirdhand.review.scene3d import PARENT_RGB, SELECTED_RGB, hex_colour
from thirdhand.task.constraint import Constraint
from thirdhand.task.geometry import DOF_NAMES
from thirdhand.taskfile import TaskFile

VALUE_NAMES = ("x", "y", "z", "roll", "pitch", "yaw")


def fmt_value(name: str, value: float) -> str:
    """A pose value as shown and typed: metres as cm, radians as degrees."""
    if name in ("x", "y", "z", "tx", "ty", "tz"):
        return f"{100.0 * value:.2f} cm"
    return f"{math.degrees(value):.1f} deg"


def step_label(i: int, step: Any) -> str:
    """``"2. leg3 on seating (c3)"``: a plan step as listed."""
    cid = f" ({step.constraint})" if step.constraint else ""
    return f"{i + 1}. {step.child} on {step.parent}{cid}"


def demo_labels(timelines: Sequence[Timeline]) -> list[str]:
    """One label per recording: ``"1: chair (64.2 s)"``."""
    out = []
    for i, tl in enumerate(timelines):
        name = tl.demo.meta.get("name") or tl.demo.meta.get("scene") or "recording"
        out.append(f"{i + 1}: {name} ({tl.end - tl.start:.1f} s)")
    return out


def index_of(value: str, labels: list[str]) -> int:
    """The 0-based step of a Step list value (0, or -1 without steps, when it names none)."""
    try:
        return int(value.split(".", 1)[0]) - 1
    except ValueError:
        return 0 if labels else -1


def live_steps_html(meta: Mapping[str, Any]) -> str:
    """The steps a live run recognised (``thirdhand live --record``), in time order, or ``""``."""
    steps = meta.get("live_steps")
    if not isinstance(steps, list) or not steps:
        return ""
    rows = []
    for s in steps:
        if not isinstance(s, Mapping):
            continue
        verb = "recognised" if s.get("kind") == "formed" else "undone"
        rows.append(
            f"<tr><td>{float(s.get('t', 0.0)):.2f} s</td><td>step {s.get('step')} {verb}</td>"
            f"<td>{html.escape(str(s.get('constraint')))}: "
            f"{html.escape(str(s.get('parent')))} ← {html.escape(str(s.get('child')))}</td></tr>"
        )
    return (
        '<div id="th-live-steps" style="padding:0 0.75em;font-size:0.85em">'
        f"live run:<table>{''.join(rows)}</table></div>"
    )


def legend_html(source: str, meta: Mapping[str, Any], replay_summary: str | None) -> str:
    """The legend of the recording played back (who holds what: ``source`` of its
    contacts); for a live run's record (``meta``), the steps it recognised; for an
    execution replay, its outcome (``replay_summary``, None: not a replay)."""
    legend = _legend(source) + live_steps_html(meta)
    if replay_summary is None:
        return legend
    return legend + (
        f'<div id="th-replay" style="padding:0 0.75em;font-size:0.85em">'
        f"{html.escape(replay_summary)}</div>"
    )


def _legend(source: str) -> str:
    if source == "execution":
        return (
            f'<div style="padding:0 0.75em;font-size:0.85em"><span style="color:'
            f'{hex_colour(ROBOT_RGB)}">■ held by the robot</span>; the tool frame drawn as '
            "axes (the robot's links are not drawn)</div>"
        )
    items = " ".join(
        f'<span style="color:{hex_colour(rgb)}">■ {side}</span>' for side, rgb in HAND_RGB.items()
    )
    return f'<div style="padding:0 0.75em;font-size:0.85em">{items}<br>contacts: {source}</div>'


def constraint_html(c: Constraint | None) -> str:
    """The constraint's type, confidence, pose and free DOFs (and its runner-up)."""
    if c is None:
        return '<div style="padding:0 0.75em;font-size:0.85em">no constraint</div>'
    rows = []
    for name, (lo, hi) in zip(DOF_NAMES, c.free_dofs.ranges(), strict=True):
        cls = dofs_mod.classify_dof(lo, hi, name)
        rng = "" if cls == "locked" else f" [{fmt_value(name, lo)}, {fmt_value(name, hi)}]"
        rows.append(f"<tr><td>{name}</td><td>{cls}{rng}</td></tr>")
    v = pose_values(c)
    pose = ", ".join(fmt_value(n, v[n]) for n in VALUE_NAMES)
    return (
        f'<div id="th-constraint" style="padding:0 0.75em;font-size:0.85em">'
        f"<b>{html.escape(c.id)}</b>: {c.type}, confidence {c.confidence:.2f}, {c.source}<br>"
        f"pose: {pose}<table>{''.join(rows)}</table>{runner_up_html(c)}</div>"
    )


def runner_up_html(c: Constraint) -> str:
    """The type the detector found next most likely, with its geometry (parent frame)."""
    ru = c.runner_up
    if ru is None:
        return ""
    parts = [f"{ru.type}, probability {ru.probability:.2f}"]
    if ru.axis is not None:
        parts.append("axis (" + ", ".join(f"{a:.2f}" for a in ru.axis) + ")")
    if ru.radius is not None:
        parts.append(f"radius {ru.radius * 100:.1f} cm")
    if ru.type == "prismatic":
        parts.append(f"travel {ru.travel * 100:.1f} cm")
    elif ru.type == "revolute":
        parts.append(f"turn {math.degrees(ru.travel):.1f}°")
    return f'<div id="th-runner-up">runner-up: {html.escape("; ".join(parts))}</div>'


def motion_html(
    task: TaskFile, c: Constraint | None, path: PrimitivePath | None, key_point: int
) -> str:
    """The selected part's learned motion: its key points (parent frame, cm) and edits,
    ``key_point`` (0-based) marked as the one the Motion panel moves."""
    pad = 'style="padding:0 0.75em;font-size:0.85em"'
    if c is None:
        return f'<div id="th-motion" {pad}>select a part to see its learned motion</div>'
    if path is None:
        return f'<div id="th-motion" {pad}>{html.escape(c.child)}: no learned motion</div>'
    assert task.stages.primitives is not None  # the path came from it
    entry = task.stages.primitives.constraints[path.key]
    rows = []
    for i, (t, p) in enumerate(zip(path.key_times, path.key_points, strict=True)):
        where = ", ".join(f"{100.0 * v:.1f}" for v in p)
        mark = " ◀" if i == key_point else ""
        rows.append(f"<tr><td>{i + 1}</td><td>{t:.1f} s</td><td>({where}) cm{mark}</td></tr>")
    edits = len(entry.edits)
    said = f", {edits} key point move(s)" if edits else ""
    return (
        f'<div id="th-motion" {pad}><b>{html.escape(path.key)}</b>: {html.escape(c.child)} '
        f"in {html.escape(c.parent)}'s frame, {path.s[-1]:.1f} s{said}"
        f"<table>{''.join(rows)}</table></div>"
    )


def band_html(
    probability: Any,
    edges: Any,
    labelled: list[tuple[float, float]],
    *,
    span: tuple[float, float],
    question: tuple[float, float] | None = None,
    mark: float | None = None,
    segments: int = 200,
) -> str:
    """A pair's CRF marginal as a band (violet, opaque where p = 1, grey where unknown) over
    the recording's time ``span`` (s), its labelled intervals as green bars under it, the
    interval asked about outlined in orange, and a started mark as a line."""
    import numpy as np

    t0, t1 = span
    width = max(t1 - t0, 1e-9)
    p = np.asarray(probability, dtype=np.float64)
    centres = 0.5 * (np.asarray(edges[:-1]) + np.asarray(edges[1:]))
    grid = np.linspace(t0, t1, segments + 1)
    stops = []
    for k in range(segments):
        inside = (centres >= grid[k]) & (centres < grid[k + 1])
        vals = p[inside]
        vals = vals[np.isfinite(vals)]
        colour = "rgba(200,200,200,1)" if vals.size == 0 else f"rgba(132,94,247,{vals.mean():.2f})"
        a, b = 100.0 * k / segments, 100.0 * (k + 1) / segments
        stops.append(f"{colour} {a:.2f}%, {colour} {b:.2f}%")

    def pct(t: float) -> float:
        return 100.0 * min(max((t - t0) / width, 0.0), 1.0)

    bars = "".join(
        f'<div class="th-label" style="position:absolute;top:0;height:100%;background:#2b8a3e;'
        f'left:{pct(s):.2f}%;width:{max(pct(e) - pct(s), 0.2):.2f}%"></div>'
        for s, e in labelled
    )
    outline = ""
    if question is not None:
        s, e = question
        outline = (
            f'<div id="th-band-q" style="position:absolute;top:-2px;height:32px;'
            f"border:2px solid {hex_colour(SELECTED_RGB)};left:{pct(s):.2f}%;"
            f'width:{max(pct(e) - pct(s), 0.4):.2f}%"></div>'
        )
    line = (
        f'<div style="position:absolute;top:-2px;height:32px;border-left:2px dashed #000;'
        f'left:{pct(mark):.2f}%"></div>'
        if mark is not None
        else ""
    )
    return (
        f'<div id="th-band" style="margin:0 0.75em;position:relative;height:28px">'
        f'<div style="height:16px;background:linear-gradient(to right, {", ".join(stops)})">'
        f'</div><div style="position:relative;height:8px;margin-top:4px;background:#e9ecef">'
        f"{bars}</div>{outline}{line}</div>"
        f'<div style="padding:0 0.75em;font-size:0.75em;color:#495057">{t0:.1f} s … {t1:.1f} s: '
        "band = the model's p(interacting); green = labelled</div>"
    )


def question_html(text: str | None, why: str) -> str:
    """The question asked (empty when none), under why it comes first (a focus, or empty)."""
    if text is None:
        return ""
    pad = "padding:0 0.75em"
    reason = f'<div id="th-focus" style="{pad};color:#1971c2">{html.escape(why)}</div>'
    return (
        reason if why else ""
    ) + f'<div id="th-question" style="{pad}">{html.escape(text)}</div>'


def plan_html(plan: Sequence[Any], shown: int | None) -> str:
    """The plan's steps as a list, the one whose keyframe is ``shown`` in bold."""
    items = []
    for i, s in enumerate(plan):
        label = html.escape(step_label(i, s))
        items.append(f"<li><b>{label}</b></li>" if i == shown else f"<li>{label}</li>")
    return (
        f'<ul id="th-plan" style="font-size:0.85em;margin:0;padding-left:1em;list-style:none">'
        f"{''.join(items)}</ul>"
    )


def keyframe_marks(
    task: TaskFile, timeline: Timeline, replay_starts: Mapping[str, float] | None
) -> list[tuple[float, str]]:
    """Where the plan's steps are on the time axis of what is played back.

    A recording of the person: each step's keyframe time; an execution replay:
    when the run began the step. Labelled with the step's number in the current
    plan order; steps off the recording's time span are left out.

    Parameters
    ----------
    task : TaskFile
    timeline : Timeline
        What is played back.
    replay_starts : mapping or None
        For an execution replay, when the run began each step (constraint id -> s);
        None for a recording of the person.

    Returns
    -------
    list of (float, str)
        Seconds (rounded to 0.01, as the slider), label; in time order.
    """
    tl = timeline
    out = []
    for i, s in enumerate(task.plan):
        t = replay_starts.get(s.constraint or "") if replay_starts is not None else s.time
        if t is not None and tl.start <= t <= tl.end:
            out.append((round(float(t), 2), str(i + 1)))
    return sorted(out)


def step_positions(n: int) -> list[str]:
    """The positions a step may move to, as listed (``"-"`` without steps)."""
    return [str(i + 1) for i in range(n)] or ["-"]


def timeline_html(task: TaskFile, chosen: int | None, shown: int | None) -> str:
    """The plan as a row of step markers in order, each with what it must follow.

    The chosen step (the one Move acts on) is orange with id ``th-tl-chosen``; the
    one whose keyframe is shown is underlined. Marker ``i`` has id ``th-tl-{i}``.
    """
    from thirdhand.review.edits import is_partial_order

    partial = is_partial_order(task)
    preds = task.predecessors()
    chips = []
    for i, s in enumerate(task.plan):
        if partial:
            after = ", ".join(str(j + 1) for j in preds[i]) or "none"
            order = f"after {after}"
        else:
            order = ""
        when = f"{s.time:.1f} s" if s.time is not None else ""
        style = (
            "display:inline-block;margin:2px;padding:2px 6px;border-radius:4px;"
            "border:1px solid #adb5bd;font-size:0.8em;line-height:1.25;text-align:center;"
        )
        if i == chosen:
            style += f"background:{hex_colour(SELECTED_RGB)};color:white;font-weight:bold;"
        if i == shown:
            style += "text-decoration:underline;"
        ident = ' id="th-tl-chosen"' if i == chosen else ""
        lines = [f"{i + 1}. {html.escape(s.child)}", html.escape(order), when]
        body = "<br>".join(x for x in lines if x)
        chips.append(
            f'<span{ident} class="th-tl-step" data-step="{i}" style="{style}">'
            f'<span id="th-tl-{i}">{body}</span></span>'
        )
    how = (
        "partial order: a step moves only where what it must follow stays before it"
        if partial
        else "the demonstration's order: any step may move"
    )
    return (
        f'<div id="th-timeline" style="padding:0 0.75em">{"&#8594;".join(chips)}'
        f'<div id="th-tl-order" style="font-size:0.75em;color:#495057">{how}</div></div>'
    )


def effort_html(effort: Any) -> str:
    """The effort log: operations per object and their total."""
    counts = effort.counts()
    rows = []
    for obj in sorted(counts):
        ops = ", ".join(f"{op} {n}" for op, n in sorted(counts[obj].items()))
        rows.append(f"<tr><td>{html.escape(obj)}</td><td>{ops}</td></tr>")
    total = effort.total()
    return (
        f'<div id="th-effort" style="padding:0 0.75em;font-size:0.85em">{total} operations'
        f"<table>{''.join(rows)}</table></div>"
    )


def status_html(task_name: str, text: str, *, error: bool, dirty: bool) -> str:
    """The status line: the task's name, whether it is saved, the last message."""
    colour = "#c92a2a" if error else "#495057"
    flag = (
        '<span id="th-dirty" style="color:#e8590c">● unsaved changes</span>'
        if dirty
        else '<span id="th-clean" style="color:#2b8a3e">saved</span>'
    )
    return (
        f'<div style="padding:0 0.75em;font-size:0.85em"><b>{html.escape(task_name)}'
        f'</b> {flag}<br><span id="th-message" style="color:{colour}">'
        f"{html.escape(text)}</span></div>"
    )


def selection_html(selected: str | None, parent: str | None, animating: str | None) -> str:
    """The selected object (orange) on its parent (blue), and the DOF being animated."""
    parts = []
    if selected is not None:
        parts.append(
            f'<span id="th-selected" style="color:{hex_colour(SELECTED_RGB)};'
            f'font-weight:bold">{html.escape(selected)}</span>'
        )
        if parent is not None:
            parts.append(
                f' on <span id="th-parent" style="color:{hex_colour(PARENT_RGB)};'
                f'font-weight:bold">{html.escape(parent)}</span>'
            )
        else:
            parts.append(" (no parent)")
    else:
        parts.append("nothing selected")
    if animating is not None:
        parts.append(f'<br><span id="th-animating">animating {animating}</span>')
    return f'<div style="padding:0 0.75em">{"".join(parts)}</div>'


def animation_label(c: Constraint, dof: str | None) -> str | None:
    """The DOF being animated as named, and whether it is locked (None: animation over)."""
    if dof is not None and dofs_mod.classify_dof(*c.free_dofs[dof], dof) == "locked":
        return f"{dof} (locked: a small swing shows its axis)"
    return dof


def phase_question_html(text: str, left: int) -> str:
    """The phase question asked (or that every one is answered) and how many are left."""
    return (
        f'<div id="th-phase-q" style="padding:0 0.75em;font-size:0.85em">'
        f"{html.escape(text)}<br>{max(left, 0)} question(s) left</div>"
    )


__all__ = [
    "VALUE_NAMES",
    "animation_label",
    "band_html",
    "constraint_html",
    "demo_labels",
    "effort_html",
    "fmt_value",
    "index_of",
    "keyframe_marks",
    "legend_html",
    "live_steps_html",
    "motion_html",
    "phase_question_html",
    "plan_html",
    "question_html",
    "runner_up_html",
    "selection_html",
    "status_html",
    "step_label",
    "step_positions",
    "timeline_html",
]
