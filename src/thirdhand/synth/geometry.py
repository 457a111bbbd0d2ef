"""Part geometry and slots of the synthetic scenes.

Sizes come from the 3rdHand project's meshes (``meshes/*.stl``, millimetres; the
bounding boxes are read by :func:`thirdhand.io.stl.stl_bounds`): the chair's seat is 300 × 300 ×
20 mm, its legs 80 mm thick and 280 mm long, its back 386 × 420 × 30 mm; the
bench's seat 300 × 300 × 40 mm and legs 61 × 240 mm; the toolbox boards 17 mm
thick (``ToolboxPart1`` the handle 390 × 180, ``Part2`` the front/back 260 × 120,
``Part3`` the sides 425 × 120). Slot positions follow the corrected constraints of
the IROS 2015 user study (``iros15_user_study.yaml``). The geometry is stored here
so that scenes build without the data; tests check it against the meshes.

Body frames (all synthetic, metres):

- seat: origin at the centre, ``y`` the normal towards the legs.
- leg: origin at the screw end (the chair leg's narrow tenon, which goes into the
  seat's pocket), ``x`` along the leg away from the seat.
- back: origin at the middle of its bottom edge (the narrow end, which goes into the
  seat's groove), extending along ``−y``.

A mesh sits in its body frame as its bounding box aligned onto the body's
(:func:`thirdhand.task.meshes.align_bounds`), turned a half-turn about one body axis
where the box alone leaves the part upside down (``mesh_turn``): the chair leg's
tenon and the back's narrow end lie at the far end of their meshes' boxes.
- board: origin at the centre of its bounding box, ``x`` along its length,
  ``y`` along its height, ``z`` through its thickness.
- screw: origin at the head, ``x`` along the shaft towards the tip.
- screwdriver: origin at the tip, ``x`` along the shaft towards the handle.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from thirdhand.arrays import FloatArray

# Re-exported: the synthetic scenes read part sizes from the meshes with them.
from thirdhand.io.stl import read_stl as read_stl
from thirdhand.io.stl import stl_bounds as stl_bounds
from thirdhand.se3 import matrix_from_quat, quat_from_matrix

# Re-exported: the 3rdHand meshes' bounds, known to the task package.
from thirdhand.task.meshes import MESH_BOUNDS_MM as MESH_BOUNDS_MM
from thirdhand.task.meshes import align_bounds


@dataclass(frozen=True)
class PartGeometry:
    """Shape of one kind of part, in its synthetic body frame.

    Attributes
    ----------
    mesh : str or None
        File name of the 3rdHand mesh (in ``meshes/``), None for synthetic-only parts.
    lo, hi : tuple of 3 floats
        Bounding box in the body frame, metres.
    mesh_turn : int or None
        Body axis (0, 1, 2) about which the box-aligned mesh is turned a half-turn
        through the box's centre, or None.
    """

    mesh: str | None
    lo: tuple[float, float, float]
    hi: tuple[float, float, float]
    mesh_turn: int | None = None

    @property
    def size(self) -> FloatArray:
        """Extent along x, y, z, metres, shape (3,)."""
        return np.subtract(self.hi, self.lo)

    def mesh_to_body(self) -> tuple[FloatArray, FloatArray] | None:
        """Pose of the mesh in the body frame, ``(pos (3,) m, quat (4,) xyzw)``, or None.

        None without a 3rdHand mesh, or when the bounding boxes' alignment is right as
        it is (the task reads it from the boxes then).
        """
        if self.mesh is None or self.mesh_turn is None:
            return None
        mlo, mhi = (np.asarray(b, float) * 1e-3 for b in MESH_BOUNDS_MM[self.mesh])
        lo, hi = np.asarray(self.lo), np.asarray(self.hi)
        aligned = align_bounds(mlo, mhi, lo, hi)
        turn = np.diag([-1.0, -1.0, -1.0])
        turn[self.mesh_turn, self.mesh_turn] = 1.0
        centre = (lo + hi) / 2
        rot = turn @ matrix_from_quat(np.asarray(aligned.quat))
        pos = turn @ (np.asarray(aligned.pos) - centre) + centre
        return pos, quat_from_matrix(rot)

    def to_meta(self) -> dict[str, object]:
        """JSON-able description for ``Demonstration.meta``."""
        meta: dict[str, object] = {
            "mesh": self.mesh, "bbox_min_m": list(self.lo), "bbox_max_m": list(self.hi)
        }  # fmt: skip
        pose = self.mesh_to_body()
        if pose is not None:
            meta["mesh_to_body"] = {"pos": pose[0].tolist(), "quat": pose[1].tolist()}
        return meta


def _box(mesh: str | None, sx: float, sy: float, sz: float) -> PartGeometry:
    return PartGeometry(mesh, (-sx / 2, -sy / 2, -sz / 2), (sx / 2, sy / 2, sz / 2))


CHAIR_SEAT = _box("chair_seating.stl", 0.300, 0.020, 0.300)
CHAIR_LEG = PartGeometry("chair_leg.stl", (0.0, -0.040, -0.040), (0.280, 0.040, 0.040), 1)
CHAIR_BACK = PartGeometry("chair_back.stl", (-0.193, -0.420, -0.015), (0.193, 0.0, 0.015), 2)
BENCH_SEAT = _box("bench_sitting.stl", 0.300, 0.040, 0.300)
BENCH_LEG = PartGeometry("bench_leg.stl", (0.0, -0.0305, -0.0305), (0.240, 0.0305, 0.0305))
TOOLBOX_HANDLE = _box("ToolboxPart1.stl", 0.390, 0.180, 0.017)
TOOLBOX_END = _box("ToolboxPart2.stl", 0.260, 0.120, 0.017)
TOOLBOX_SIDE = _box("ToolboxPart3.stl", 0.425, 0.120, 0.017)
SCREW = PartGeometry(None, (0.0, -0.004, -0.004), (0.035, 0.004, 0.004))
SCREWDRIVER = PartGeometry(None, (0.0, -0.016, -0.016), (0.22, 0.016, 0.016))
DRAWER_FRAME = _box(None, 0.40, 0.36, 0.20)
DRAWER = _box(None, 0.38, 0.32, 0.16)
LID_BOX = _box(None, 0.30, 0.20, 0.12)
LID = PartGeometry(None, (-0.15, 0.0, -0.005), (0.15, 0.20, 0.005))

#: Leg slots of the chair seat, metres, seat frame: the centres of the seat mesh's four
#: 52 mm square, 10 mm deep pockets (where the IROS 2015 corrected constraints put the
#: legs, within 2 mm), the leg's 9 mm tenon in the pocket, its shoulder on the seat's face.
CHAIR_SLOTS: dict[str, tuple[float, float, float]] = {
    "c1": (0.115, 0.001, 0.115),
    "c2": (-0.115, 0.001, 0.115),
    "c3": (0.115, 0.001, -0.115),
    "c4": (-0.115, 0.001, -0.115),
}
#: Where the chair's back sits in the seat frame, metres (fixed, symbol ``c5``): its
#: narrow end on the floor of the seat mesh's 241 × 31 mm groove, 9 mm deep.
CHAIR_BACK_SLOT = (0.0, -0.001, 0.1195)
#: Leg slots of the bench seat, metres, seat frame: the leg's end on the seat's face.
BENCH_SLOTS: dict[str, tuple[float, float, float]] = {
    "c1": (0.07, 0.020, 0.07),
    "c2": (-0.07, 0.020, 0.07),
    "c3": (0.07, 0.020, -0.07),
    "c4": (-0.07, 0.020, -0.07),
}

#: Sensor-to-mesh transforms of the 3rdHand scene files, ``[[x, y, z] mm, [w, x, y, z]]``.
MESH_TRANSFORMS: dict[str, list[list[float]]] = {
    "chair_seating.stl": [[0, 0, 0], [0, 0.707, 0.707, 0]],
    "chair_leg.stl": [[0, 280, 0], [0, -0.707, 0.707, 0]],
    "chair_back.stl": [[0, 335, -15], [0, 0, 0, -1]],
    "bench_sitting.stl": [[157.5, -20, -157.5], [0, 0, 0.70710678, 0.70710678]],
    "bench_leg.stl": [[-32.5, 0, -32.5], [0, 0, 0, 1]],
}
