"""Shared fixtures of ``tests/`` and ``research/tests/``: the real recordings in
``../shared/data``, seeded generators, and a local Dask cluster."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, settings

from thirdhand.simulate.video import choose_backend

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

# MuJoCo picks its OpenGL back end once, when it is first imported: a test worker that
# imports it for physics before a test renders would otherwise have no offscreen renderer.
choose_backend()

ROOT = Path(__file__).resolve().parent
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


@pytest.fixture(scope="module")
def cluster() -> Iterator[str]:
    """Address of a ``dask scheduler`` with two single-threaded ``dask worker`` processes.

    The workers (and the scheduler, which unpickles the graph) import the test modules'
    helpers and the ``research`` package by name, as they would thirdhand's own functions.
    """
    pytest.importorskip("distributed")
    from thirdhand.batch import dask_processes

    path = os.pathsep.join([str(ROOT / "tests"), str(ROOT), os.environ.get("PYTHONPATH", "")])
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "PYTHONPATH": path}
    with dask_processes(2, env=env, timeout=120) as address:
        yield address
