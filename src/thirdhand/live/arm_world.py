"""The assist's simulated arm and its two worlds, kept for every place its base stands.

Each place of the base (its x, y to the millimetre) has its own arm (the execution
stage's :class:`~thirdhand.execute.robot.Robot`, its base there) and two worlds
(:class:`~thirdhand.execute.scene.CollisionScene`): the one *checked* (the table, every
tracked part's box, a box for every tracked finger) and the one *planned in* (the same
boxes grown on every side). They are built the first time the base stands there and
kept; when the base comes back, the tracked bodies are moved to where they are now.

Frames: world, metres; quaternions x y z w.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from thirdhand.arrays import BoolArray, FloatArray

if TYPE_CHECKING:
    from thirdhand.execute.robot import Robot
    from thirdhand.execute.scene import CollisionScene

Pose = tuple[FloatArray, FloatArray]
#: Where a body out of the world is put (below the floor), metres.
GONE = np.array([0.0, 0.0, -10.0])


class ArmWorlds:
    """The arm and its worlds where the base stands now, and at every place it stood.

    Parameters
    ----------
    robot : str
        The arm (:meth:`~thirdhand.execute.robot.Robot.load`).
    names : sequence of str
        The stream's bodies (rows).
    parts, fingers : sequence of int
        The rows of the parts (a box each) and of the fingers.
    box : callable
        A part's box by row: centre (part frame) and sides, metres.
    table_z : float
        Height of the table's top, metres.
    hand_size_m : float
        Side of the box of each finger, metres.
    clearance_m : float
        How much the world planned in grows every box on every side, metres.

    Attributes
    ----------
    robot : Robot or None
        The arm where the base stands (None before it first stood).
    checked, planned : CollisionScene or None
        Its worlds: the one the arm's motion is checked in, the one it is planned in.
    base : ndarray, shape (3,)
        Where the base stands, world.
    attached : bool
        Whether the carried part is attached to the gripper in :attr:`checked`.
    """

    def __init__(
        self,
        robot: str,
        names: Sequence[str],
        parts: Sequence[int],
        fingers: Sequence[int],
        box: Callable[[int], tuple[FloatArray, FloatArray]],
        *,
        table_z: float,
        hand_size_m: float,
        clearance_m: float,
    ) -> None:
        self.robot_name = robot
        self.names = list(names)
        self.parts = list(parts)
        self.fingers = list(fingers)
        self.box = box
        self.table_z = table_z
        self.hand_size_m = hand_size_m
        self.clearance_m = clearance_m
        self.robot: Any = None
        self.checked: Any = None
        self.planned: Any = None
        self.base = np.zeros(3)
        self.attached = False
        #: The place the base stands at and the arm and both worlds of every place it has
        #: stood or been checked at (key: its x, y in millimetres).
        self._place: tuple[int, int] | None = None
        self._places: dict[tuple[int, int], tuple[Robot, CollisionScene, CollisionScene]] = {}

    def stand(
        self,
        base: FloatArray,
        base_quat: Callable[[], FloatArray],
        pos: FloatArray,
        quat: FloatArray,
        valid: BoolArray,
    ) -> None:
        """Make the arm and both worlds those of the base standing at ``base`` (3,), world.

        ``base_quat``: the base's orientation there (x y z w), asked when the place is new.
        An arm and its worlds are built once per place and kept; the tracked bodies are
        moved to ``pos``, ``quat`` (where ``valid``) when the base changes place.
        """
        from thirdhand.execute.robot import Robot

        key = (round(1e3 * float(base[0])), round(1e3 * float(base[1])))
        if key == self._place:
            return
        self._place = key
        if key in self._places:
            self.robot, self.checked, self.planned = self._places[key]
            self.base = np.asarray(base, dtype=np.float64).copy()
            self.track(pos, quat, valid, skip=-1)
            return
        self.robot = Robot.load(self.robot_name, base_pose=(base, base_quat()))
        self.base = np.asarray(base, dtype=np.float64).copy()
        self._build(pos, quat)
        self._places[key] = (self.robot, self.checked, self.planned)

    def home_clear(self) -> bool:
        """Whether the arm at home touches nothing in the world planned in."""
        return bool(self.planned.is_valid(self.robot.home))

    def _build(self, pos: FloatArray, quat: FloatArray) -> None:
        """The world checked (the tracked boxes) and the one planned in (the same boxes
        grown by the clearance on every side, so that a path grazing a part does not
        collide with it at its next, noisy, tracked pose)."""
        from thirdhand.execute.scene import CollisionScene

        grow = 2.0 * self.clearance_m
        scenes = []
        for extra in (0.0, grow):
            scene = CollisionScene(self.robot)
            centre = (float(self.base[0]), float(self.base[1]))
            scene.add_table(height=self.table_z, center=centre)
            ident = np.array([0.0, 0.0, 0.0, 1.0])
            for i in self.parts:
                c, size = self.box(i)
                p = pos[i] if np.all(np.isfinite(pos[i])) else GONE.copy()
                q = quat[i] if np.all(np.isfinite(quat[i])) else ident
                scene.add_object(self.names[i], (p, q), size=size + extra, box_center=c)
            s = self.hand_size_m + extra
            for i in self.fingers:
                p = pos[i] if np.all(np.isfinite(pos[i])) else GONE.copy()
                scene.add_box(self.names[i], (p, ident), (s, s, s))
            scenes.append(scene)
        self.checked, self.planned = scenes
        self.attached = False

    def track(self, pos: FloatArray, quat: FloatArray, valid: BoolArray, skip: int) -> None:
        """Move every tracked body (but row ``skip``) of both worlds to its pose now (the
        last one when not seen)."""
        ident = np.array([0.0, 0.0, 0.0, 1.0])
        for scene in (self.checked, self.planned):
            for i in self.parts:
                if i != skip and valid[i]:
                    scene.set_object_pose(self.names[i], (pos[i], quat[i]))
            for i in self.fingers:
                if valid[i]:
                    scene.set_object_pose(self.names[i], (pos[i], ident))

    def attach(self, name: str, pose: Pose, q: FloatArray) -> None:
        """Attach the part ``name``, put at ``pose`` (where it was grasped), to the gripper
        at ``q`` in the world checked."""
        self.checked.set_object_pose(name, pose)
        self.checked.attach(name, q)
        self.attached = True

    def release(self, name: str) -> None:
        """The person took the part ``name``: the arm lets go (it leaves both worlds)."""
        if self.attached:
            self.checked.detach(name, self.robot.home)
            gone = (GONE.copy(), np.array([0, 0, 0, 1.0]))
            self.checked.set_object_pose(name, gone)
            self.planned.set_object_pose(name, gone)
            self.attached = False


__all__ = ["ArmWorlds"]
