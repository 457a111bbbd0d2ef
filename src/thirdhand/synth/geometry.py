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
- leg: origin at the screw end, ``x`` along the leg away from the seat.
- back: origin at the middle of its bottom edge, extending along ``−y``.
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

# Re-exported: the 3rdHand meshes' bounds, known to the task package.
from thirdhand.task.meshes import MESH_BOUNDS_MM as MESH_BOUNDS_MM


@dataclass(frozen=True)
class PartGeometry:
    """Shape of one kind of part, in its synthetic body frame.

    Attributes
    ----------
    mesh : str or None
        File name of the 3rdHand mesh (in ``meshes/``), None for synthetic-only parts.
    lo, hi : tuple of 3 floats
        Bounding box in the body frame, metres.
    """

    mesh: str | None
    lo: tuple[float, float, float]
    hi: tuple[float, float, float]

    @property
    def size(self) -> FloatArray:
        """Extent along x, y, z, metres, shape (3,)."""
        return np.subtract(self.hi, self.lo)

    def to_meta(self) -> dict[str, object]:
        """JSON-able description for ``Demonstration.meta``."""
        return {"mesh": self.mesh, "bbox_min_m": list(self.lo), "bbox_max_m": list(self.hi)}


def _box(mesh: str | None, sx: float, sy: float, sz: float) -> PartGeometry:
    return PartGeometry(mesh, (-sx / 2, -sy / 2, -sz / 2), (sx / 2, sy / 2, sz / 2))


CHAIR_SEAT = _box("chair_seating.stl", 0.300, 0.020, 0.300)
CHAIR_LEG = PartGeometry("chair_leg.stl", (0.0, -0.040, -0.040), (0.280, 0.040, 0.040))
CHAIR_BACK = PartGeometry("chair_back.stl", (-0.193, -0.420, -0.015), (0.193, 0.0, 0.015))
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

#: Leg slots of the chair seat, metres, seat frame (IROS 2015 corrected constraints).
CHAIR_SLOTS: dict[str, tuple[float, float, float]] = {
    "c1": (0.115, 0.005, 0.117),
    "c2": (-0.115, 0.005, 0.117),
    "c3": (0.115, 0.005, -0.117),
    "c4": (-0.115, 0.005, -0.117),
}
#: Where the chair's back sits in the seat frame, metres (fixed, symbol ``c5``).
CHAIR_BACK_SLOT = (0.0, 0.0, 0.12)
#: Leg slots of the bench seat, metres, seat frame.
BENCH_SLOTS: dict[str, tuple[float, float, float]] = {
    "c1": (0.07, -0.015, 0.07),
    "c2": (-0.07, -0.015, 0.07),
    "c3": (0.07, -0.015, -0.07),
    "c4": (-0.07, -0.015, -0.07),
}

#: Sensor-to-mesh transforms of the 3rdHand scene files, ``[[x, y, z] mm, [w, x, y, z]]``.
MESH_TRANSFORMS: dict[str, list[list[float]]] = {
    "chair_seating.stl": [[0, 0, 0], [0, 0.707, 0.707, 0]],
    "chair_leg.stl": [[0, 280, 0], [0, -0.707, 0.707, 0]],
    "chair_back.stl": [[0, 335, -15], [0, 0, 0, -1]],
    "bench_sitting.stl": [[157.5, -20, -157.5], [0, 0, 0.70710678, 0.70710678]],
    "bench_leg.stl": [[-32.5, 0, -32.5], [0, 0, 0, 1]],
}
