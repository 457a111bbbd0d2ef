"""The review GUI's control panel: viser widgets wired to a :class:`PanelHost` (the app).

Every callback builds its request with the pure functions of
:mod:`~thirdhand.review.corrections` and :mod:`~thirdhand.review.view` and calls
one host action; a refused action shows its one-line message (status line +
notification) and changes nothing. The panel is filled from a :class:`PanelState`
snapshot (:meth:`Panels.refresh`) with the HTML of :mod:`~thirdhand.review.panel_html`.
A widget updated by the server (a new selection fills the editors) fires its own
callback with no client: those events are ignored, so only a person's input
becomes an edit.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Protocol

import viser
from viser._messages import GuiSliderMark

from thirdhand.errors import ThirdhandError
from thirdhand.review.corrections import (
    NONE,
    changed_texts,
    key_point_edit,
    nudge_delta,
    nudge_edit,
    parent_edit,
    range_edit,
    step_index,
    value_edits,
)
from thirdhand.review.dialogs import (
    Dialog,
    Discard,
    discard_dialog,
    overwrite_dialog,
    refusal_notice,
)
from thirdhand.review.edits import Edit, pose_values
from thirdhand.review.effort import EffortLog
from thirdhand.review.motion import Motion
from thirdhand.review.panel_html import (
    VALUE_NAMES,
    animation_label,
    band_html,
    constraint_html,
    demo_labels,
    effort_html,
    fmt_value,
    index_of,
    keyframe_marks,
    legend_html,
    live_steps_html,
    motion_html,
    phase_question_html,
    plan_html,
    question_html,
    selection_html,
    status_html,
    step_label,
    step_positions,
    timeline_html,
)
from thirdhand.review.phase_labels import PhaseLabelling
from thirdhand.review.playback import Timeline
from thirdhand.review.primitive_edit import KEY_FRACTIONS
from thirdhand.review.questioning import Clarifier, Labeller
from thirdhand.review.rounds import ClarificationRound, LabelCursor
from thirdhand.review.session import ReviewSession
from thirdhand.review.shortcuts import shortcuts_html
from thirdhand.review.tabs import EditorTabs, tell
from thirdhand.review.task_scene import TaskScene
from thirdhand.review.view import (
    ReviewView,
    motion_path,
    moving_step,
    require_constraint,
    require_motion_path,
    selected_constraint,
    selected_parent,
    step_target,
)
from thirdhand.task.constraint import Constraint
from thirdhand.task.geometry import DOF_NAMES
from thirdhand.taskfile import TaskFile

#: Rough-adjustment steps: cm for x y z, degrees for roll pitch yaw.
NUDGE_STEPS = ("-5", "-1", "+1", "+5")


def _user(event: Any) -> bool:
    """True for an event a person caused (the server's own updates carry no client)."""
    return getattr(event, "client", None) is not None


@dataclass(frozen=True)
class PanelState:
    """Everything the panel shows, as one snapshot of the app.

    Attributes
    ----------
    task : TaskFile
    view : ReviewView
    dirty, can_undo, can_redo : bool
        Unsaved changes; whether an edit can be undone, redone.
    effort : EffortLog
    animating : str or None
        The DOF being animated.
    clarification : ClarificationRound
    labelling : PhaseLabelling or None
    cursor : LabelCursor
    demo_index : int
        The recording played back.
    timeline : Timeline or None
        Its timeline (None: no recording loaded).
    contact_source : str
        Who holds what in it: ``"labels"``, ``"segmentation"``, ``"execution"``...
    replay_summary : str or None
        An execution replay's outcome (None: a recording of the person).
    replay_starts : mapping or None
        An execution replay's step start times (constraint id -> s).
    """

    task: TaskFile
    view: ReviewView
    dirty: bool
    can_undo: bool
    can_redo: bool
    effort: EffortLog
    animating: str | None
    clarification: ClarificationRound
    labelling: PhaseLabelling | None
    cursor: LabelCursor
    demo_index: int
    timeline: Timeline | None
    contact_source: str
    replay_summary: str | None
    replay_starts: dict[str, float] | None

    @property
    def legend(self) -> str:
        """The legend of the recording played back (empty without one)."""
        if self.timeline is None:
            return ""
        return legend_html(self.contact_source, self.timeline.demo.meta, self.replay_summary)

    @property
    def marks(self) -> list[tuple[float, str]]:
        """The plan's steps on the time slider (:func:`panel_html.keyframe_marks`)."""
        if self.timeline is None:
            return []
        return keyframe_marks(self.task, self.timeline, self.replay_starts)


@dataclass(frozen=True)
class PanelSetup:
    """What the panel is built from: the task's file name, the objects drawn, the
    recordings' timelines, whether one is of the person (phases can be labelled),
    the first message and the first state."""

    task_name: str
    names: tuple[str, ...]
    timelines: tuple[Timeline, ...]
    has_person_demos: bool
    message: str
    state: PanelState


class PanelHost(Protocol):
    """What the panel asks of the app: its state, the actions the widgets call, and the
    parts (tabs, scene, playback, question rounds) the widgets drive directly."""

    lock: threading.RLock
    view: ReviewView
    session: ReviewSession
    tabs: EditorTabs
    scene: TaskScene | None
    motion: Motion
    clarifier: Clarifier
    labeller: Labeller

    @property
    def task(self) -> TaskFile: ...

    def attempt(self, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> None: ...

    def attempt_long(self, fn: Callable[..., Any], *args: Any) -> None: ...

    def notify(self, text: str, *, error: bool = False) -> None: ...

    def apply(self, edit: Edit, *, operation: str | None = None) -> None: ...

    def select(self, name: str | None, *, operation: str | None = "click") -> None: ...

    def undo(self) -> None: ...

    def redo(self) -> None: ...

    def save(self, *, force: bool = False) -> Path | None: ...

    def reload(self, *, force: bool = False) -> bool: ...

    def request_quit(self, *, force: bool = False) -> bool: ...

    def animate_dofs(
        self, constraint_id: str | None = None, dofs: Iterable[str] = DOF_NAMES
    ) -> None: ...

    def set_gizmo_edits(self, edits: bool) -> None: ...

    def choose_key_point(self, index: int) -> None: ...

    def show_step(self, index: int | None) -> None: ...

    def choose_step(self, index: int) -> None: ...

    def move_step_to(self, index: int, new_index: int) -> None: ...

    def show_task(self) -> None: ...


class Panels:
    """The control panel in ``gui``, built from ``setup``, acting through ``host``.

    Attributes
    ----------
    state : PanelState
        The snapshot shown last.
    """

    def __init__(self, gui: viser.GuiApi, setup: PanelSetup, host: PanelHost) -> None:
        self.host = host
        self.gui = gui
        self.setup = setup
        self.state = setup.state
        self.message = (setup.message, False)
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
        self._on(self.undo.on_click, lambda e: host.attempt(host.undo))
        self._on(self.redo.on_click, lambda e: host.attempt(host.redo))
        self._on(self.save.on_click, lambda e: host.attempt(host.save))
        self._on(self.reload.on_click, lambda e: self._discard("reload"))
        self._on(self.quit.on_click, lambda e: self._discard("quit"))

        names = list(setup.names)
        with gui.add_folder("Object"):
            self.object = gui.add_dropdown("Object", [NONE, *names], initial_value=NONE)
            self.selection = gui.add_html("")
            self.info = gui.add_html("")
            self.animate = gui.add_button("Animate DOFs")
            self.frame = gui.add_button("Frame selection")
        self._on(
            self.object.on_update,
            lambda e: (
                host.attempt(host.select, None if self.object.value == NONE else self.object.value)
                if _user(e)
                else None
            ),
        )
        self._on(self.animate.on_click, lambda e: host.attempt(host.animate_dofs))
        # Framing only moves the asking tab's camera: a read-only tab may frame too.
        self.frame.on_click(lambda e: host.attempt(self._frame, e.client) if _user(e) else None)

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
        self._on(self.apply_values.on_click, lambda e: host.attempt(self._submit_values))
        self._on(self.nudge.on_click, lambda e: host.attempt(self._nudged))
        self._on(self.dof.on_update, lambda e: self._fill_range(self.state))
        self._on(
            self.set_range.on_click,
            lambda e: host.attempt(
                lambda: host.apply(
                    range_edit(
                        require_constraint(host.task, host.view),
                        self.dof.value,
                        self.dof_lo.value,
                        self.dof_hi.value,
                    ),
                    operation="range",
                )
            ),
        )
        self._on(
            self.set_parent.on_click,
            lambda e: host.attempt(
                lambda: host.apply(
                    parent_edit(host.view.selected, self.new_parent.value), operation="parent"
                )
            ),
        )
        self._on(
            self.gizmo_edits.on_update,
            lambda e: (
                host.attempt(host.set_gizmo_edits, self.gizmo_edits.value) if _user(e) else None
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
                host.attempt(host.choose_key_point, int(self.key_point.value) - 1)
                if _user(e)
                else None
            ),
        )
        self._on(self.move_key.on_click, lambda e: host.attempt(self._submit_key_point))

        with gui.add_folder("Keyframes"):
            self.plan = gui.add_html("")
            self.step = gui.add_dropdown("Step", ["-"], initial_value="-")
            self.up = gui.add_button("Up")
            self.down = gui.add_button("Down")
            self.show_kf = gui.add_button("Show keyframe")
            self.show_all = gui.add_button("Show assembled")
        self._on(self.step.on_update, self._step_chosen)
        self._on(self.up.on_click, lambda e: host.attempt(self._move_listed, -1))
        self._on(self.down.on_click, lambda e: host.attempt(self._move_listed, 1))
        self._on(
            self.show_kf.on_click,
            lambda e: host.attempt(lambda: host.show_step(step_index(self.step.value))),
        )
        self._on(self.show_all.on_click, lambda e: host.attempt(host.show_step, None))

        with gui.add_folder("Plan timeline"):
            # viser has no drag-and-drop: a marker button chooses (and shows) a step,
            # "Move to" + "Move step" reorder it; the partial order decides what may move.
            self.timeline = gui.add_html("")
            positions = step_positions(len(setup.state.task.plan))
            self.markers = gui.add_button_group("Go to step", positions)
            self.move_to = gui.add_dropdown("Move to", positions, initial_value=positions[0])
            self.move = gui.add_button("Move step")
        self._on(
            self.markers.on_click,
            lambda e: (
                host.attempt(host.choose_step, int(self.markers.value) - 1)
                if self.markers.value.isdigit()
                else None
            ),
        )
        self._on(
            self.move.on_click,
            lambda e: host.attempt(
                lambda: host.move_step_to(
                    moving_step(host.task, host.view), int(self.move_to.value) - 1
                )
            ),
        )

        with gui.add_folder("Clarify"):
            self.start_q = gui.add_button("Start clarification")
            self.question = gui.add_html("")
            self.yes = gui.add_button("Yes, right", visible=False, color="green")
            self.no = gui.add_button("No, wrong", visible=False, color="red")
        self._on(self.start_q.on_click, lambda e: host.attempt(host.clarifier.start))
        self._on(self.yes.on_click, lambda e: host.attempt(host.clarifier.answer, True))
        self._on(self.no.on_click, lambda e: host.attempt(host.clarifier.answer, False))

        self.time: viser.GuiSliderHandle[float] | None = None
        if setup.timelines:
            self._add_playback(gui, setup)

        self.label_band: viser.GuiHtmlHandle | None = None
        if setup.has_person_demos:
            self._add_labelling(gui)

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

    def _add_playback(self, gui: viser.GuiApi, setup: PanelSetup) -> None:
        host, state = self.host, setup.state
        motion = host.motion
        labels = demo_labels(setup.timelines)
        tl = setup.timelines[state.demo_index]
        with gui.add_folder("Playback"):
            self.demo = gui.add_dropdown(
                "Recording",
                labels,
                initial_value=labels[state.demo_index],
                visible=len(setup.timelines) > 1,
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
            self.legend = gui.add_html(state.legend)
        slider = self.time
        assert slider is not None
        self._on(
            slider.on_update,
            lambda e: host.attempt(motion.set_time, slider.value) if _user(e) else None,
        )
        self._on(
            self.play.on_click,
            lambda e: host.attempt(motion.play, not motion.playing, speed=float(self.speed.value)),
        )
        self._on(self.back.on_click, lambda e: host.attempt(host.show_task))
        self._on(
            self.demo.on_update,
            lambda e: (
                host.attempt(motion.set_demo, labels.index(self.demo.value)) if _user(e) else None
            ),
        )

    def _add_labelling(self, gui: viser.GuiApi) -> None:
        labeller, host = self.host.labeller, self.host
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
        self._on(self.start_labels.on_click, lambda e: host.attempt_long(labeller.start))
        self._on(self.phase_yes.on_click, lambda e: host.attempt(labeller.answer, True))
        self._on(self.phase_no.on_click, lambda e: host.attempt(labeller.answer, False))
        self._on(self.mark_from.on_click, lambda e: host.attempt(labeller.mark_from_here))
        self._on(
            self.mark_to.on_click,
            lambda e: host.attempt(labeller.mark_to_here, self.mark_to.value == "interacting"),
        )
        self._on(self.save_labels.on_click, lambda e: host.attempt(labeller.save))

        def pair_chosen(event: Any) -> None:
            value = self.label_pair.value
            if _user(event) and " - " in value:
                a, b = value.split(" - ", 1)
                host.attempt(labeller.choose_pair, (a, b))

        self._on(self.label_pair.on_update, pair_chosen)

    # ---------------------------------------------------------------- one editor
    def _on(self, register: Any, fn: Callable[[Any], Any]) -> None:
        """Register ``fn`` for a widget event, refused (and undone) from a read-only tab."""

        def gated(event: Any) -> Any:
            if _user(event) and not self.host.tabs.may_edit(event.client_id):
                self._refuse(event)
                return None
            return fn(event)

        register(gated)

    def _refuse(self, event: Any) -> None:
        """Tell a read-only tab why nothing happened; undo its change of an input."""
        target = getattr(event, "target", None)
        if target is not None and id(target) in self._last:
            target.value = self._last[id(target)]
        tell(event.client, refusal_notice(has_token=self.host.tabs.admits(event.client_id)))

    def _typing_of(self, handle: Any) -> Callable[[Any], None]:
        """The update callback of a text input: the editor's text is kept, another tab's undone."""

        def typed(event: Any) -> None:
            if not _user(event):
                return
            if self.host.tabs.may_edit(event.client_id):
                self._last[id(handle)] = handle.value
            else:
                self._refuse(event)

        return typed

    def _set(self, handle: Any, value: Any) -> None:
        """Set a widget's value from the server (viser's typing marks ``value`` read-only)."""
        handle.value = value
        self._last[id(handle)] = value

    # ---------------------------------------------------------------- callbacks
    def _frame(self, client: viser.ClientHandle) -> None:
        host = self.host
        selected = host.view.selected
        if selected is None or host.scene is None:
            raise ThirdhandError("select a part to frame first")
        host.scene.frame(client, selected)

    def _step_chosen(self, event: Any) -> None:
        if _user(event) and self.step.value != "-":
            host = self.host
            with host.lock:
                host.view = replace(host.view, chosen_step=step_index(self.step.value))
                self.state = replace(self.state, view=host.view)
            self._render_timeline(self.state)

    def _move_listed(self, delta: int) -> None:
        """Move the step chosen in the Step list up (``delta`` -1) or down (+1)."""
        index = step_index(self.step.value)
        self.host.move_step_to(index, step_target(self.host.task, index, delta))

    def _submit_values(self) -> None:
        host = self.host
        texts = {n: h.value for n, h in self.values.items()}
        changed = changed_texts(texts, self._shown)
        if not changed:
            host.notify("no value changed")
            return
        for edit, operation in value_edits(require_constraint(host.task, host.view), changed):
            host.apply(edit, operation=operation)

    def _nudged(self) -> None:
        host = self.host
        name = self.nudge_what.value
        c = require_constraint(host.task, host.view)
        edit, operation = nudge_edit(c, name, nudge_delta(name, self.nudge.value))
        host.apply(edit, operation=operation)

    def _submit_key_point(self) -> None:
        host = self.host
        texts = {n: h.value for n, h in self.key_values.items()}
        shown = {n: self._shown[f"key {n}"] for n in "xyz" if f"key {n}" in self._shown}
        changed = changed_texts(texts, shown)
        if not changed:
            host.notify("no key point value changed")
            return
        path = require_motion_path(host.task, host.view)
        host.apply(key_point_edit(path, host.view.key_point, changed), operation="primitive")

    # ---------------------------------------------------------------- dialogs
    def _discard(self, what: Discard) -> None:
        """Reload or quit; with unsaved changes only after the person confirms."""
        if not self.host.session.dirty:
            self._do(what)
            return
        self._ask(discard_dialog(what), lambda: self._do(what))

    def ask_overwrite(self, task_name: str, kept_name: str) -> None:
        """After a refused save: offer to overwrite the file changed on disk."""
        host = self.host
        self._ask(
            overwrite_dialog(task_name, kept_name), lambda: host.attempt(host.save, force=True)
        )

    def _ask(self, dialog: Dialog, confirmed: Callable[[], None]) -> None:
        """Show ``dialog`` as a modal; its red button runs ``confirmed``."""
        gui = self.gui
        with gui.add_modal(dialog.title) as modal:
            gui.add_markdown(dialog.markdown)
            go = gui.add_button(dialog.confirm, color="red")
            cancel = gui.add_button(dialog.cancel)

        def confirm(_: Any) -> None:
            modal.close()
            confirmed()

        self._on(go.on_click, confirm)
        self._on(cancel.on_click, lambda _: modal.close())

    def _do(self, what: Discard) -> None:
        host = self.host
        if what == "reload":
            host.attempt(host.reload, force=True)
        else:
            host.request_quit(force=True)
            host.notify("Quit: the server stops; close this tab")

    # ---------------------------------------------------------------- views
    def show_message(self, text: str, *, error: bool) -> None:
        """The status line's message."""
        self.message = (text, error)
        self._render_status(self.state)

    def _render_status(self, state: PanelState) -> None:
        text, error = self.message
        self.status.content = status_html(
            self.setup.task_name, text, error=error, dirty=state.dirty
        )

    def show_animation(self, c: Constraint, dof: str | None) -> None:
        """Name the DOF being animated, and whether it is locked (None: animation over)."""
        self._render_selection(self.state, animation_label(c, dof))

    def show_playing(self, playing: bool) -> None:
        """The play button's label."""
        if self.time is not None:
            self.play.label = "Pause" if playing else "Play"

    def show_demo(self, state: PanelState) -> None:
        """The slider's range and the legend of the current recording."""
        self.state = state
        if self.time is None or state.timeline is None:
            return
        tl = state.timeline
        self.time.min, self.time.max = round(tl.start, 2), round(tl.end, 2)
        self.legend.content = state.legend
        self._show_marks(state)

    def _show_marks(self, state: PanelState) -> None:
        """The plan's steps as marks on the time slider, labelled with their plan number.

        viser 1.1 takes marks only in ``add_slider(marks=...)``; its slider's
        ``_marks`` property (a client-synced prop like ``min``) updates them.
        """
        if self.time is None:
            return
        marks = tuple(GuiSliderMark(value=t, label=label) for t, label in state.marks)
        self.time._marks = marks or None

    def show_time(self, t: float) -> None:
        """Move the time slider (no callback: the event has no client)."""
        if self.time is not None:
            self._set(self.time, round(t, 2))

    def _render_selection(self, state: PanelState, animating: str | None) -> None:
        view = state.view
        parent = selected_parent(state.task, view)
        self.selection.content = selection_html(view.selected, parent, animating)

    def refresh(self, state: PanelState) -> None:
        """Fill every widget from ``state``."""
        self.state = state
        task, view = state.task, state.view
        self._render_status(state)
        self._render_selection(state, state.animating)
        self.undo.disabled = not state.can_undo
        self.redo.disabled = not state.can_redo
        self._set(self.object, view.selected if view.selected is not None else NONE)
        c = selected_constraint(task, view)
        self.info.content = constraint_html(c)
        vals = pose_values(c) if c is not None else {}
        for n, h in self.values.items():
            text = fmt_value(n, vals[n]) if n in vals else ""
            self._shown[n] = text
            self._set(h, text)
            h.disabled = c is None
        self._fill_range(state)
        self._fill_motion(state)
        self._fill_labelling(state)
        parent = selected_parent(task, view)
        self._set(self.new_parent, parent if parent is not None else NONE)
        labels = [step_label(i, s) for i, s in enumerate(task.plan)] or ["-"]
        self.step.options = labels
        if view.step is not None:
            current = view.step
        elif view.chosen_step is not None:
            current = view.chosen_step
        else:
            current = index_of(self.step.value, labels)
        self._set(self.step, labels[min(max(current, 0), len(labels) - 1)])
        self.plan.content = plan_html(task.plan, view.step)
        positions = tuple(step_positions(len(task.plan)))
        if tuple(self.markers.options) != positions:
            self.markers.options = positions
            self.move_to.options = positions
        self._render_timeline(state)
        self._show_marks(state)
        round_ = state.clarification
        q = round_.question
        self.question.content = question_html(
            q.text if q is not None else None, round_.focus_reason
        )
        self.yes.visible = self.no.visible = q is not None
        self.effort.content = effort_html(state.effort)

    def _render_timeline(self, state: PanelState) -> None:
        view = state.view
        chosen = view.chosen_step if view.chosen_step is not None else 0
        self.timeline.content = timeline_html(state.task, chosen, view.step)

    def _fill_motion(self, state: PanelState) -> None:
        task, view = state.task, state.view
        c = selected_constraint(task, view)
        path = motion_path(task, view) if c is not None else None
        self.motion_info.content = motion_html(task, c, path, view.key_point)
        point = path.key_points[view.key_point] if path is not None else None
        for k, (n, h) in enumerate(self.key_values.items()):
            text = fmt_value(n, float(point[k])) if point is not None else ""
            self._shown[f"key {n}"] = text
            self._set(h, text)
            h.disabled = path is None
        self._set(self.key_point, str(view.key_point + 1))
        self.move_key.disabled = path is None

    def _fill_range(self, state: PanelState) -> None:
        c = selected_constraint(state.task, state.view)
        dof = self.dof.value
        if c is None:
            self._set(self.dof_lo, "")
            self._set(self.dof_hi, "")
            return
        lo, hi = c.free_dofs[dof]
        self._set(self.dof_lo, fmt_value(dof, lo))
        self._set(self.dof_hi, fmt_value(dof, hi))

    def _fill_labelling(self, state: PanelState) -> None:
        if self.label_band is None:
            return
        s, pair = state.labelling, state.cursor.pair
        if s is None or pair is None or state.timeline is None:
            self.label_band.content = ""
            self.phase_question.content = ""
            self.phase_yes.visible = self.phase_no.visible = False
            return
        options = tuple(f"{a} - {b}" for a, b in s.pairs)
        if tuple(self.label_pair.options) != options:
            self.label_pair.options = options
        self._set(self.label_pair, f"{pair[0]} - {pair[1]}")
        tl = state.timeline
        q = s.question
        shown = q if q is not None and (q.a, q.b) == pair else None
        self.label_band.content = band_html(
            s.probability[pair],
            s.edges,
            s.labelled[pair],
            span=(tl.start, tl.end),
            question=(shown.start, shown.end) if shown is not None else None,
            mark=state.cursor.mark_from,
        )
        text = q.text() if q is not None else "every uncertain interval answered"
        self.phase_question.content = phase_question_html(text, len(s.questions) - s.index)
        self.phase_yes.visible = self.phase_no.visible = q is not None


__all__ = ["NONE", "PanelHost", "PanelSetup", "PanelState", "Panels", "live_steps_html"]
