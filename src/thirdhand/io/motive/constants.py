"""Constants and array aliases shared by the Motive CSV reader and writer."""

from __future__ import annotations

#: Length unit (lower case, as written in the header or abbreviated) -> units per metre.
LENGTH_UNITS: dict[str, float] = {
    "meters": 1.0,
    "metres": 1.0,
    "m": 1.0,
    "centimeters": 100.0,
    "centimetres": 100.0,
    "cm": 100.0,
    "millimeters": 1000.0,
    "millimetres": 1000.0,
    "mm": 1000.0,
}
#: Asset types Motive writes in the ``Type`` row (used to recognise an unlabelled Type row).
ASSET_TYPES = frozenset(
    {
        "Rigid Body",
        "Rigid Body Marker",
        "Marker",
        "Bone",
        "Bone Marker",
        "Skeleton",
        "Trained Markerset",
        "Trained Markerset Marker",
        "Force Plate",
    }
)

_MAGIC = "Format Version"


#: First-line key holding what a Motive export cannot state (body kinds, labels),
#: as JSON; written by thirdhand, read back by :func:`~thirdhand.io.motive.read`.
EXTRA_KEY = "thirdhand"
EXTRA_FORMAT = "thirdhand.motive-extra/1"
