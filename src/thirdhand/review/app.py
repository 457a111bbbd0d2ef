"""The review GUI: a local viser web app to see, animate and correct a task file.

::

    app = ReviewApp("chair.task.json", demos=[demo], port=8080)
    url = app.start()          # serves http://127.0.0.1:8080 in a background thread
    ...
    app.stop()

The app is a thin shell over pure functions: what is shown is a
:class:`~thirdhand.review.view.ReviewView` changed by the functions of
:mod:`thirdhand.review.view`; every correction is an edit of
:mod:`thirdhand.review.edits` (built from the widgets' input by
:mod:`thirdhand.review.corrections`) applied through a
:class:`~thirdhand.review.session.ReviewSession` (undo/redo, effort log, save
with conflict check); the dialogs are :mod:`thirdhand.review.dialogs`. The app
keeps the server, the scene's handles (:class:`~thirdhand.review.task_scene.TaskScene`),
the tabs (:class:`~thirdhand.review.tabs.EditorTabs`), the playback
(:class:`~thirdhand.review.motion.Motion`) and the question rounds
(:mod:`thirdhand.review.questioning`); its methods (:meth:`select`,
:meth:`apply`, :meth:`show_step`, :meth:`save`...) are what the widgets of
:mod:`thirdhand.review.panels` call.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Iterable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import viser

from thirdhand.arrays import FloatArray
from thirdhand.demonstration import Demonstration
from thirdhand.errors import ThirdhandError
from thirdhand.review.access import AccessGate, is_loopback, new_token, shown_host, token_url
from thirdhand.review.corrections import dragged_key_point, gizmo_edit, gizmo_pose, reparent_edit
from thirdhand.review.dialogs import conflict_message, conflict_path, message_notice
from thirdhand.review.edits import Edit, MoveStep, describe_edit
from thirdhand.review.effort import ACTIONS
from thirdhand.review.gizmo import GizmoMove
from thirdhand.review.motion import Motion, MotionEvents
from thirdhand.review.panels import Panels, PanelSetup, PanelState
from thirdhand.review.questioning import Clarifier, Labeller
from thirdhand.review.session import ConflictError, ReviewSession
from thirdhand.review.tabs import EditorTabs, tell
from thirdhand.review.task_scene import TaskScene
from thirdhand.review.view import (
    ReviewView,
    after_reload,
    after_step_move,
    check_step_move,
    choose_key_point,
    choose_step,
    clamp_key_point,
    constraint_of,
    drop_unknown,
    motion_path,
    primitive_key,
    require_constraint,
    select,
    selected_constraint,
    show_step,
    shown_poses,
)
from thirdhand.task.geometry import DOF_NAMES
from thirdhand.taskfile import TaskFile, save_task

if TYPE_CHECKING:
    from thirdhand.review.replay import Replay

Vec3 = tuple[float, float, float]


class ReviewApp:
    """The review web app over one task file.

    Parameters
    ----------
    task_path : path-like
        The task file (``thirdhand.task/2``); saved in place, the previous version kept.
    demos : sequence of Demonstration or path-like
        Recordings to play back on the timeline.
    host : str
        Address to bind (default local only).
    port : int
        Port; 0 picks a free one. A busy port is replaced by the next free one.
    meshes : sequence of path-like
        Folders searched for part meshes (then ``THIRDHAND_MESH_PATH``).
    segment : bool
        Find hand contacts with the segmentation stage when a recording has no labels.
    light_rendering : bool
        No environment map and no shadows: for software WebGL (headless browsers,
        remote desktops), where they make every frame slow.
    replays : sequence of path-like
        Execution records (``thirdhand execute --record OUT``) of this task, played
        back after the recordings on the same scene (the first one shown first);
        a record of another task is refused (:func:`~thirdhand.review.replay.load_replay`).
    token : str, optional
        Access token (:mod:`thirdhand.review.access`): a client must present it to
        see the task or edit. Default: none on a loopback ``host``, a fresh random
        one beyond loopback. :attr:`url` carries it.

    Attributes
    ----------
    session : ReviewSession
    view : ReviewView
        What is shown: the selected object, the keyframe, the chosen step, the mode
        (``"task"`` or ``"playback"``), the key point.
    gate : AccessGate or None
        Who may connect (None: anyone who reaches a loopback address).
    tabs : EditorTabs
        The tabs and the one that edits.
    scene : TaskScene or None
        The 3D view's handles (after :meth:`start`).
    panels : Panels or None
        The control panel (after :meth:`start`).
    motion : Motion
        Animation and playback (its ``time``, ``playing``, ``animating``...).
    clarifier : Clarifier
        The clarification round (the object in focus, then least confident first).
    labeller : Labeller
        Phase labelling of the recording shown.
    message : str
        The last message shown to the user (errors start with ``"Error: "``).
    conflict : Path or None
        Where the edits went when a save was refused (the file changed on disk).
    """

    def __init__(
        self,
        task_path: str | os.PathLike[str],
        demos: Sequence[Demonstration | str | os.PathLike[str]] = (),
        host: str = "127.0.0.1",
        port: int = 8080,
        *,
        meshes: Sequence[str | os.PathLike[str]] = (),
        segment: bool = True,
        light_rendering: bool = False,
        replays: Sequence[str | os.PathLike[str]] = (),
        token: str | None = None,
    ) -> None:
        self.task_path = Path(task_path)
        if token is None and not is_loopback(host):
            token = new_token()
        self.gate = AccessGate(token) if token is not None else None
        self.host, self.requested_port = host, port
        self.meshes = [Path(m) for m in meshes]
        self.light_rendering = light_rendering
        self.session = ReviewSession.open(self.task_path)
        self.demos = [_load_demo(d) for d in demos]
        self.replays: list[Replay] = []
        if replays:
            from thirdhand.review.replay import load_replay

            self.replays = [load_replay(r, self.session.task, self.task_path) for r in replays]
        self.lock = threading.RLock()
        self.view = ReviewView()
        self.message = f"Loaded {self.task_path.name}"
        self.conflict: Path | None = None
        self.quit_requested = threading.Event()
        self.server: viser.ViserServer | None = None
        self.tabs = EditorTabs(self.gate, self.lock)
        self.scene: TaskScene | None = None
        self.panels: Panels | None = None
        self.clarifier = Clarifier(self)
        self.labeller = Labeller(self)
        self.motion = Motion(
            self.lock, [*self.demos, *(r.demo for r in self.replays)], segment=segment
        )
        if self.replays:  # the run first: it is what --replay asked to see
            self.motion.demo_index = len(self.demos)
            self.motion.time = self.motion.timelines[len(self.demos)].start
            self.message = "; ".join(r.summary() for r in self.replays)
        self.motion.events = MotionEvents(
            playback_entered=self._enter_playback, animation_ended=self.refresh
        )

    # ------------------------------------------------------------------ lifecycle
    @property
    def task(self) -> TaskFile:
        """The current task (the session history's current version)."""
        return self.session.task

    @property
    def port(self) -> int:
        """The port served (after :meth:`start`)."""
        return self.server.get_port() if self.server is not None else self.requested_port

    @property
    def url(self) -> str:
        """Address of the web app; beyond loopback it carries the access token."""
        return app_url(shown_host(self.host), self.port, self.gate)

    def start(self) -> str:
        """Start the server (background threads), build the scene and panels; return the URL."""
        server = viser.ViserServer(host=self.host, port=self.requested_port, verbose=False)
        self.server = server
        if self.gate is not None:
            self.gate.install(server)
        server.scene.set_up_direction("+z")
        if self.light_rendering:
            server.scene.configure_environment_map(None)
            server.scene.configure_default_lights(True, cast_shadow=False)
            server.scene.add_light_hemisphere(
                "/light", sky_color=(255, 255, 255), ground_color=(120, 120, 130), intensity=1.2
            )
        scene = TaskScene(
            server.scene,
            self.task,
            self.task_path,
            self.meshes,
            on_click=self._clicked,
            on_gizmo=self.gizmo_moved,
            on_key_point=self._key_point_dragged,
        )
        self.scene = scene
        self.motion.attach(server.scene, scene.parts)
        setup = PanelSetup(
            task_name=self.task_path.name,
            names=tuple(scene.parts.names),
            timelines=tuple(self.motion.timelines),
            has_person_demos=bool(self.demos),
            message=self.message,
            state=self._panel_state(),
        )
        self.panels = panels = Panels(server.gui, setup, self)
        self.motion.events = MotionEvents(
            playback_entered=self._enter_playback,
            time_shown=panels.show_time,
            playing_changed=panels.show_playing,
            demo_changed=lambda: panels.show_demo(self._panel_state()),
            animating=panels.show_animation,
            animation_ended=self.refresh,
        )
        server.on_client_connect(
            lambda c: self.tabs.connected(
                c, lambda: camera_pose(self.scene, replay_at(self.replays, self.demos, self.motion))
            )
        )
        server.on_client_disconnect(lambda c: self.tabs.disconnected(c, server))
        with self.lock:
            self.refresh()
            said = [r.summary() for r in self.replays]
            if scene.parts.missing_meshes:
                listed = ", ".join(f"{m} ({n})" for n, m in scene.parts.missing_meshes.items())
                said.append(
                    f"mesh files the task records not found, drawn as boxes: {listed} "
                    f"(looked beside {self.task_path.name}, in --meshes folders and along "
                    "THIRDHAND_MESH_PATH)"
                )
            if said:
                self.say("; ".join(said))
        return self.url

    def stop(self) -> None:
        """Stop animations, playback and the server."""
        self.motion.halt()
        self.motion.attach(None, None)
        if self.server is not None:
            self.server.stop()
            self.server = None

    # ------------------------------------------------------------------ messages
    def notify(self, text: str, *, error: bool = False) -> None:
        """Show ``text`` in the status line and as a notification in every browser."""
        self.message = f"Error: {text}" if error else text
        if self.panels is not None:
            self.panels.show_message(self.message, error=error)
        if self.server is not None:
            for client in self.server.get_clients().values():
                tell(client, message_notice(text, error=error))

    def say(self, text: str) -> None:
        """Show ``text`` in the status line (replacing an earlier error), no notification."""
        self.message = text
        if self.panels is not None:
            self.panels.show_message(text, error=False)

    def attempt(self, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> None:
        """Run an action for a widget: a refused one shows its message and changes nothing."""
        try:
            with self.lock:
                fn(*args, **kwargs)
        except ThirdhandError as exc:
            self.notify(str(exc), error=True)

    def attempt_long(self, fn: Callable[..., Any], *args: Any) -> None:
        """:meth:`attempt` for a long action that takes the app's lock only around its
        quick parts (:meth:`Labeller.start`), so other tabs and panels are not blocked."""
        try:
            fn(*args)
        except ThirdhandError as exc:
            self.notify(str(exc), error=True)

    # ------------------------------------------------------------------ actions
    def select(self, name: str | None, *, operation: str | None = "click") -> None:
        """Select an object: it turns orange, its parent blue; its values fill the editors."""
        with self.lock:
            self.motion.halt()
            if self.scene is not None:
                self.view = select(self.view, name, self.scene.parts.frames)
            else:
                self.view = replace(self.view, selected=name, mode="task")
            if name is not None and operation is not None:
                self.session.effort.record(operation, name)
            self.refresh()

    def _clicked(self, name: str, modifier: str | None = None) -> None:
        """A click in the 3D view: select; shift: make it the selection's parent;
        ctrl/cmd: animate its DOFs (the report's context-menu actions)."""
        if modifier == "shift":
            self.attempt(
                lambda: self.apply(reparent_edit(self.view.selected, name), operation="parent")
            )
        elif modifier == "cmd/ctrl":

            def animate() -> None:
                c = constraint_of(self.task, name)
                if c is None:
                    raise ThirdhandError(f"{name} has no constraint to animate")
                self.select(name)
                self.animate_dofs(c.id)

            self.attempt(animate)
        else:
            self.attempt(self.select, name)

    def apply(self, edit: Edit, *, operation: str | None = None) -> None:
        """Apply one edit through the session (undoable, logged); refresh the views.

        Raises
        ------
        ThirdhandError
            The edit was refused (nothing changed).
        """
        with self.lock:
            self.motion.halt()
            self.session.apply(edit, operation=operation)
            self.say(f"applied: {describe_edit(edit)}")
            self.refresh()

    def choose_key_point(self, index: int) -> None:
        """Choose the key point (0-based) the Motion panel moves."""
        with self.lock:
            self.view = choose_key_point(self.task, self.view, index)
            self.refresh()

    def _key_point_dragged(self, index: int, point: FloatArray, client_id: int | None) -> None:
        """The key point's handle was released at ``point`` (m, parent frame)."""
        if not self.tabs.may_edit(client_id):
            self.notify("this tab only views: the key point stays", error=True)
            with self.lock:
                self.refresh()  # the handle goes back
            return
        key = primitive_key(self.task, self.view)
        if key is None:
            return
        edit = dragged_key_point(key, index, point)
        self.attempt(self.apply, edit, operation="primitive")

    def undo(self) -> None:
        """Undo the last edit."""
        with self.lock:
            if not self.session.history.can_undo:
                raise ThirdhandError("nothing to undo")
            self.session.undo()
            self.refresh()

    def redo(self) -> None:
        """Redo the last undone edit."""
        with self.lock:
            if not self.session.history.can_redo:
                raise ThirdhandError("nothing to redo")
            self.session.redo()
            self.refresh()

    def move_step_to(self, index: int, new_index: int) -> None:
        """Move plan step ``index`` to position ``new_index`` (0-based: the Up and Down
        buttons, the plan timeline's Move); the chosen and shown step follow it. An
        undoable edit like the others.

        Raises
        ------
        ThirdhandError
            An index out of range, or the move puts a step before one it must follow
            (or after one that must follow it) in a true partial order
            (:func:`~thirdhand.review.edits.order_conflict`); nothing changes.
        """
        with self.lock:
            check_step_move(self.task, index, new_index)
            self.apply(MoveStep(index, new_index, keep_order=True), operation="reordering")
            self.view = after_step_move(self.view, index, new_index)
            self.refresh()

    def choose_step(self, index: int) -> None:
        """Choose plan step ``index`` (a timeline marker) and show its keyframe."""
        with self.lock:
            self.view = choose_step(self.task, self.view, index)
            self.show_step(index)

    def show_step(self, index: int | None) -> None:
        """Show the keyframe of plan step ``index`` (None: the assembled task)."""
        with self.lock:
            self.motion.halt()
            self.view = show_step(self.task, self.view, index)
            if index is not None:
                self.session.effort.record("kfviews", ACTIONS)
                t = self.task.plan[index].time
                if t is not None and self.motion.timelines:  # playback resumes then
                    tl = self.motion.timelines[self.motion.demo_index]
                    self.motion.time = float(min(max(t, tl.start), tl.end))
                    if self.panels is not None:
                        self.panels.show_time(self.motion.time)
            self.refresh()

    def save(self, *, force: bool = False) -> Path | None:
        """Save the task (atomic, previous version kept); on a conflict keep the edits aside
        and offer to overwrite. ``force``: save over a file that changed on disk (its
        other version is kept as ``.bak``)."""
        with self.lock:
            try:
                path = self.session.save(force=force)
            except ConflictError:
                side = conflict_path(self.task_path)
                task = self.task.model_copy(deep=True)
                effort = self.session.effort.to_stage(self.session.changed_parameters())
                task.stages.ensure_review().effort = effort
                save_task(task, side)
                self.conflict = side
                self.notify(conflict_message(self.task_path.name, side.name), error=True)
                if self.panels is not None:
                    self.panels.ask_overwrite(self.task_path.name, side.name)
                return None
            if force:
                self.conflict = None
                self.notify(
                    f"Saved {path.name} over the changed file "
                    f"(the other version is {path.name}.bak)"
                )
            else:
                self.notify(f"Saved {path.name}")
            self.refresh()
            return path

    def reload(self, *, force: bool = False) -> bool:
        """Reload the file from disk; with unsaved changes only when ``force`` (else False)."""
        with self.lock:
            if self.session.dirty and not force:
                return False
            self.motion.halt()
            self.session = ReviewSession.open(self.task_path)
            self.view = after_reload(self.task, self.view)
            self.notify(f"Reloaded {self.task_path.name}")
            self.refresh()
            return True

    def request_quit(self, *, force: bool = False) -> bool:
        """Ask to quit; refused (False) with unsaved changes unless ``force``."""
        if self.session.dirty and not force:
            return False
        self.quit_requested.set()
        return True

    # ------------------------------------------------------------------ animation & playback
    def animate_dofs(
        self, constraint_id: str | None = None, dofs: Iterable[str] = DOF_NAMES
    ) -> None:
        """Animate a constraint's DOFs one after another (default: the selected one, all six)."""
        with self.lock:
            c = (
                require_constraint(self.task, self.view)
                if constraint_id is None
                else self.task.constraint_by_id(constraint_id)
            )
            parent = shown_poses(self.task, self.view).get(c.parent)
            self.motion.animate(c, list(dofs), parent)

    def _enter_playback(self) -> None:
        """The view shows the recording: the task's DOF glyphs and gizmo go away."""
        self.view = replace(self.view, mode="playback")
        if self.scene is not None:
            self.scene.hide_task_marks()

    def show_task(self) -> None:
        """Leave playback: parts back at their constraint poses."""
        with self.lock:
            self.motion.halt()
            self.view = replace(self.view, mode="task")
            self.refresh()

    # ------------------------------------------------------------------ scene
    def refresh(self) -> None:
        """Redraw the scene and the panels from the current state."""
        scene = self.scene
        if scene is not None:
            self.view = drop_unknown(self.view, scene.parts.frames)
        path = motion_path(self.task, self.view)
        if path is not None:
            self.view = clamp_key_point(self.view, path)
        if self.view.mode == "playback" and self.motion.timelines:
            self.motion.place()
            if scene is not None:
                scene.hide_task_marks()
        else:
            self.motion.hide_fingers()
            if scene is not None:
                scene.show(self.task, self.view, path)
        if self.panels is not None:
            self.panels.refresh(self._panel_state())

    def _panel_state(self) -> PanelState:
        """What the panels show, as one snapshot."""
        motion = self.motion
        replay = replay_at(self.replays, self.demos, motion)
        timeline = motion.timelines[motion.demo_index] if motion.timelines else None
        return PanelState(
            task=self.task,
            view=self.view,
            dirty=self.session.dirty,
            can_undo=self.session.history.can_undo,
            can_redo=self.session.history.can_redo,
            effort=self.session.effort,
            animating=motion.animating,
            clarification=self.clarifier.round,
            labelling=self.labeller.labelling,
            cursor=self.labeller.cursor,
            demo_index=motion.demo_index,
            timeline=timeline,
            contact_source=motion.contacts[motion.demo_index].source if timeline else "",
            replay_summary=replay.summary() if replay is not None else None,
            replay_starts=replay.step_starts() if replay is not None else None,
        )

    # ------------------------------------------------------------------ gizmo
    def gizmo_moved(self, move: GizmoMove) -> None:
        """A gizmo drag: the child follows; releasing it in editing mode corrects the pose.

        A tab that only views moves nothing: its drag is undone when released.
        """
        if not self.tabs.may_edit(move.client_id):
            if move.phase == "end":
                self.notify("this tab only views: the part stays", error=True)
                with self.lock:
                    self.refresh()  # the gizmo goes back
            return
        with self.lock:
            c = selected_constraint(self.task, self.view)
            poses = shown_poses(self.task, self.view)
            scene = self.scene
            if c is None or scene is None or c.child not in poses or c.parent not in poses:
                return
            p, q = gizmo_pose(poses[c.child], c, move)
            scene.parts.set_pose(c.child, p, q)
            if move.phase != "end" or not scene.gizmo.edits:
                return
            edit, operation = gizmo_edit(c, poses[c.parent], p, q, move)
        self.attempt(self.apply, edit, operation=operation)

    def set_gizmo_edits(self, edits: bool) -> None:
        """False: the gizmo explores the free DOFs; True: it corrects the pose on release."""
        with self.lock:
            if self.scene is not None:
                self.scene.gizmo.edits = edits
            self.refresh()


def app_url(host: str, port: int, gate: AccessGate | None) -> str:
    """Address of the web app reached as ``host`` on ``port`` (with the token ``gate``
    asks, if any)."""
    if gate is None:
        return f"http://{host}:{port}/"
    return token_url(host, port, gate.token)


def replay_at(
    replays: Sequence[Replay], demos: Sequence[Demonstration], motion: Motion
) -> Replay | None:
    """The execution record played back now (None: a recording of the person)."""
    k = motion.demo_index - len(demos)
    return replays[k] if 0 <= k < len(replays) else None


def camera_pose(scene: TaskScene | None, replay: Replay | None) -> tuple[Vec3, Vec3]:
    """Initial camera position and target (:meth:`TaskScene.camera_pose`; an execution
    replay shown: everything it moves, :func:`replay.replay_view`), world frame, m."""
    if replay is not None:
        from thirdhand.review.replay import replay_view

        return replay_view(replay.demo)
    if scene is None:
        return (1.0, -1.0, 1.0), (0.0, 0.0, 0.0)
    return scene.camera_pose()


def _load_demo(d: Demonstration | str | os.PathLike[str]) -> Demonstration:
    if isinstance(d, Demonstration):
        return d
    from thirdhand import io

    return io.load(Path(d))


__all__ = ["ReviewApp", "app_url", "camera_pose", "replay_at"]
