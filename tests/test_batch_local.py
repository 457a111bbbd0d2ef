"""Local worker processes of ``thirdhand.batch.parallel_map``: order, errors, and stopping."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from thirdhand.batch import parallel_map


def _square(x: int) -> int:
    return x * x


def _fail_on_three(x: int) -> int:
    if x == 3:
        raise ValueError(f"unit {x} is bad")
    return x


def test_local_workers_keep_the_items_order() -> None:
    items = list(range(23))
    assert list(parallel_map(_square, items, jobs=2)) == [x * x for x in items]
    assert list(parallel_map(_square, items, jobs=1)) == [x * x for x in items]


def test_a_failing_unit_raises_in_the_parent() -> None:
    with pytest.raises(ValueError, match="unit 3 is bad"):
        list(parallel_map(_fail_on_three, range(6), jobs=2))


def _children(pid: int) -> list[int]:
    """Live processes whose parent is ``pid`` (from /proc)."""
    out = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        # pid (comm) state ppid ...: comm may hold spaces, so split after the last ')'.
        fields = stat.rsplit(")", 1)[1].split()
        if int(fields[1]) == pid and fields[0] != "Z":
            out.append(int(entry.name))
    return out


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_stops_the_parent_and_its_workers(signum: int) -> None:
    # Before the fix the workers inherited the CLI's SIGTERM handler, caught the
    # exception as a unit's result, and the parent waited for every pending unit:
    # `kill` of `irl experiment --jobs 2` never ended it.
    script = textwrap.dedent(
        """
        import signal, sys, time
        from thirdhand.batch import parallel_map
        from thirdhand.cli import Terminated, _on_signal

        signal.signal(signal.SIGTERM, _on_signal)
        signal.signal(signal.SIGINT, signal.default_int_handler)

        def slow(x):
            time.sleep(300)
            return x

        print("ready", flush=True)
        try:
            list(parallel_map(slow, range(8), jobs=2))
        except Terminated:
            sys.exit(143)
        except KeyboardInterrupt:
            sys.exit(130)
        """
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", script],
        stdout=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == "ready"
        workers: list[int] = []
        for _ in range(600):  # the two workers appear (bounded wait, not a timing check)
            workers = _children(proc.pid)
            if len(workers) >= 2:
                break
            time.sleep(0.1)
        assert len(workers) >= 2, workers
        time.sleep(0.5)  # the workers are inside their units
        os.kill(proc.pid, signum)
        # A hang check: the units sleep 300 s each, 8 units on 2 workers.
        rc = proc.wait(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert rc == (143 if signum == signal.SIGTERM else 130)
    for _ in range(100):
        if not any(_alive(w) for w in workers):
            break
        time.sleep(0.1)
    assert not any(_alive(w) for w in workers), "a worker outlived its parent"
