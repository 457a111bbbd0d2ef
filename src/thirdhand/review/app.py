"""The review GUI: a local viser web app to see, animate and correct a task file.

::

    app = ReviewApp("chair.task.json", demos=[demo], port=8080)
    url = app.start()          # serves http://127.0.0.1:8080 in a background thread
    ...
    app.stop()

The app is a thin layer over the model layer: every correction is an edit of
:mod:`thirdhand.review.edits` applied through a
:class:`~thirdhand.review.session.ReviewSession` (undo/redo, effort log, save
with conflict check). The methods of :class:`ReviewApp` (:meth:`select`,
:meth:`apply`, :meth:`set_values`, :meth:`move_step`, :meth:`save`...) are
what the widgets call; tests call them too. The widgets themselves are built
in :mod:`thirdhand.review.panels`.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import viser

from thirdhand.arrays import FloatArray
from thirdhand.demonstration import Demonstration
from thirdhand.errors import ThirdhandError
from thirdhand.review import dofs as dofs_mod
from thirdhand.review.access import AccessGate, is_loopback, new_token, shown_host, token_url
from thirdhand.review.clarify import Question, clarification_queue
from thirdhand.review.edits import (
    Confirm,
    Edit,
    MoveStep,
    SetParent,
    SetPose,
    SetPoseValue,
    SetPrimitivePoint,
    describe_edit,
    parse_number,
    pose_values,
)
from thirdhand.review.effort import ACTIONS, VALUE_OPERATION
from thirdhand.review.focus import Focus, find_focus
from thirdhand.review.gizmo import DofGizmo, GizmoMove, dominant_operation, moved_child
from thirdhand.review.motion import Motion, MotionEvents
from thirdhand.review.phase_labels import PhaseLabelling, PhaseQuestion
from thirdhand.review.primitive_edit import PrimitivePath, key_for, primitive_path
from thirdhand.review.primitive_view import PrimitiveView
from thirdhand.review.scene3d import (
    DofGlyphView,
    PartsView,
    floor_height,
    framed_view,
    front_view,
    selection_colours,
)
from thirdhand.review.session import ConflictError, ReviewSession
from thirdhand.se3 import pose_compose, pose_invert
from thirdhand.task.constraint import Constraint
from thirdhand.task.geometry import DOF_NAMES
from thirdhand.taskfile import TaskFile, save_task

if TYPE_CHECKING:
    from thirdhand.review.replay import Replay


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
    selected : str or None
        The selected object.
    step : int or None
        The keyframe shown (index into the plan), None for the assembled task.
    mode : {"task", "playback"}
        What the 3D view shows: the task at its constraint poses, or a recording.
    motion : Motion
        Animation and playback (its ``time``, ``playing``, ``animating``...).
    questions : list of Question
        The clarification round (least confident first); ``question_index`` the current one.
    focus : Focus or None
        The object the person pointed at or looked at (task's perception events,
        else the recording's pointing gestures): the round starts with it.
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
        #: Who may connect (None: anyone who reaches a loopback address).
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
        self.selected: str | None = None
        self.step: int | None = None
        #: The plan step chosen in the Step list (it follows Up/Down), None: the first.
        self.chosen_step: int | None = None
        self.mode = "task"
        self.message = f"Loaded {self.task_path.name}"
        self.questions: list[Question] = []
        self.question_index = 0
        self.focus: Focus | None = None
        self.conflict: Path | None = None
        self.quit_requested = threading.Event()
        self.server: viser.ViserServer | None = None
        self.parts: PartsView | None = None
        self.grid: viser.GridHandle | None = None
        #: The tab that may edit (viser client id): the first to connect; the others
        #: only view, and are told so, until it closes.
        self.editor: int | None = None
        self.glyphs: DofGlyphView | None = None
        self.gizmo: DofGizmo | None = None
        #: Phase labelling for calibration (None until started), the pair whose band is
        #: shown and where a marked interval starts (s).
        self.labelling: PhaseLabelling | None = None
        self.label_pair: tuple[str, str] | None = None
        self.label_from: float | None = None
        self.motion_view: PrimitiveView | None = None
        #: The learned motion's key point the Motion panel moves (0-based).
        self.key_point = 0
        self.panels: Any = None
        self.motion = Motion(self, [*self.demos, *(r.demo for r in self.replays)], segment=segment)
        if self.replays:  # the run first: it is what --replay asked to see
            self.motion.demo_index = len(self.demos)
            self.motion.time = self.motion.timelines[len(self.demos)].start
            self.message = "; ".join(r.summary() for r in self.replays)
        self.motion.events = MotionEvents(playback_entered=self._enter_playback)

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
        return self.url_for(shown_host(self.host))

    def url_for(self, host: str) -> str:
        """Address of the web app reached as ``host`` (with the token when one is asked)."""
        if self.gate is None:
            return f"http://{host}:{self.port}/"
        return token_url(host, self.port, self.gate.token)

    def start(self) -> str:
        """Start the server (background threads), build the scene and panels; return the URL."""
        from thirdhand.review.panels import Panels

        self.server = viser.ViserServer(host=self.host, port=self.requested_port, verbose=False)
        if self.gate is not None:
            self.gate.install(self.server)
        self.server.scene.set_up_direction("+z")
        if self.light_rendering:
            self.server.scene.configure_environment_map(None)
            self.server.scene.configure_default_lights(True, cast_shadow=False)
            self.server.scene.add_light_hemisphere(
                "/light", sky_color=(255, 255, 255), ground_color=(120, 120, 130), intensity=1.2
            )
        self.parts = PartsView(self.server.scene, self.task, self.task_path, self.meshes)
        self.grid = self.server.scene.add_grid(
            "/floor",
            width=2.0,
            height=2.0,
            cell_size=0.1,
            section_size=0.5,
            position=(0.0, 0.0, floor_height(self.task)),
        )
        self.parts.on_click(self._clicked)
        self.glyphs = DofGlyphView(self.server.scene)
        self.gizmo = DofGizmo(self.server.scene, self.gizmo_moved)
        self.motion_view = PrimitiveView(self.server.scene, on_drag=self._key_point_dragged)
        self.panels = Panels(self)
        self.motion.events = MotionEvents(
            playback_entered=self._enter_playback,
            time_shown=self.panels.show_time,
            playing_changed=self.panels.show_playing,
            demo_changed=self.panels.show_demo,
            animating=self.panels.show_animation,
        )
        self.server.on_client_connect(self._client_connected)
        self.server.on_client_disconnect(self._client_disconnected)
        with self.lock:
            self.refresh()
            said = [r.summary() for r in self.replays]
            if self.parts.missing_meshes:
                listed = ", ".join(f"{m} ({n})" for n, m in self.parts.missing_meshes.items())
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
        if self.server is not None:
            self.server.stop()
            self.server = None

    def _client_connected(self, client: viser.ClientHandle) -> None:
        if self.gate is not None and not self.gate.allowed(client.client_id):
            return
        position, look_at = self.camera_pose()
        client.camera.position = position
        client.camera.look_at = look_at
        with self.lock:
            if self.editor is None:
                self.editor = client.client_id
                return
        client.add_notification(
            "Read-only",
            "Another tab is editing this task; this one only shows it (one editor at a time).",
            color="yellow",
            auto_close_seconds=None,
        )

    def _client_disconnected(self, client: viser.ClientHandle) -> None:
        """The editing tab closed: the oldest other tab edits now, and is told so."""
        server = self.server  # stop() may clear it meanwhile
        if server is None:
            return
        with self.lock:
            if client.client_id != self.editor:
                return
            clients = server.get_clients()
            others = sorted(
                c
                for c in clients
                if c != client.client_id and (self.gate is None or self.gate.allowed(c))
            )
            self.editor = others[0] if others else None
            heir = clients.get(self.editor) if self.editor is not None else None
        if heir is not None:
            heir.add_notification(
                "You can edit now", "The editing tab closed.", color="green", auto_close_seconds=6.0
            )

    def may_edit(self, client_id: int | None) -> bool:
        """Whether the tab ``client_id`` may change the task (None: the server itself).

        A client without the access token never may; of the others, the editing tab.
        """
        if client_id is None:
            return True
        if self.gate is not None and not self.gate.allowed(client_id):
            return False
        return self.editor is None or client_id == self.editor

    def replay_shown(self) -> Replay | None:
        """The execution record played back now (None: a recording of the person)."""
        k = self.motion.demo_index - len(self.demos)
        return self.replays[k] if 0 <= k < len(self.replays) else None

    def camera_pose(self) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        """Initial camera position and target (:func:`scene3d.front_view`; an execution
        replay shown: everything it moves, :func:`replay.replay_view`), world frame, m."""
        replay = self.replay_shown()
        if replay is not None:
            from thirdhand.review.replay import replay_view

            return replay_view(replay.demo)
        parts = self.parts
        if parts is None:
            return (1.0, -1.0, 1.0), (0.0, 0.0, 0.0)
        centroids = np.array([parts.world_centroid(n) for n in parts.names]).reshape(-1, 3)
        return front_view(centroids, max(parts.extent.values(), default=0.3))

    # ------------------------------------------------------------------ derived state
    def constraint_of(self, child: str | None) -> Constraint | None:
        """The constraint whose child is ``child`` (None if none)."""
        if child is None:
            return None
        return next((c for c in self.task.constraints if c.child == child), None)

    @property
    def constraint(self) -> Constraint | None:
        """The selected object's constraint."""
        return self.constraint_of(self.selected)

    @property
    def parent(self) -> str | None:
        """The selected object's parent."""
        c = self.constraint
        return None if c is None else c.parent

    def colours(self) -> dict[str, tuple[int, int, int]]:
        """Every drawn object's colour as the scene shows it now."""
        return dict(self.parts.colours) if self.parts is not None else {}

    def world_poses(self) -> dict[str, Any]:
        """Every object's world pose at the keyframe shown (:func:`dofs.world_poses`)."""
        if not self.task.plan:
            return {}
        return dofs_mod.world_poses(self.task, self.step)

    # ------------------------------------------------------------------ messages
    def notify(self, text: str, *, error: bool = False) -> None:
        """Show ``text`` in the status line and as a notification in every browser."""
        self.message = f"Error: {text}" if error else text
        if self.panels is not None:
            self.panels.show_message(self.message, error=error)
        if self.server is not None:
            for client in self.server.get_clients().values():
                client.add_notification(
                    "Refused" if error else "Review",
                    text,
                    color="red" if error else "blue",
                    auto_close_seconds=None if error else 4.0,
                )

    def say(self, text: str) -> None:
        """Show ``text`` in the status line (replacing an earlier error), no notification."""
        self.message = text
        if self.panels is not None:
            self.panels.show_message(text, error=False)

    def attempt(self, fn: Any, *args: Any, **kwargs: Any) -> None:
        """Run an action for a widget: a refused one shows its message and changes nothing."""
        try:
            with self.lock:
                fn(*args, **kwargs)
        except ThirdhandError as exc:
            self.notify(str(exc), error=True)

    def attempt_long(self, fn: Any, *args: Any) -> None:
        """:meth:`attempt` for a long action that takes the app's lock only around its
        quick parts (:meth:`start_labelling`), so other tabs and panels are not blocked."""
        try:
            fn(*args)
        except ThirdhandError as exc:
            self.notify(str(exc), error=True)

    # ------------------------------------------------------------------ actions
    def select(self, name: str | None, *, operation: str | None = "click") -> None:
        """Select an object: it turns orange, its parent blue; its values fill the editors."""
        with self.lock:
            self.motion.halt()
            if name is not None and self.parts is not None and name not in self.parts.frames:
                raise ThirdhandError(f"unknown object {name!r}")
            self.selected = name
            if name is not None and operation is not None:
                self.session.effort.record(operation, name)
            self.mode = "task"
            self.refresh()

    def _clicked(self, name: str, modifier: str | None = None) -> None:
        """A click in the 3D view: select; shift: make it the selection's parent;
        ctrl/cmd: animate its DOFs (the report's context-menu actions)."""
        if modifier == "shift":
            self.attempt(self._reparent_selected, name)
        elif modifier == "cmd/ctrl":
            self.attempt(self._animate_object, name)
        else:
            self.attempt(self.select, name)

    def _reparent_selected(self, parent: str) -> None:
        if self.selected is None:
            raise ThirdhandError("select the child first, then shift-click its new parent")
        self.apply(SetParent(self.selected, parent), operation="parent")

    def _animate_object(self, name: str) -> None:
        c = self.constraint_of(name)
        if c is None:
            raise ThirdhandError(f"{name} has no constraint to animate")
        self.select(name)
        self.animate_dofs(c.id)

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

    def set_values(self, texts: dict[str, str]) -> None:
        """Typed pose values of the selected constraint: ``{"x": "12 cm", "yaw": "90 deg"}``.

        A bare number is read in the unit shown (cm, deg). Every value is parsed
        before any is applied, so one bad value changes nothing.
        """
        with self.lock:
            c = self.constraint
            if c is None:
                raise ThirdhandError("select an object with a constraint first")
            values = {
                name: parse_number(text, unit="cm" if name in ("x", "y", "z") else "deg")
                for name, text in texts.items()
            }
            for name, value in values.items():
                self.apply(SetPoseValue(c.id, name, value), operation=VALUE_OPERATION[name])

    def nudge(self, name: str, delta: float) -> None:
        """Rough adjustment: add ``delta`` (m or rad) to a pose value of the selected constraint."""
        with self.lock:
            c = self.constraint
            if c is None:
                raise ThirdhandError("select an object with a constraint first")
            current = pose_values(c)[name]
            self.apply(SetPoseValue(c.id, name, current + delta), operation=VALUE_OPERATION[name])

    def primitive_key(self) -> str | None:
        """The key of the selected constraint's learned motion (None: it has none)."""
        c = self.constraint
        if c is None:
            return None
        return key_for(self.task.stages.primitives, c.parent, c.child)

    def motion_path(self) -> PrimitivePath | None:
        """The selected constraint's learned motion as a path with key points (parent frame)."""
        key = self.primitive_key()
        return None if key is None else primitive_path(self.task.stages.primitives, key)

    def choose_key_point(self, index: int) -> None:
        """Choose the key point (0-based) the Motion panel moves."""
        with self.lock:
            path = self.motion_path()
            if path is None:
                raise ThirdhandError("select a part whose constraint has a learned motion first")
            n = len(path.key_times)
            if not 0 <= index < n:
                raise ThirdhandError(f"no key point {index + 1}; the motion has {n}")
            self.key_point = index
            self.refresh()

    def move_key_point(self, texts: dict[str, str]) -> None:
        """Move the chosen key point of the selected motion: ``{"x": "12 cm", ...}``.

        Parent frame; a bare number is in cm; a value not given stays. The motion
        is refitted and saved in the task's primitives block (undoable, counted as
        ``primitive`` in the effort log).
        """
        with self.lock:
            path = self.motion_path()
            if path is None:
                raise ThirdhandError("select a part whose constraint has a learned motion first")
            point = [float(v) for v in path.key_points[self.key_point]]
            for k, name in enumerate("xyz"):
                text = texts.get(name, "").strip()
                if text:
                    point[k] = parse_number(text, unit="cm")
            edit = SetPrimitivePoint(path.key, self.key_point, (point[0], point[1], point[2]))
            self.apply(edit, operation="primitive")

    def frame_selection(self, client: viser.ClientHandle) -> None:
        """Point ``client``'s camera at the selected part, from the direction it looks now."""
        with self.lock:
            if self.selected is None or self.parts is None:
                raise ThirdhandError("select a part to frame first")
            centre = self.parts.world_centroid(self.selected)
            size = self.parts.extent.get(self.selected, 0.1)
        eye, target = framed_view(client.camera.position, client.camera.look_at, centre, size)
        client.camera.position = eye
        client.camera.look_at = target

    def _key_point_dragged(self, index: int, point: FloatArray, client_id: int | None) -> None:
        """The key point's handle was released at ``point`` (m, parent frame)."""
        if not self.may_edit(client_id):
            self.notify("this tab only views: the key point stays", error=True)
            with self.lock:
                self.refresh()  # the handle goes back
            return
        key = self.primitive_key()
        if key is None:
            return
        edit = SetPrimitivePoint(key, index, (float(point[0]), float(point[1]), float(point[2])))
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

    def move_step(self, index: int, delta: int) -> None:
        """Move plan step ``index`` up (``delta`` -1) or down (+1); the chosen and shown step
        follow it.

        Raises
        ------
        ThirdhandError
            The step is already first (up) or last (down), or the move contradicts the
            plan's partial order.
        """
        with self.lock:
            new = index + delta
            n = len(self.task.plan)
            if not 0 <= new < n:
                where = "first" if delta < 0 else "last"
                raise ThirdhandError(f"step {index + 1} is already the {where} of {n}")
            self.move_step_to(index, new)

    def move_step_to(self, index: int, new_index: int) -> None:
        """Move plan step ``index`` to position ``new_index`` (0-based; the plan timeline's
        Move); the chosen and shown step follow it. An undoable edit like the others.

        Raises
        ------
        ThirdhandError
            An index out of range, or the move puts a step before one it must follow
            (or after one that must follow it) in a true partial order
            (:func:`~thirdhand.review.edits.order_conflict`); nothing changes.
        """
        with self.lock:
            n = len(self.task.plan)
            for what, v in (("step", index), ("position", new_index)):
                if not 0 <= v < n:
                    raise ThirdhandError(f"no {what} {v + 1}: the plan has {n} steps")
            if index == new_index:
                raise ThirdhandError(f"step {index + 1} is already at position {new_index + 1}")
            self.apply(MoveStep(index, new_index, keep_order=True), operation="reordering")
            if self.step == index:
                self.step = new_index
            self.chosen_step = new_index
            self.refresh()

    def choose_step(self, index: int) -> None:
        """Choose plan step ``index`` (a timeline marker) and show its keyframe."""
        with self.lock:
            n = len(self.task.plan)
            if not 0 <= index < n:
                raise ThirdhandError(f"no plan step {index + 1}; the plan has {n}")
            self.chosen_step = index
            self.show_step(index)

    def show_step(self, index: int | None) -> None:
        """Show the keyframe of plan step ``index`` (None: the assembled task)."""
        with self.lock:
            self.motion.halt()
            if index is not None and not 0 <= index < len(self.task.plan):
                raise ThirdhandError(f"no plan step {index}; the plan has {len(self.task.plan)}")
            self.step = index
            self.mode = "task"
            if index is not None:
                self.session.effort.record("kfviews", ACTIONS)
                t = self.task.plan[index].time
                if t is not None and self.motion.timelines:  # playback resumes then
                    tl = self.motion.timelines[self.motion.demo_index]
                    self.motion.time = float(min(max(t, tl.start), tl.end))
                    if self.panels is not None:
                        self.panels.show_time(self.motion.time)
            self.refresh()

    def save(self) -> Path | None:
        """Save the task (atomic, previous version kept); on a conflict keep the edits aside."""
        with self.lock:
            try:
                path = self.session.save()
            except ConflictError:
                side = self.task_path.with_name(self.task_path.stem + ".unsaved.json")
                task = self.task.model_copy(deep=True)
                effort = self.session.effort.to_stage(self.session.changed_parameters())
                task.stages.ensure_review().effort = effort
                save_task(task, side)
                self.conflict = side
                self.notify(
                    f"{self.task_path.name} changed on disk since it was loaded: not saved. "
                    f"Your edits are kept here and in {side.name}",
                    error=True,
                )
                if self.panels is not None:
                    self.panels.ask_overwrite(side)
                return None
            self.notify(f"Saved {path.name}")
            self.refresh()
            return path

    def overwrite(self) -> Path:
        """Save over a file that changed on disk (its other version is kept as ``.bak``)."""
        with self.lock:
            path = self.session.save(force=True)
            self.conflict = None
            self.notify(
                f"Saved {path.name} over the changed file (the other version is {path.name}.bak)"
            )
            self.refresh()
            return path

    def reload(self, *, force: bool = False) -> bool:
        """Reload the file from disk; with unsaved changes only when ``force`` (else False)."""
        with self.lock:
            if self.session.dirty and not force:
                return False
            self.motion.halt()
            self.session = ReviewSession.open(self.task_path)
            if self.step is not None and self.step >= len(self.task.plan):
                self.step = None
            self.notify(f"Reloaded {self.task_path.name}")
            self.refresh()
            return True

    def request_quit(self, *, force: bool = False) -> bool:
        """Ask to quit; refused (False) with unsaved changes unless ``force``."""
        if self.session.dirty and not force:
            return False
        self.quit_requested.set()
        return True

    # ------------------------------------------------------------------ clarification
    def start_clarification(self) -> Question | None:
        """Build the question queue (the object in focus, then least confident first); ask."""
        with self.lock:
            i = self.motion.demo_index
            demo = self.demos[i if i < len(self.demos) else 0] if self.demos else None
            self.focus = find_focus(self.task, demo)
            focus = self.focus.object if self.focus is not None else None
            self.questions = clarification_queue(self.task, focus=focus)
            self.question_index = 0
            return self._ask()

    @property
    def question(self) -> Question | None:
        """The question being asked, None when the round is over."""
        if 0 <= self.question_index < len(self.questions):
            return self.questions[self.question_index]
        return None

    def _ask(self) -> Question | None:
        q = self.question
        if q is None:
            self.notify("Clarification done: every question answered")
            self.refresh()
            return None
        c = self.task.constraint_by_id(q.constraint)
        self.selected = c.child
        self.refresh()
        self.animate_dofs(c.id, [q.dof] if q.dof is not None else list(DOF_NAMES))
        return q

    def answer(self, yes: bool) -> Question | None:
        """Answer the current question: yes confirms it; no leaves it for a correction.

        Returns the next question (None when the round is over).
        """
        with self.lock:
            q = self.question
            if q is None:
                raise ThirdhandError("no question to answer; start the clarification round")
            if yes:
                self.apply(Confirm(q.constraint, q.dof), operation="confirm")
            else:
                self.notify(f"Correct {q.constraint} in the Correct panel, then go on")
            self.question_index += 1
            return self._ask()

    # ------------------------------------------------------------------ phase labelling
    def start_labelling(self) -> PhaseQuestion | None:
        """Segment the recording shown and ask about its most uncertain intervals first.

        The segmentation (tens of seconds on a long recording) runs outside the
        app's lock, so the other panels and tabs stay responsive meanwhile.
        """
        with self.lock:
            i = self.motion.demo_index
            if i >= len(self.demos):
                raise ThirdhandError("phases are labelled on a recording of the person (--demo)")
            demo = self.demos[i]
            self.say("labelling: segmenting the recording…")
        from thirdhand.segment import segment_demonstration

        labelling = PhaseLabelling.from_segmentation(demo, segment_demonstration(demo))
        with self.lock:
            self.labelling = labelling
            self.label_pair = self.labelling.pairs[0]
            self.label_from = None
            return self._ask_phase()

    def _labelling(self) -> PhaseLabelling:
        if self.labelling is None:
            raise ThirdhandError("start labelling first")
        return self.labelling

    def _ask_phase(self) -> PhaseQuestion | None:
        q = self._labelling().question
        if q is None:
            self.notify("Labelling: every uncertain interval answered")
        else:
            self.label_pair = (q.a, q.b)
            self.motion.set_time(q.start)
        self.refresh()
        return q

    def answer_phase(self, yes: bool) -> PhaseQuestion | None:
        """Answer the phase question: its interval is (``yes``) or is not an interaction."""
        with self.lock:
            self._labelling().answer(yes)
            return self._ask_phase()

    def choose_label_pair(self, pair: tuple[str, str]) -> None:
        """Show the band of ``pair`` (its marginal and labels)."""
        with self.lock:
            if pair not in self._labelling().pairs:
                raise ThirdhandError(f"no pair {pair[0]} - {pair[1]} to label")
            self.label_pair = pair
            self.refresh()

    def mark_from_here(self) -> None:
        """The marked interval starts at the playback time."""
        with self.lock:
            self._labelling()
            self.label_from = self.motion.time
            self.say(f"labelling: from {self.label_from:.2f} s; play on, then mark to here")
            self.refresh()

    def mark_to_here(self, value: bool) -> None:
        """Mark the shown pair interacting (``value``) or not from the mark to the playback time."""
        with self.lock:
            labelling = self._labelling()
            if self.label_from is None or self.label_pair is None:
                raise ThirdhandError("mark where the interval starts first (From here)")
            a, b = sorted((self.label_from, self.motion.time))
            labelling.mark(self.label_pair, a, b, value)
            what = "interacting" if value else "not interacting"
            self.say(
                f"labelling: {self.label_pair[0]} - {self.label_pair[1]} {what} {a:.2f}-{b:.2f} s"
            )
            self.label_from = None
            self.refresh()

    def save_phase_labels(self) -> Path:
        """Write the labels next to the task (``STEM.phases.kvg``; the previous one kept as
        a numbered backup): ``thirdhand segment train/calibrate --labels`` reads it."""
        with self.lock:
            path = self.task_path.with_name(f"{self.task_path.stem}.phases.kvg")
            out = self._labelling().write(path, force=True)
            self.notify(f"Saved the phase labels in {out.name}")
            return out

    # ------------------------------------------------------------------ animation & playback
    def animate_dofs(
        self, constraint_id: str | None = None, dofs: Iterable[str] = DOF_NAMES
    ) -> None:
        """Animate a constraint's DOFs one after another (default: the selected one, all six)."""
        with self.lock:
            c = (
                self.constraint
                if constraint_id is None
                else self.task.constraint_by_id(constraint_id)
            )
            if c is None:
                raise ThirdhandError("select an object with a constraint first")
            self.motion.animate(c, list(dofs))

    def _enter_playback(self) -> None:
        """The view shows the recording: the task's DOF glyphs and gizmo go away."""
        self.mode = "playback"
        if self.motion_view is not None:
            self.motion_view.clear()
        if self.glyphs is not None:
            self.glyphs.clear()
        if self.gizmo is not None:
            self.gizmo.hide()

    def show_task(self) -> None:
        """Leave playback: parts back at their constraint poses."""
        with self.lock:
            self.motion.halt()
            self.mode = "task"
            self.refresh()

    # ------------------------------------------------------------------ scene
    def refresh(self) -> None:
        """Redraw the scene and the panels from the current state."""
        if self.selected is not None and self.parts is not None:
            if self.selected not in self.parts.frames:
                self.selected = None
        if self.mode == "playback" and self.motion.timelines:
            self.motion.place()
            if self.motion_view is not None:
                self.motion_view.clear()
            if self.glyphs is not None:
                self.glyphs.clear()
            if self.gizmo is not None:
                self.gizmo.hide()
        else:
            self.motion.hide_fingers()
            self._place_parts()
        if self.panels is not None:
            self.panels.refresh()

    def _place_parts(self) -> None:
        if self.parts is None or self.glyphs is None or self.gizmo is None:
            return
        poses = self.world_poses()
        self.parts.set_poses({n: (p.pos, p.quat) for n, p in poses.items()})
        self.parts.set_colours(selection_colours(self.parts.names, self.selected, self.parent))
        c = self.constraint
        child = poses.get(c.child) if c is not None else None
        if c is None or child is None:
            self.glyphs.clear()
            self.gizmo.hide()
            if self.motion_view is not None:
                self.motion_view.clear()
            return
        self._show_motion(c, poses)
        ap, aq = pose_compose(child.pos, child.quat, c.frame.pos, c.frame.quat)
        ranges = c.free_dof_array()
        classes = [
            dofs_mod.classify_dof(lo, hi, d) for d, (lo, hi) in zip(DOF_NAMES, ranges, strict=True)
        ]
        size = self.parts.extent.get(c.child, 0.1)
        self.glyphs.show(ap, aq, ranges, classes, size=size)
        self.gizmo.show(c, classes, size)

    def _show_motion(self, c: Constraint, poses: dict[str, Any]) -> None:
        """Draw the constraint's learned motion at its parent's pose (or nothing)."""
        view = self.motion_view
        if view is None:
            return
        path = self.motion_path()
        parent = poses.get(c.parent)
        if path is None or parent is None:
            view.clear()
            return
        self.key_point = min(self.key_point, len(path.key_times) - 1)
        size = self.parts.extent.get(c.child, 0.1) if self.parts is not None else 0.1
        view.show(path, parent.pos, parent.quat, chosen=self.key_point, size=size)

    # ------------------------------------------------------------------ gizmo
    def gizmo_moved(self, move: GizmoMove) -> None:
        """A gizmo drag: the child follows; releasing it in editing mode corrects the pose.

        A tab that only views moves nothing: its drag is undone when released.
        """
        if not self.may_edit(move.client_id):
            if move.phase == "end":
                self.notify("this tab only views: the part stays", error=True)
                with self.lock:
                    self.refresh()  # the gizmo goes back
            return
        with self.lock:
            c = self.constraint
            poses = self.world_poses()
            if c is None or self.parts is None or c.child not in poses or c.parent not in poses:
                return
            p, q = moved_child(poses[c.child], c.frame, move.pos, move.quat)
            self.parts.set_pose(c.child, p, q)
            if move.phase != "end" or self.gizmo is None or not self.gizmo.edits:
                return
            parent = poses[c.parent]
            lp, lq = pose_compose(*pose_invert(parent.pos, parent.quat), p, q)
        edit = SetPose(c.id, _vec3(lp), _quat4(lq))
        self.attempt(self.apply, edit, operation=dominant_operation(move.pos, move.quat))

    def set_gizmo_edits(self, edits: bool) -> None:
        """False: the gizmo explores the free DOFs; True: it corrects the pose on release."""
        with self.lock:
            if self.gizmo is not None:
                self.gizmo.edits = edits
            self.refresh()


def _vec3(v: FloatArray) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


def _quat4(v: FloatArray) -> tuple[float, float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]), float(v[3]))


def _load_demo(d: Demonstration | str | os.PathLike[str]) -> Demonstration:
    if isinstance(d, Demonstration):
        return d
    from thirdhand import io

    return io.load(Path(d))


__all__ = ["ReviewApp"]
