"""The review GUI's control panel: viser widgets wired to :class:`~thirdhand.review.app.ReviewApp`.

Every callback calls one app action and nothing else; a refused action shows
its one-line message (status line + notification) and changes nothing. A
widget updated by the server (a new selection fills the editors) fires its own
callback with no client: those events are ignored, so only a person's input
becomes an edit.
"""

from __future__ import annotations

import html
import math
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

import viser
from viser._messages import GuiSliderMark

from thirdhand.errors import ThirdhandError
from thirdhand.review import dofs as dofs_mod
from thirdhand.review.edits import SetDofRange, SetParent, parse_number, pose_values
from thirdhand.review.playback import HAND_RGB, ROBOT_RGB
from thirdhand.review.primitive_edit import KEY_FRACTIONS
from thirdhand.review.scene3d import PARENT_RGB, SELECTED_RGB, hex_colour
from thirdhand.review.shortcuts import shortcuts_html
from thirdhand.task.constraint import Constraint
from thirdhand.task.geometry import DOF_NAMES

if TYPE_CHECKING:
    from thirdhand.review.app import ReviewApp

NONE = "(none)"
VALUE_NAMES = ("x", "y", "z", "roll", "pitch", "yaw")
#: Rough-adjustment steps: cm for x y z, degrees for roll pitch yaw.
NUDGE_STEPS = ("-5", "-1", "+1", "+5")


def fmt_value(name: str, value: float) -> str:
    """A pose value as shown and typed: metres as cm, radians as degrees."""
    if name in ("x", "y", "z", "tx", "ty", "tz"):
        return f"{100.0 * value:.2f} cm"
    return f"{math.degrees(value):.1f} deg"


def _user(event: Any) -> bool:
    """True for an event a person caused (the server's own updates carry no client)."""
    return getattr(event, "client", None) is not None


def step_label(i: int, step: Any) -> str:
    """``"2. leg3 on seating (c3)"``: a plan step as listed."""
    cid = f" ({step.constraint})" if step.constraint else ""
    return f"{i + 1}. {step.child} on {step.parent}{cid}"


class Panels:
    """Build the control panel of ``app`` (its server must be running)."""

    def __init__(self, app: ReviewApp) -> None:
        assert app.server is not None
        self.app = app
        gui = app.server.gui
        self._shown: dict[str, str] = {}
        #: Per input handle (by id), the value the server or the editing tab set last:
        #: what a read-only tab's change is undone to.
        self._last: dict[int, Any] = {}
        self.status = gui.add_html("")
        self.shortcuts = gui.add_html(shortcuts_html())
        self.undo = gui.add_button("Undo", icon=viser.Icon.ARROW_BACK_UP)
        self.redo = gui.add_button("Redo", icon=viser.Icon.ARROW_FORWARD_UP)
        self.save = gui.add_button("Save", icon=viser.Icon.DEVICE_FLOPPY)
        self.reload = gui.add_button("Reload")
        self.quit = gui.add_button("Quit")
        self._on(self.undo.on_click, lambda e: app.attempt(app.undo))
        self._on(self.redo.on_click, lambda e: app.attempt(app.redo))
        self._on(self.save.on_click, lambda e: app.attempt(app.save))
        self._on(self.reload.on_click, lambda e: self._confirm_discard("reload"))
        self._on(self.quit.on_click, lambda e: self._confirm_discard("quit"))

        names = list(app.parts.names) if app.parts is not None else []
        with gui.add_folder("Object"):
            self.object = gui.add_dropdown("Object", [NONE, *names], initial_value=NONE)
            self.selection = gui.add_html("")
            self.info = gui.add_html("")
            self.animate = gui.add_button("Animate DOFs")
            self.frame = gui.add_button("Frame selection")
        self._on(self.object.on_update, self._object_chosen)
        self._on(self.animate.on_click, lambda e: app.attempt(app.animate_dofs))
        # Framing only moves the asking tab's camera: a read-only tab may frame too.
        self.frame.on_click(
            lambda e: app.attempt(app.frame_selection, e.client) if _user(e) else None
        )

        with gui.add_folder("Correct"):
            # Plain inputs, not a form: the client sends a value and a form's "dirty"
            # notice through one throttled slot, where the value can be dropped.
            gui.add_markdown("**Pose in the parent frame** (type e.g. `12 cm`, `90 deg`)")
            self.values = {n: gui.add_text(n, "") for n in VALUE_NAMES}
            self.apply_values = gui.add_button("Apply values")
            self.nudge_what = gui.add_dropdown("Nudge", list(VALUE_NAMES), initial_value="x")
            self.nudge = gui.add_button_group("cm / deg", NUDGE_STEPS)
            self.dof = gui.add_dropdown("DOF", list(DOF_NAMES), initial_value="rz")
            self.dof_lo = gui.add_text("min", "")
            self.dof_hi = gui.add_text("max", "")
            self.set_range = gui.add_button("Set range")
            self.new_parent = gui.add_dropdown("New parent", [NONE, *names], initial_value=NONE)
            self.set_parent = gui.add_button("Change parent")
            self.gizmo_edits = gui.add_checkbox("Gizmo edits pose", False)
        self._on(self.apply_values.on_click, lambda e: app.attempt(self._submit_values))
        self._on(self.nudge.on_click, self._nudged)
        self._on(self.dof.on_update, lambda e: self._fill_range())
        self._on(self.set_range.on_click, lambda e: app.attempt(self._submit_range))
        self._on(self.set_parent.on_click, lambda e: app.attempt(self._submit_parent))
        self._on(
            self.gizmo_edits.on_update,
            lambda e: (
                app.attempt(app.set_gizmo_edits, self.gizmo_edits.value) if _user(e) else None
            ),
        )

        with gui.add_folder("Motion"):
            # The learned motion (DMP rollout) of the selected part, drawn as a violet path
            # with key points; moving one refits the motion.
            self.motion_info = gui.add_html("")
            self.key_point = gui.add_dropdown(
                "Key point", [str(i + 1) for i in range(len(KEY_FRACTIONS))], initial_value="1"
            )
            self.key_values = {n: gui.add_text(f"key {n}", "") for n in "xyz"}
            self.move_key = gui.add_button("Move key point")
        self._on(
            self.key_point.on_update,
            lambda e: (
                app.attempt(app.choose_key_point, int(self.key_point.value) - 1)
                if _user(e)
                else None
            ),
        )
        self._on(self.move_key.on_click, lambda e: app.attempt(self._submit_key_point))

        with gui.add_folder("Keyframes"):
            self.plan = gui.add_html("")
            self.step = gui.add_dropdown("Step", ["-"], initial_value="-")
            self.up = gui.add_button("Up")
            self.down = gui.add_button("Down")
            self.show_kf = gui.add_button("Show keyframe")
            self.show_all = gui.add_button("Show assembled")
        self._on(self.step.on_update, self._step_chosen)
        self._on(
            self.up.on_click, lambda e: app.attempt(lambda: app.move_step(self._step_index(), -1))
        )
        self._on(
            self.down.on_click, lambda e: app.attempt(lambda: app.move_step(self._step_index(), 1))
        )
        self._on(
            self.show_kf.on_click, lambda e: app.attempt(lambda: app.show_step(self._step_index()))
        )
        self._on(self.show_all.on_click, lambda e: app.attempt(app.show_step, None))

        with gui.add_folder("Plan timeline"):
            # viser has no drag-and-drop: a marker button chooses (and shows) a step,
            # "Move to" + "Move step" reorder it; the partial order decides what may move.
            self.timeline = gui.add_html("")
            positions = _positions(len(app.task.plan))
            self.markers = gui.add_button_group("Go to step", positions)
            self.move_to = gui.add_dropdown("Move to", positions, initial_value=positions[0])
            self.move = gui.add_button("Move step")
        self._on(self.markers.on_click, self._marker_clicked)
        self._on(
            self.move.on_click,
            lambda e: app.attempt(
                lambda: app.move_step_to(self._chosen(), int(self.move_to.value) - 1)
            ),
        )

        with gui.add_folder("Clarify"):
            self.start_q = gui.add_button("Start clarification")
            self.question = gui.add_html("")
            self.yes = gui.add_button("Yes, right", visible=False, color="green")
            self.no = gui.add_button("No, wrong", visible=False, color="red")
        self._on(self.start_q.on_click, lambda e: app.attempt(app.start_clarification))
        self._on(self.yes.on_click, lambda e: app.attempt(app.answer, True))
        self._on(self.no.on_click, lambda e: app.attempt(app.answer, False))

        self.time = None
        if app.motion.timelines:
            tl = app.motion.timelines[app.motion.demo_index]
            with gui.add_folder("Playback"):
                self.demo = gui.add_dropdown(
                    "Recording",
                    demo_labels(app),
                    initial_value=demo_labels(app)[app.motion.demo_index],
                    visible=len(app.motion.timelines) > 1,
                )
                self.time = gui.add_slider(
                    "Time (s)",
                    min=round(tl.start, 2),
                    max=round(tl.end, 2),
                    step=0.05,
                    initial_value=round(tl.start, 2),
                )
                self.play = gui.add_button("Play")
                self.speed = gui.add_number("Speed", 1.0, min=0.1, max=10.0, step=0.1)
                self.back = gui.add_button("Show task")
                self.legend = gui.add_html(_legend_of(app))
            slider = self.time
            self._on(
                slider.on_update,
                lambda e: app.attempt(app.motion.set_time, slider.value) if _user(e) else None,
            )
            self._on(
                self.play.on_click,
                lambda e: app.attempt(
                    app.motion.play, not app.motion.playing, speed=float(self.speed.value)
                ),
            )
            self._on(self.back.on_click, lambda e: app.attempt(app.show_task))
            self._on(
                self.demo.on_update,
                lambda e: (
                    app.attempt(app.motion.set_demo, demo_labels(app).index(self.demo.value))
                    if _user(e)
                    else None
                ),
            )

        self.label_band = None
        if app.demos:
            with gui.add_folder("Label phases", expand_by_default=False):
                # The CRF's marginal of a pair as a band, the labels under it; the most
                # uncertain intervals are asked first (calibration labels for segment train).
                self.start_labels = gui.add_button("Start labelling")
                self.label_pair = gui.add_dropdown("Pair", ["-"], initial_value="-")
                self.label_band = gui.add_html("")
                self.phase_question = gui.add_html("")
                self.phase_yes = gui.add_button("Interacting", color="green", visible=False)
                self.phase_no = gui.add_button("Not interacting", color="red", visible=False)
                self.mark_from = gui.add_button("From here")
                self.mark_to = gui.add_button_group("To here", ("interacting", "not"))
                self.save_labels = gui.add_button("Save labels")
            self._on(self.start_labels.on_click, lambda e: app.attempt_long(app.start_labelling))
            self._on(self.phase_yes.on_click, lambda e: app.attempt(app.answer_phase, True))
            self._on(self.phase_no.on_click, lambda e: app.attempt(app.answer_phase, False))
            self._on(self.mark_from.on_click, lambda e: app.attempt(app.mark_from_here))
            self._on(
                self.mark_to.on_click,
                lambda e: app.attempt(app.mark_to_here, self.mark_to.value == "interacting"),
            )
            self._on(self.save_labels.on_click, lambda e: app.attempt(app.save_phase_labels))
            self._on(self.label_pair.on_update, self._label_pair_chosen)

        with gui.add_folder("Effort", expand_by_default=False):
            self.effort = gui.add_html("")

        # Typing in a read-only tab must not change what the editing tab will apply.
        for text in (*self.values.values(), *self.key_values.values(), self.dof_lo, self.dof_hi):
            text.on_update(self._typing_of(text))
        for choice in (
            self.object,
            self.nudge_what,
            self.dof,
            self.new_parent,
            self.step,
            self.move_to,
            self.key_point,
        ):
            self._last[id(choice)] = choice.value
        if self.time is not None:
            self._last[id(self.demo)] = self.demo.value
        gui.set_panel_label("thirdhand review")

    # ---------------------------------------------------------------- one editor
    def _on(self, register: Any, fn: Callable[[Any], Any]) -> None:
        """Register ``fn`` for a widget event, refused (and undone) from a read-only tab."""

        def gated(event: Any) -> Any:
            if _user(event) and not self.app.may_edit(event.client_id):
                self._refuse(event)
                return None
            return fn(event)

        register(gated)

    def _refuse(self, event: Any) -> None:
        """Tell a read-only tab why nothing happened; undo its change of an input."""
        target = getattr(event, "target", None)
        if target is not None and id(target) in self._last:
            target.value = self._last[id(target)]
        gate = self.app.gate
        if gate is not None and not gate.allowed(event.client_id):
            event.client.add_notification(
                "Refused", "This tab has no access token.", color="red", auto_close_seconds=6.0
            )
            return
        event.client.add_notification(
            "Read-only",
            "Another tab is editing this task; this one only shows it (one editor at a time). "
            "Close the other tab to edit here.",
            color="yellow",
            auto_close_seconds=6.0,
        )

    def _typing_of(self, handle: Any) -> Callable[[Any], None]:
        """The update callback of a text input: the editor's text is kept, another tab's undone."""

        def typed(event: Any) -> None:
            if not _user(event):
                return
            if self.app.may_edit(event.client_id):
                self._last[id(handle)] = handle.value
            else:
                self._refuse(event)

        return typed

    def _set(self, handle: Any, value: Any) -> None:
        """Set a widget's value from the server (viser's typing marks ``value`` read-only)."""
        handle.value = value
        self._last[id(handle)] = value

    # ---------------------------------------------------------------- callbacks
    def _object_chosen(self, event: Any) -> None:
        if not _user(event):
            return
        value = self.object.value
        self.app.attempt(self.app.select, None if value == NONE else value)

    def _step_chosen(self, event: Any) -> None:
        if _user(event) and self.step.value != "-":
            self.app.chosen_step = self._step_index()
            self._render_timeline()

    def _marker_clicked(self, event: Any) -> None:
        value = self.markers.value
        if value.isdigit():
            self.app.attempt(self.app.choose_step, int(value) - 1)

    def _chosen(self) -> int:
        """The step the timeline's Move acts on: the chosen one (the first if none)."""
        if not self.app.task.plan:
            raise ThirdhandError("the plan has no step to move")
        c = self.app.chosen_step
        return 0 if c is None else c

    def _submit_values(self) -> None:
        changed = {n: h.value for n, h in self.values.items() if h.value != self._shown.get(n)}
        if not changed:
            self.app.notify("no value changed")
            return
        self.app.set_values(changed)

    def _nudged(self, event: Any) -> None:
        name = self.nudge_what.value
        step = float(self.nudge.value)
        delta = step / 100.0 if name in ("x", "y", "z") else math.radians(step)
        self.app.attempt(self.app.nudge, name, delta)

    def _label_pair_chosen(self, event: Any) -> None:
        value = self.label_pair.value
        if _user(event) and " - " in value:
            a, b = value.split(" - ", 1)
            self.app.attempt(self.app.choose_label_pair, (a, b))

    def _fill_labelling(self) -> None:
        app = self.app
        if self.label_band is None:
            return
        s = app.labelling
        if s is None or app.label_pair is None:
            self.label_band.content = ""
            self.phase_question.content = ""
            self.phase_yes.visible = self.phase_no.visible = False
            return
        options = tuple(f"{a} - {b}" for a, b in s.pairs)
        if tuple(self.label_pair.options) != options:
            self.label_pair.options = options
        self._set(self.label_pair, f"{app.label_pair[0]} - {app.label_pair[1]}")
        self._last[id(self.label_pair)] = self.label_pair.value
        tl = app.motion.timelines[app.motion.demo_index]
        q = s.question
        shown = q if q is not None and (q.a, q.b) == app.label_pair else None
        self.label_band.content = band_html(
            s.probability[app.label_pair],
            s.edges,
            s.labelled[app.label_pair],
            span=(tl.start, tl.end),
            question=(shown.start, shown.end) if shown is not None else None,
            mark=app.label_from,
        )
        left = len(s.questions) - s.index
        text = q.text() if q is not None else "every uncertain interval answered"
        self.phase_question.content = (
            f'<div id="th-phase-q" style="padding:0 0.75em;font-size:0.85em">'
            f"{html.escape(text)}<br>{max(left, 0)} question(s) left</div>"
        )
        self.phase_yes.visible = self.phase_no.visible = q is not None

    def _submit_key_point(self) -> None:
        changed = {
            n: h.value for n, h in self.key_values.items() if h.value != self._shown.get(f"key {n}")
        }
        if not changed:
            self.app.notify("no key point value changed")
            return
        self.app.move_key_point(changed)

    def _submit_range(self) -> None:
        c = self.app.constraint
        if c is None:
            raise ThirdhandError("select an object with a constraint first")
        dof = self.dof.value
        unit = "cm" if dof.startswith("t") else "deg"  # a bare number, as shown
        lo, hi = (parse_number(h.value, unit=unit) for h in (self.dof_lo, self.dof_hi))
        self.app.apply(SetDofRange(c.id, dof, lo, hi), operation="range")

    def _submit_parent(self) -> None:
        child, parent = self.app.selected, self.new_parent.value
        if child is None or parent == NONE:
            raise ThirdhandError("select an object and its new parent first")
        self.app.apply(SetParent(child, parent), operation="parent")

    def _step_index(self) -> int:
        value = self.step.value
        try:
            return int(value.split(".", 1)[0]) - 1
        except ValueError:
            raise ThirdhandError("the plan has no step to choose") from None

    def _confirm_discard(self, what: str) -> None:
        app = self.app
        if not app.session.dirty:
            self._do(what)
            return
        assert app.server is not None
        with app.server.gui.add_modal("Unsaved changes") as modal:
            app.server.gui.add_markdown(
                f"The task has unsaved changes. {what.capitalize()} and lose them?"
            )
            go = app.server.gui.add_button(f"Discard and {what}", color="red")
            cancel = app.server.gui.add_button("Cancel")

        def discard(_: Any) -> None:
            modal.close()
            self._do(what, force=True)

        self._on(go.on_click, discard)
        self._on(cancel.on_click, lambda _: modal.close())

    def ask_overwrite(self, side: Any) -> None:
        """After a refused save: offer to overwrite the file changed on disk."""
        app = self.app
        assert app.server is not None
        with app.server.gui.add_modal("File changed on disk") as modal:
            app.server.gui.add_markdown(
                f"**{html.escape(app.task_path.name)}** changed on disk since it was loaded. "
                f"Your edits are kept in this session and in **{html.escape(side.name)}**."
            )
            overwrite = app.server.gui.add_button("Overwrite (keep theirs as .bak)", color="red")
            keep = app.server.gui.add_button("Keep both")

        def go(_: Any) -> None:
            modal.close()
            app.attempt(app.overwrite)

        self._on(overwrite.on_click, go)
        self._on(keep.on_click, lambda _: modal.close())

    def _do(self, what: str, *, force: bool = False) -> None:
        if what == "reload":
            self.app.attempt(self.app.reload, force=True)
        else:
            self.app.request_quit(force=True)
            self.app.notify("Quit: the server stops; close this tab")

    # ---------------------------------------------------------------- views
    def show_message(self, text: str, *, error: bool) -> None:
        """The status line's message."""
        self._message = (text, error)
        self._render_status()

    def _render_status(self) -> None:
        app = self.app
        text, error = getattr(self, "_message", (app.message, False))
        dirty = app.session.dirty
        colour = "#c92a2a" if error else "#495057"
        flag = (
            '<span id="th-dirty" style="color:#e8590c">● unsaved changes</span>'
            if dirty
            else '<span id="th-clean" style="color:#2b8a3e">saved</span>'
        )
        self.status.content = (
            f'<div style="padding:0 0.75em;font-size:0.85em"><b>{html.escape(app.task_path.name)}'
            f'</b> {flag}<br><span id="th-message" style="color:{colour}">'
            f"{html.escape(text)}</span></div>"
        )

    def show_animation(self, c: Constraint, dof: str | None) -> None:
        """Name the DOF being animated, and whether it is locked (None: animation over)."""
        if dof is not None and dofs_mod.classify_dof(*c.free_dofs[dof], dof) == "locked":
            dof = f"{dof} (locked: a small swing shows its axis)"
        self._render_selection(animating=dof)

    def show_playing(self, playing: bool) -> None:
        """The play button's label."""
        if self.time is not None:
            self.play.label = "Pause" if playing else "Play"

    def show_demo(self) -> None:
        """The slider's range and the legend of the current recording."""
        if self.time is None:
            return
        app = self.app
        tl = app.motion.timelines[app.motion.demo_index]
        self.time.min, self.time.max = round(tl.start, 2), round(tl.end, 2)
        self.legend.content = _legend_of(app)
        self.show_marks()

    def show_marks(self) -> None:
        """The plan's steps as marks on the time slider, labelled with their plan number.

        viser 1.1 takes marks only in ``add_slider(marks=...)``; its slider's
        ``_marks`` property (a client-synced prop like ``min``) updates them.
        """
        if self.time is None:
            return
        marks = tuple(GuiSliderMark(value=t, label=label) for t, label in keyframe_marks(self.app))
        self.time._marks = marks or None

    def show_time(self, t: float) -> None:
        """Move the time slider (no callback: the event has no client)."""
        if self.time is not None:
            self._set(self.time, round(t, 2))

    def _render_selection(self, animating: str | None = None) -> None:
        app = self.app
        sel, par = app.selected, app.parent
        parts = []
        if sel is not None:
            parts.append(
                f'<span id="th-selected" style="color:{hex_colour(SELECTED_RGB)};'
                f'font-weight:bold">{html.escape(sel)}</span>'
            )
            if par is not None:
                parts.append(
                    f' on <span id="th-parent" style="color:{hex_colour(PARENT_RGB)};'
                    f'font-weight:bold">{html.escape(par)}</span>'
                )
            else:
                parts.append(" (no parent)")
        else:
            parts.append("nothing selected")
        if animating is not None:
            parts.append(f'<br><span id="th-animating">animating {animating}</span>')
        self.selection.content = f'<div style="padding:0 0.75em">{"".join(parts)}</div>'

    def refresh(self) -> None:
        """Fill every widget from the app's state."""
        app = self.app
        self._render_status()
        self._render_selection(app.motion.animating)
        self.undo.disabled = not app.session.history.can_undo
        self.redo.disabled = not app.session.history.can_redo
        self._set(self.object, app.selected if app.selected is not None else NONE)
        c = app.constraint
        self.info.content = _constraint_html(c)
        vals = pose_values(c) if c is not None else {}
        for n, h in self.values.items():
            text = fmt_value(n, vals[n]) if n in vals else ""
            self._shown[n] = text
            self._set(h, text)
            h.disabled = c is None
        self._fill_range()
        self._fill_motion()
        self._fill_labelling()
        self._set(self.new_parent, app.parent if app.parent is not None else NONE)
        labels = [step_label(i, s) for i, s in enumerate(app.task.plan)] or ["-"]
        self.step.options = labels
        if app.step is not None:
            current = app.step
        elif app.chosen_step is not None:
            current = app.chosen_step
        else:
            current = _index_of(self.step.value, labels)
        self._set(self.step, labels[min(max(current, 0), len(labels) - 1)])
        self.plan.content = _plan_html(app.task.plan, app.step)
        positions = tuple(_positions(len(app.task.plan)))
        if tuple(self.markers.options) != positions:
            self.markers.options = positions
            self.move_to.options = positions
        self._render_timeline()
        self.show_marks()
        q = app.question
        why = app.focus.reason if q is not None and q.focused and app.focus is not None else ""
        self.question.content = _question_html(q.text if q is not None else None, why)
        self.yes.visible = self.no.visible = q is not None
        self.effort.content = _effort_html(app.session.effort)

    def _render_timeline(self) -> None:
        app = self.app
        chosen = app.chosen_step if app.chosen_step is not None else 0
        self.timeline.content = timeline_html(app.task, chosen, app.step)

    def _fill_motion(self) -> None:
        app = self.app
        path = app.motion_path() if app.constraint is not None else None
        self.motion_info.content = _motion_html(app, path)
        point = path.key_points[app.key_point] if path is not None else None
        for k, (n, h) in enumerate(self.key_values.items()):
            text = fmt_value(n, float(point[k])) if point is not None else ""
            self._shown[f"key {n}"] = text
            self._set(h, text)
            h.disabled = path is None
        self._set(self.key_point, str(app.key_point + 1))
        self.move_key.disabled = path is None

    def _fill_range(self) -> None:
        c = self.app.constraint
        dof = self.dof.value
        if c is None:
            self._set(self.dof_lo, "")
            self._set(self.dof_hi, "")
            return
        lo, hi = c.free_dofs[dof]
        self._set(self.dof_lo, fmt_value(dof, lo))
        self._set(self.dof_hi, fmt_value(dof, hi))


def demo_labels(app: ReviewApp) -> list[str]:
    """One label per recording: ``"1: chair (64.2 s)"``."""
    out = []
    for i, tl in enumerate(app.motion.timelines):
        name = tl.demo.meta.get("name") or tl.demo.meta.get("scene") or "recording"
        out.append(f"{i + 1}: {name} ({tl.end - tl.start:.1f} s)")
    return out


def _index_of(value: str, labels: list[str]) -> int:
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


def _legend_of(app: ReviewApp) -> str:
    """The legend of the recording played back; for an execution, its outcome too; for a
    live run's record, the steps it recognised."""
    tl = app.motion.timelines[app.motion.demo_index]
    legend = _legend(app.motion.contacts[app.motion.demo_index].source) + live_steps_html(
        tl.demo.meta
    )
    replay = app.replay_shown()
    if replay is None:
        return legend
    return legend + (
        f'<div id="th-replay" style="padding:0 0.75em;font-size:0.85em">'
        f"{html.escape(replay.summary())}</div>"
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


def _constraint_html(c: Constraint | None) -> str:
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
        f"pose: {pose}<table>{''.join(rows)}</table>{_runner_up_html(c)}</div>"
    )


def _runner_up_html(c: Constraint) -> str:
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


def _motion_html(app: ReviewApp, path: Any) -> str:
    """The selected part's learned motion: its key points (parent frame, cm) and edits."""
    pad = 'style="padding:0 0.75em;font-size:0.85em"'
    c = app.constraint
    if c is None:
        return f'<div id="th-motion" {pad}>select a part to see its learned motion</div>'
    if path is None:
        return f'<div id="th-motion" {pad}>{html.escape(c.child)}: no learned motion</div>'
    assert app.task.stages.primitives is not None  # the path came from it
    entry = app.task.stages.primitives.constraints[path.key]
    rows = []
    for i, (t, p) in enumerate(zip(path.key_times, path.key_points, strict=True)):
        where = ", ".join(f"{100.0 * v:.1f}" for v in p)
        mark = " ◀" if i == app.key_point else ""
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


def _question_html(text: str | None, why: str) -> str:
    """The question asked (empty when none), under why it comes first (a focus, or empty)."""
    if text is None:
        return ""
    pad = "padding:0 0.75em"
    reason = f'<div id="th-focus" style="{pad};color:#1971c2">{html.escape(why)}</div>'
    return (
        reason if why else ""
    ) + f'<div id="th-question" style="{pad}">{html.escape(text)}</div>'


def _plan_html(plan: list[Any], shown: int | None) -> str:
    items = []
    for i, s in enumerate(plan):
        label = html.escape(step_label(i, s))
        items.append(f"<li><b>{label}</b></li>" if i == shown else f"<li>{label}</li>")
    return (
        f'<ul id="th-plan" style="font-size:0.85em;margin:0;padding-left:1em;list-style:none">'
        f"{''.join(items)}</ul>"
    )


def keyframe_marks(app: ReviewApp) -> list[tuple[float, str]]:
    """Where the plan's steps are on the time axis of what is played back.

    A recording of the person: each step's keyframe time; an execution replay:
    when the run began the step. Labelled with the step's number in the current
    plan order; steps off the recording's time span are left out.

    Returns
    -------
    list of (float, str)
        Seconds (rounded to 0.01, as the slider), label; in time order.
    """
    if not app.motion.timelines:
        return []
    tl = app.motion.timelines[app.motion.demo_index]
    replay = app.replay_shown()
    starts = replay.step_starts() if replay is not None else {}
    out = []
    for i, s in enumerate(app.task.plan):
        t = starts.get(s.constraint or "") if replay is not None else s.time
        if t is not None and tl.start <= t <= tl.end:
            out.append((round(float(t), 2), str(i + 1)))
    return sorted(out)


def _positions(n: int) -> list[str]:
    return [str(i + 1) for i in range(n)] or ["-"]


def timeline_html(task: Any, chosen: int | None, shown: int | None) -> str:
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


def _effort_html(effort: Any) -> str:
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
