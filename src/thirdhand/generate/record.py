"""The frame sink that records a simulated episode: state, commands, parts' poses, two cameras.

At every frame :class:`FrameRecorder` (a ``sink(model, data, label)`` of
:func:`~thirdhand.simulate.run.simulate_run`) keeps:

- the state: the 7 arm joint positions (rad) and the gripper's width (m, the sum
  of the two finger joints);
- the action: the arm servos' set-points (``data.ctrl`` of the arm actuators,
  rad: the planned position plus ``damping / stiffness`` times the planned
  velocity, the servo's velocity feed-forward) and the gripper's width command
  (m): the fingers are force-driven, pushing open or closed with the gripper's
  force, so a positive force is the open width (0.08 m) and a negative one 0;
- every part's pose in the world frame: position (m) and unit quaternion
  (x, y, z, w), sign-continuous over the episode;
- a frame of the fixed camera of ``thirdhand simulate --video`` and one of the
  wrist camera (:data:`~thirdhand.simulate.model.WRIST_CAMERA`);
- the step and motion segment under way, as text.
"""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from thirdhand.arrays import FloatArray
from thirdhand.execute.robot import ROBOTS
from thirdhand.simulate.model import FINGER_OPEN, FINGERS, WRIST_CAMERA
from thirdhand.simulate.parts import SimulateError
from thirdhand.simulate.video import front_camera

#: Names of the state's and the action's columns after the arm joints.
GRIPPER = "gripper_width"
#: Columns of a part's pose, after ``<part>.``.
POSE_COLUMNS = ("x", "y", "z", "qx", "qy", "qz", "qw")


@dataclass(frozen=True)
class Recording:
    """One episode as recorded, one row per frame.

    Attributes
    ----------
    state : ndarray, shape (n_frames, 8)
        Arm joint positions (rad) and the gripper's width (m).
    action : ndarray, shape (n_frames, 8)
        Arm servo set-points (rad) and the gripper's width command (m).
    environment : ndarray, shape (n_frames, 7 * n_parts)
        Per part: position (m) and quaternion (x, y, z, w), world frame.
    joints : tuple of str
        The arm joints, in the order of the columns.
    parts : tuple of str
        The parts, in the order of ``environment``.
    front, wrist : ndarray of uint8, shape (n_frames, height, width, 3)
        RGB frames of the fixed and the wrist camera.
    labels : tuple of str
        The step and segment under way at each frame.
    time : ndarray, shape (n_frames,)
        Simulated time of each frame, seconds.
    """

    state: FloatArray
    action: FloatArray
    environment: FloatArray
    joints: tuple[str, ...]
    parts: tuple[str, ...]
    front: NDArray[np.uint8]
    wrist: NDArray[np.uint8]
    labels: tuple[str, ...]
    time: FloatArray

    @property
    def n_frames(self) -> int:
        """Number of frames."""
        return int(self.state.shape[0])


def gripper_command(finger_ctrl: FloatArray) -> float:
    """The width the fingers are driven to, m: open (0.08) when they push open, else 0.

    Parameters
    ----------
    finger_ctrl : ndarray, shape (2,)
        The finger actuators' forces, N (positive opens).
    """
    return 2.0 * FINGER_OPEN if float(np.mean(finger_ctrl)) > 0.0 else 0.0


def continuous_quaternions(quat: FloatArray, previous: FloatArray | None) -> FloatArray:
    """``quat`` (k, 4) with each row's sign flipped where it points away from ``previous``."""
    q = np.array(quat, dtype=np.float64)
    if previous is not None:
        flip = np.einsum("ij,ij->i", q, previous) < 0.0
        q[flip] *= -1.0
    return q


def open_renderer(model: Any, *, width: int, height: int) -> Any:
    """A ``mujoco.Renderer`` of ``width`` x ``height`` pixels.

    Raises
    ------
    SimulateError
        No offscreen renderer can be made (one line with the reason and the packages).
    """
    import mujoco

    try:
        return mujoco.Renderer(model, height=height, width=width)
    except Exception as exc:  # any GL failure: missing library, no display, bad back end
        gl = os.environ.get("MUJOCO_GL", "")
        why = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise SimulateError(
            f"no offscreen renderer for the cameras (MUJOCO_GL={gl}): {why}; install Debian's "
            "libegl1 and libgl1-mesa-dri (egl) or libosmesa6 (MUJOCO_GL=osmesa)"
        ) from None


class FrameRecorder:
    """Records every frame of a running simulation (see the module documentation).

    Parameters
    ----------
    model : mujoco.MjModel
        The compiled model of the run.
    robot : str
        The robot (its arm joints name the actuators).
    parts : sequence of str
        The parts whose poses are recorded (bodies of the model).
    lookat : ndarray, shape (3,)
        Where the fixed camera looks, world frame, metres (2 m away).
    width, height : int
        Image size, pixels.
    """

    def __init__(
        self, model: Any, *, robot: str, parts: Sequence[str], lookat: FloatArray, width: int,
        height: int,
    ) -> None:  # fmt: skip
        self.joints = tuple(ROBOTS[robot].arm_joints)
        self.parts = tuple(parts)
        self._qadr = np.array([model.jnt_qposadr[model.joint(n).id] for n in self.joints])
        self._arm_act = np.array([model.actuator(n).id for n in self.joints])
        self._finger_q = np.array([model.jnt_qposadr[model.joint(n).id] for n in FINGERS])
        self._finger_act = np.array([model.actuator(n).id for n in FINGERS])
        self._bodies = np.array([model.body(p).id for p in self.parts], dtype=np.int64)
        self._camera = front_camera(lookat, 2.0)
        self._renderer = open_renderer(model, width=width, height=height)
        self._rows: dict[str, list[Any]] = {
            k: [] for k in ("state", "action", "env", "front", "wrist", "label", "time")
        }
        self._quat: FloatArray | None = None
        self.render_time = 0.0

    def __call__(self, model: Any, data: Any, label: str) -> None:
        """Record the current state of ``data``."""
        rows = self._rows
        q = np.asarray(data.qpos[self._qadr], dtype=np.float64)
        width = float(np.sum(data.qpos[self._finger_q]))
        rows["state"].append(np.append(q, width))
        ctrl = np.asarray(data.ctrl[self._arm_act], dtype=np.float64)
        rows["action"].append(np.append(ctrl, gripper_command(data.ctrl[self._finger_act])))
        wxyz = np.asarray(data.xquat[self._bodies], dtype=np.float64)
        self._quat = continuous_quaternions(wxyz[:, [1, 2, 3, 0]], self._quat)
        pos = np.asarray(data.xpos[self._bodies], dtype=np.float64)
        rows["env"].append(np.concatenate([pos, self._quat], axis=1).reshape(-1))
        rows["label"].append(label)
        rows["time"].append(float(data.time))
        t0 = time.perf_counter()
        r = self._renderer
        r.update_scene(data, camera=self._camera)
        rows["front"].append(r.render().copy())
        r.update_scene(data, camera=WRIST_CAMERA)
        rows["wrist"].append(r.render().copy())
        self.render_time += time.perf_counter() - t0

    def recording(self) -> Recording:
        """Everything recorded so far.

        Raises
        ------
        SimulateError
            No frame was recorded.
        """
        rows = self._rows
        if not rows["state"]:
            raise SimulateError("the simulation recorded no frame")
        return Recording(
            state=np.stack(rows["state"]),
            action=np.stack(rows["action"]),
            environment=np.stack(rows["env"]),
            joints=self.joints,
            parts=self.parts,
            front=np.stack(rows["front"]),
            wrist=np.stack(rows["wrist"]),
            labels=tuple(rows["label"]),
            time=np.asarray(rows["time"], dtype=np.float64),
        )

    def close(self) -> None:
        """Free the renderer."""
        self._renderer.close()
