"""Batch work on Dask: a real scheduler and two workers started here, same table as serial.

The scheduler and workers are separate processes (``python -m dask scheduler`` /
``dask worker``) on the loopback interface, as a user would start them; the
trials are seeded by their own settings, so the Dask run's table must equal the
serial one exactly.
"""

from __future__ import annotations

import socket
import time
from pathlib import Path

import pytest

from cli_helpers import call
from thirdhand.batch import CONNECT_TIMEOUT_S, check_scheduler, parallel_map
from thirdhand.errors import OptionError

distributed = pytest.importorskip("distributed")


def _square(x: int) -> int:
    return x * x


def _fail_on_three(x: int) -> int:
    if x == 3:
        raise ValueError("three is bad")
    return x


def test_parallel_map_in_order_on_the_cluster(cluster: str) -> None:
    assert list(parallel_map(_square, range(20), scheduler=cluster)) == [x * x for x in range(20)]


def test_a_failing_unit_is_one_error(cluster: str) -> None:
    from thirdhand.batch import BatchError

    with pytest.raises(BatchError, match="unit 3 of 5 failed on a Dask worker: ValueError"):
        list(parallel_map(_fail_on_three, range(5), scheduler=cluster))


def test_silent_port_times_out_instead_of_hanging() -> None:
    """A port that accepts TCP but never speaks Dask: one error after the connect timeout."""
    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen(8)
        port = server.getsockname()[1]
        start = time.monotonic()
        with pytest.raises(OptionError, match="no Dask scheduler answers there within"):
            list(parallel_map(_square, [1, 2], scheduler=f"tcp://127.0.0.1:{port}"))
        assert time.monotonic() - start < 20 * CONNECT_TIMEOUT_S  # bounded, not a hang


@pytest.mark.parametrize("bad", ["foo:bar", "http://x:1", "tcp://:80", "tcp://h:0", "h:70000"])
def test_bad_scheduler_addresses(bad: str) -> None:
    with pytest.raises(OptionError, match="expected tcp://HOST:PORT"):
        check_scheduler(bad)


def test_serial_and_process_maps_keep_order() -> None:
    assert list(parallel_map(_square, range(6))) == [0, 1, 4, 9, 16, 25]
    assert list(parallel_map(_square, range(6), jobs=2)) == [0, 1, 4, 9, 16, 25]


def test_learn_units_on_the_cluster_equal_serial(cluster: str) -> None:
    """``learn --scheduler``'s unit (segment + detect one recording) gives the serial results."""
    from thirdhand.constraints.detect import detect_constraints
    from thirdhand.learn.recordings import RecordingUnit, recording_stages
    from thirdhand.segment import segment_demonstration
    from thirdhand.synth import make_scene

    demos = [make_scene("drawer", seed=s, sensor=None).slice(0.0, 4.0) for s in (1, 2)]
    serial = [segment_demonstration(d) for d in demos]
    units = [RecordingUnit(d, f"d{k}", True) for k, d in enumerate(demos)]
    remote = list(parallel_map(recording_stages, units, scheduler=cluster))
    assert [r.phases.to_dict() for r in remote] == [ph.to_dict() for ph in serial]  # type: ignore[union-attr]
    for r, d, k in zip(remote, demos, range(2), strict=True):
        det = r.detection
        assert det is not None
        local = detect_constraints(d, phases=r.phases, demo_name=f"d{k}")
        assert [(i.parent, i.child, i.type, i.start) for i in det.instances] == [
            (i.parent, i.child, i.type, i.start) for i in local.instances
        ]


def test_local_cluster_of_two_workers() -> None:
    """``--scheduler local``: a LocalCluster of --jobs processes, started and closed here."""
    assert list(parallel_map(abs, [-1, -2, 3, -4], scheduler="local", jobs=2)) == [1, 2, 3, 4]


def test_segment_batch_on_the_cluster_writes_the_serial_files(
    cluster: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``segment batch --scheduler``: the files equal the serial run's, byte for byte."""
    from thirdhand import io
    from thirdhand.synth import make_scene

    recs = tmp_path / "recs"
    recs.mkdir()
    for s in (1, 2):
        io.save(make_scene("drawer", seed=s, sensor=None).slice(0.0, 4.0), recs / f"d{s}.parquet")
    rc, _, err = call(capsys, "segment", "batch", str(recs), "-o", str(tmp_path / "serial"))
    assert rc == 0, err
    rc, _, err = call(
        capsys, "segment", "batch", str(recs), "-o", str(tmp_path / "dask"), "--scheduler", cluster
    )
    assert rc == 0, err
    for name in ("d1.phases.json", "d2.phases.json"):
        assert (tmp_path / "dask" / name).read_bytes() == (tmp_path / "serial" / name).read_bytes()
