"""What moves by itself in the review GUI: DOF animations and demonstration playback.

One background worker at a time (starting one halts the other). A worker
never blocks on the app's lock: the thread halting it holds that lock while it
waits for the worker to end.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import viser

from thirdhand.arrays import FloatArray
from thirdhand.demonstration import Demonstration
from thirdhand.errors import ThirdhandError
from thirdhand.review import dofs as dofs_mod
from thirdhand.review.playback import HandContacts, Timeline, hand_contacts, playback_colours
from thirdhand.review.scene3d import FINGER_RGB, PartsView
from thirdhand.se3 import pose_compose
from thirdhand.task.constraint import Constraint

#: Seconds per DOF of an animation, and its frame rate (Hz).
ANIMATION_SECONDS = 1.2
ANIMATION_RATE = 20.0
#: Playback frame rate, Hz.
PLAYBACK_RATE = 20.0
#: Radius of a finger's sphere in playback, metres.
FINGER_RADIUS = 0.008
#: Axis length of a robot tool frame in an execution replay, metres.
TOOL_AXES = 0.08


def _contacts(demo: Demonstration, *, segment: bool) -> HandContacts:
    """Who holds what: the hands of a recording, the robot of an execution replay."""
    if demo.meta.get("source") == "thirdhand.execute":
        from thirdhand.review.replay import robot_contacts

        return robot_contacts(demo)
    return hand_contacts(demo, segment=segment)


def _ignore(*_args: object) -> None:
    return None


@dataclass
class MotionEvents:
    """What :class:`Motion` tells its owner (the app and its panels); each a no-op by default.

    Attributes
    ----------
    playback_entered : callable ()
        The view shows the recording now (not the task).
    time_shown : callable (float)
        The playback time, seconds.
    playing_changed : callable (bool)
        Playback started (True) or stopped.
    demo_changed : callable ()
        Another recording is played back.
    animating : callable (Constraint, str or None)
        The DOF being animated (None: the animation is over).
    animation_ended : callable ()
        An animation ran to its end; called holding the owner's lock (the view is redrawn).
    """

    playback_entered: Callable[[], None] = _ignore
    time_shown: Callable[[float], None] = _ignore
    playing_changed: Callable[[bool], None] = _ignore
    demo_changed: Callable[[], None] = _ignore
    animating: Callable[[Constraint, str | None], None] = _ignore
    animation_ended: Callable[[], None] = _ignore


class Motion:
    """Animation and playback in the review's 3D view.

    It draws on the scene given to :meth:`attach` and reports through
    :attr:`events`; it knows no app and no panel.

    Parameters
    ----------
    lock : threading.RLock
        The owner's lock: a worker takes it around each frame it draws.
    demos : sequence of Demonstration
        Recordings to play back.
    segment : bool
        Find hand contacts with the segmentation stage when a recording has no labels.

    Attributes
    ----------
    timelines : list of Timeline
    contacts : list of HandContacts
    demo_index : int
        The recording played back.
    time : float
        Playback time, seconds.
    playing : bool
    animating : str or None
        The DOF being animated.
    """

    def __init__(
        self, lock: threading.RLock, demos: Sequence[Demonstration], *, segment: bool
    ) -> None:
        self.lock = lock
        self._scene: viser.SceneApi | None = None
        self._parts: PartsView | None = None
        self.timelines = [Timeline(d) for d in demos]
        self.contacts: list[HandContacts] = [_contacts(d, segment=segment) for d in demos]
        self.demo_index = 0
        self.time = self.timelines[0].start if self.timelines else 0.0
        self.playing = False
        self.animating: str | None = None
        self._fingers: dict[str, viser.IcosphereHandle] = {}
        self._tools: dict[str, viser.FrameHandle] = {}
        self._worker: threading.Thread | None = None
        self._stop = threading.Event()
        #: Set by the owner: Motion reports through these, it drives no panel.
        self.events = MotionEvents()

    def attach(self, scene: viser.SceneApi | None, parts: PartsView | None) -> None:
        """Draw on ``scene`` (fingers, tool frames) and move ``parts`` (None: nowhere, the
        server stopped)."""
        self._scene, self._parts = scene, parts

    # ---------------------------------------------------------------- workers
    def _start(self, target: Callable[[threading.Event], None]) -> None:
        self.halt()
        self._stop = stop = threading.Event()
        self._worker = threading.Thread(target=target, args=(stop,), daemon=True)
        self._worker.start()

    def halt(self) -> None:
        """Stop the running animation or playback (if any) and wait for it."""
        worker, self._worker = self._worker, None
        self._stop.set()
        if worker is not None and worker is not threading.current_thread():
            worker.join(timeout=2.0)
        self.animating = None
        if self.playing:
            self.playing = False
            self.events.playing_changed(False)

    def _acquire_unless(self, stop: threading.Event) -> bool:
        """Take the owner's lock for a worker, unless it is told to stop meanwhile."""
        lock = self.lock
        while not stop.is_set():
            if lock.acquire(timeout=0.05):
                if not stop.is_set():
                    return True
                lock.release()
        return False

    # ---------------------------------------------------------------- animation
    def animate(self, c: Constraint, dofs: Sequence[str], parent: Any) -> None:
        """Move ``c``'s child along each DOF in turn (:func:`dofs.dof_animation`) from its
        parent's world pose ``parent`` (``.pos`` m, ``.quat`` x y z w; None: nothing moves)."""
        order = list(dofs)
        self._start(lambda stop: self._animation(c, order, parent, stop))

    def _animation(
        self, c: Constraint, order: list[str], parent: Any, stop: threading.Event
    ) -> None:
        parts = self._parts
        if parent is None or parts is None:
            return
        n = max(2, int(ANIMATION_SECONDS * ANIMATION_RATE))
        for dof in order:
            self.animating = dof
            self.events.animating(c, dof)
            for k in range(n):
                if stop.is_set():
                    return
                local = dofs_mod.dof_animation(c, dof, k / n)
                p, q = pose_compose(parent.pos, parent.quat, local.pos, local.quat)
                parts.set_pose(c.child, p, q)
                stop.wait(1.0 / ANIMATION_RATE)
        self.animating = None
        self.events.animating(c, None)
        if self._acquire_unless(stop):
            try:
                self.events.animation_ended()
            finally:
                self.lock.release()

    # ---------------------------------------------------------------- playback
    def _timeline(self) -> Timeline:
        if not self.timelines:
            raise ThirdhandError("no demonstration loaded (pass --demo)")
        return self.timelines[self.demo_index]

    def set_time(self, time_s: float) -> None:
        """Show the recording at ``time_s`` seconds (clamped), parts coloured by hand."""
        with self.lock:
            tl = self._timeline()
            self.time = float(min(max(time_s, tl.start), tl.end))
            self.events.playback_entered()
            self.place()
            self.events.time_shown(self.time)

    def set_demo(self, index: int) -> None:
        """Play back recording ``index`` from its start."""
        with self.lock:
            if not 0 <= index < len(self.timelines):
                raise ThirdhandError(f"no recording {index}; {len(self.timelines)} loaded")
            self.halt()
            self.demo_index = index
            self.events.demo_changed()
            self.set_time(self.timelines[index].start)

    def play(self, playing: bool = True, *, speed: float = 1.0) -> None:
        """Start (or pause) playback from the current time, ``speed`` x real time."""
        with self.lock:
            if not playing:
                self.halt()
                return
            self._timeline()
            self.events.playback_entered()
            self._start(lambda stop: self._playback(stop, speed))
            self.playing = True
            self.events.playing_changed(True)

    def _playback(self, stop: threading.Event, speed: float) -> None:
        tl = self.timelines[self.demo_index]
        last = time.perf_counter()
        while not stop.wait(1.0 / PLAYBACK_RATE):
            now = time.perf_counter()
            if not self._acquire_unless(stop):
                return
            try:
                t = self.time + speed * (now - last)
                last = now
                self.time = tl.start if t >= tl.end else t
                self.place()
                self.events.time_shown(self.time)
            finally:
                self.lock.release()

    def place(self) -> None:
        """Put parts and fingers where the recording has them at :attr:`time`."""
        parts, scene = self._parts, self._scene
        if parts is None or scene is None:
            return
        tl = self._timeline()
        poses = tl.poses_at(self.time)
        parts.set_poses({n: pq for n, pq in poses.items() if n in parts.frames})
        colours = playback_colours(self.contacts[self.demo_index], parts.names, self.time)
        parts.set_colours(colours)
        kinds = {b.name: b.kind for b in tl.demo.bodies}
        for name, tool in self._tools.items():  # another recording's tool frame
            if name not in poses:
                tool.visible = False
        for n in tl.names:
            if n in parts.frames or n not in poses:
                continue
            if kinds.get(n) == "tool":  # an execution replay's tool frame: axes
                self._show_tool(n, *poses[n])
                continue
            h = self._fingers.get(n)
            if h is None:
                h = scene.add_icosphere(f"/fingers/{n}", radius=FINGER_RADIUS, color=FINGER_RGB)
                self._fingers[n] = h
            h.visible = True
            x, y, z = (float(v) for v in poses[n][0])
            h.position = (x, y, z)

    def _show_tool(self, name: str, pos: FloatArray, quat: FloatArray) -> None:
        assert self._scene is not None
        h = self._tools.get(name)
        if h is None:
            h = self._scene.add_frame(
                f"/tools/{name}", axes_length=TOOL_AXES, axes_radius=0.1 * TOOL_AXES
            )
            self._tools[name] = h
        h.visible = True
        h.position = (float(pos[0]), float(pos[1]), float(pos[2]))
        x, y, z, w = (float(v) for v in quat)
        h.wxyz = (w, x, y, z)

    def tool_pose(self, name: str) -> tuple[FloatArray, FloatArray] | None:
        """Where the tool frame ``name`` is drawn: position (m) and quaternion x y z w."""
        h = self._tools.get(name)
        if h is None or not h.visible:
            return None
        w, x, y, z = h.wxyz
        return np.asarray(h.position, dtype=float), np.array([x, y, z, w])

    def hide_fingers(self) -> None:
        """Hide the fingers and tool frames (outside playback)."""
        for h in self._fingers.values():
            h.visible = False
        for t in self._tools.values():
            t.visible = False
