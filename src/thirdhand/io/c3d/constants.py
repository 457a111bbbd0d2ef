"""Constants and array aliases shared by the C3D reader and writer."""

from __future__ import annotations

FORMAT_VERSION = "thirdhand.c3d/1"
#: Parameter group holding the JSON description written by :func:`write`.
GROUP = "THIRDHAND"
#: Most frames ``ezc3d`` reads back (the C3D header's 16-bit frame numbers).
MAX_FRAMES = 65535
#: Length unit names of ``POINT:UNITS`` -> metres per unit.
UNIT_SCALES: dict[str, float] = {
    "mm": 1e-3,
    "millimeter": 1e-3,
    "millimeters": 1e-3,
    "millimetre": 1e-3,
    "millimetres": 1e-3,
    "cm": 1e-2,
    "m": 1.0,
    "meter": 1.0,
    "meters": 1.0,
    "metre": 1.0,
    "metres": 1.0,
    "in": 0.0254,
    "inch": 0.0254,
    "inches": 0.0254,
}
MIN_CLUSTER = 3
_MAGIC = 0x50
_PROCESSORS = {84: "<", 85: "<", 86: ">"}  # Intel, DEC, MIPS
