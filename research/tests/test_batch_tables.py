"""The research tables on a Dask cluster equal the serial ones."""

from __future__ import annotations

import json
import socket
from pathlib import Path

import pytest

from research.tests.helpers import call

distributed = pytest.importorskip("distributed")

#: Seeds per row of the compared ``irl noise`` tables: 8 rows x 2 seeds =
#: 16 trials of ~5 s each, run twice (serial, then on the cluster).
RUNS = 2


@pytest.mark.slow
def test_irl_noise_table_on_two_workers_equals_serial(
    cluster: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    serial, dask = tmp_path / "serial.json", tmp_path / "dask.json"
    args = ["irl", "noise", "--runs", str(RUNS)]
    rc, out_serial, err = call(capsys, *args, "--json", str(serial))
    assert rc == 0, err
    rc, out_dask, err = call(capsys, *args, "--json", str(dask), "--scheduler", cluster)
    assert rc == 0, err
    a, b = json.loads(serial.read_text()), json.loads(dask.read_text())
    assert a == b  # every mean and standard error, bit for bit
    assert a["runs"] == RUNS and len(a["rows"]) == 8
    table = [line for line in out_serial.splitlines() if "noise" in line and "%" in line]
    assert table and table == [
        line for line in out_dask.splitlines() if "noise" in line and "%" in line
    ]


def test_unreachable_scheduler_is_one_error_nothing_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with socket.socket() as s:  # a free port: bound, then closed, nobody listens
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    target = tmp_path / "t.json"
    rc, _, err = call(
        capsys, "irl", "noise", "--runs", "2", "--json", str(target),
        "--scheduler", f"tcp://127.0.0.1:{port}",
    )  # fmt: skip
    assert rc == 1
    assert err.count("\n") == 1 and "no Dask scheduler answers" in err
    assert not target.exists()


def test_experiment_units_on_the_cluster_give_the_serial_table(cluster: str) -> None:
    """``python -m research experiment corrections --scheduler``: same rows as serially."""
    from research.plan_accuracy import corrections_table

    kw = {"scenes": ("bench",), "seeds": [0, 1], "scale": None}
    assert corrections_table(**kw, scheduler=cluster) == corrections_table(**kw)  # type: ignore[arg-type]
