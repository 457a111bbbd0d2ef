"""Array type aliases shared by every module.

numpy arrays carry their dtype in the type; the shape, units and frame of each
array are stated in the docstring of the function that takes or returns it.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

#: float64 arrays: positions (metres), angles (radians), times (seconds), scores.
FloatArray = NDArray[np.float64]
#: int64 arrays: labels, sample indices, counts.
IntArray = NDArray[np.int64]
#: Platform index arrays, as ``np.flatnonzero`` and ``np.argsort`` return them.
IndexArray = NDArray[np.intp]
#: Boolean masks.
BoolArray = NDArray[np.bool_]

__all__ = ["BoolArray", "FloatArray", "IndexArray", "IntArray"]
