"""Shared fixtures: the real recordings in ``../shared/data`` and seeded generators."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, settings

# Shared, loaded machines: no per-example deadline, no "too slow" health check, and a
# fixed example sequence so a run is reproducible.
settings.register_profile(
    "thirdhand",
    deadline=None,
    derandomize=True,
    suppress_health_check=[
        HealthCheck.too_slow,
        HealthCheck.data_too_large,
        HealthCheck.filter_too_much,
    ],
)
settings.load_profile("thirdhand")

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("THIRDHAND_DATA", ROOT.parent / "shared" / "data"))


@pytest.fixture
def shared_data() -> Path:
    """The real-data folder; skips the test with a clear message when it is absent."""
    if not DATA.is_dir():
        pytest.skip(f"real recordings not found at {DATA} (set THIRDHAND_DATA to their folder)")
    return DATA


@pytest.fixture
def rng() -> np.random.Generator:
    """A seeded generator, the same for every test."""
    return np.random.default_rng(20261122)
