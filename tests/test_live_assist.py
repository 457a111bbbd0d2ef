"""The robot assist's grasp frame (the planning itself is the execution stage's, tested there)."""

from __future__ import annotations

import numpy as np
import pytest

from thirdhand import se3
from thirdhand.live.assist import _down_quat


@pytest.mark.parametrize("direction", [(1.0, 0.0), (0.0, -2.0), (-1.0, 1.0), (0.0, 0.0)])
def test_down_grasp_points_down_along_the_part(direction: tuple[float, float]) -> None:
    q = _down_quat(np.array(direction))
    assert np.linalg.norm(q) == pytest.approx(1.0)
    z = se3.quat_rotate(q, np.array([0.0, 0.0, 1.0]))
    x = se3.quat_rotate(q, np.array([1.0, 0.0, 0.0]))
    np.testing.assert_allclose(z, [0.0, 0.0, -1.0], atol=1e-12)
    d = np.array([*direction, 0.0])
    want = d / np.linalg.norm(d) if np.linalg.norm(d) > 0 else np.array([1.0, 0.0, 0.0])
    np.testing.assert_allclose(x, want, atol=1e-12)
