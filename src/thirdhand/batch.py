"""Independent units of work run serially, in local processes, or as Dask tasks on a cluster.

``parallel_map(fn, items, jobs=N, scheduler=ADDRESS)`` yields ``fn(item)`` for
every item, in the items' order, whatever ran them:

- ``scheduler=None, jobs=1``: in this process;
- ``scheduler=None, jobs=N``: ``N`` local worker processes;
- ``scheduler="local"``: a Dask ``LocalCluster`` of ``jobs`` single-threaded
  worker processes (``jobs=1``: one per core);
- ``scheduler="tcp://HOST:PORT"``: an existing Dask cluster (``dask scheduler``
  and ``dask worker`` processes; see ``docs/how-to/cluster.md``). The workers must run
  the same thirdhand and Python packages.

``fn`` must be a module-level function and every unit must be seeded by its own
item, so the results do not depend on where or in which order units run. Dask is
imported only here, and only when a scheduler is asked for (the ``dask`` extra).

:func:`dask_processes` starts a scheduler and workers on the loopback interface as
separate processes, the way a user starts them by hand (``dask scheduler``, ``dask
worker``): for scripts and tests that need a real cluster.

Stopping: local workers ignore SIGINT and take SIGTERM's default action, so the
signals stop the parent alone (a terminal's Ctrl-C reaches the whole process
group); whatever ends the parent's loop early (Ctrl-C, SIGTERM, a failed unit)
terminates the workers at once instead of waiting for their pending units.
"""

from __future__ import annotations

import asyncio
import json
import multiprocessing
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TypeVar
from urllib.parse import urlsplit

from thirdhand.errors import OptionError, ThirdhandError

T = TypeVar("T")
R = TypeVar("R")

#: Seconds to wait for a scheduler to accept a connection before giving up.
CONNECT_TIMEOUT_S = 5.0


class BatchError(ThirdhandError, RuntimeError):
    """A unit of work failed on a Dask worker (the message names the unit and the error)."""


def check_scheduler(address: str, option: str = "--scheduler") -> tuple[str, int] | None:
    """``(host, port)`` of a ``tcp://HOST:PORT`` (or ``HOST:PORT``) address; None for ``local``.

    Raises
    ------
    OptionError
        Any other form.
    """
    if address == "local":
        return None
    text = address if "://" in address else f"tcp://{address}"
    parts = urlsplit(text)
    try:
        port = parts.port
    except ValueError:
        port = None
    if parts.scheme != "tcp" or not parts.hostname or port is None or not 0 < port < 65536:
        raise OptionError(
            f"{option} {address!r}: expected tcp://HOST:PORT (a 'dask scheduler' address) "
            "or 'local'"
        )
    return parts.hostname, port


async def _handshake(url: str) -> None:
    """Open and close one Dask comm to ``url`` (raises on a refused, silent or foreign peer)."""
    from distributed.comm import connect

    comm = await connect(url, timeout=CONNECT_TIMEOUT_S)
    await comm.close()


def _client(address: str, jobs: int, option: str) -> tuple[Any, Any]:
    """A connected ``distributed.Client`` and the LocalCluster it owns (or None)."""
    target = check_scheduler(address, option)
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise OptionError(f"{option} needs the dask extra: pip install 'thirdhand[dask]'") from None
    if target is None:
        n = jobs if jobs > 1 else (os.cpu_count() or 1)
        cluster = LocalCluster(
            n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0"
        )
        return Client(cluster), cluster
    host, port = target
    try:  # a plain TCP probe first: a refused or silent port fails fast, never hangs
        socket.create_connection((host, port), timeout=CONNECT_TIMEOUT_S).close()
    except OSError as exc:
        raise OptionError(
            f"{option} {address}: no Dask scheduler answers there "
            f"({exc.strerror or type(exc).__name__}); start one with 'dask scheduler' "
            "and workers with 'dask worker ADDRESS' (docs/how-to/cluster.md)"
        ) from None
    url = address if "://" in address else f"tcp://{address}"
    try:  # then Dask's own handshake, bounded: Client() alone waits forever on a silent peer
        asyncio.run(asyncio.wait_for(_handshake(url), 2 * CONNECT_TIMEOUT_S))
    except (OSError, TimeoutError) as exc:
        raise OptionError(
            f"{option} {address}: no Dask scheduler answers there within "
            f"{CONNECT_TIMEOUT_S:g} s ({' '.join(str(exc).split()) or 'no handshake'})"
        ) from None
    try:
        client = Client(
            url,
            timeout=CONNECT_TIMEOUT_S,
            set_as_default=False,
        )
    except (OSError, TimeoutError) as exc:
        raise OptionError(
            f"{option} {address}: no Dask scheduler answers there within "
            f"{CONNECT_TIMEOUT_S:g} s ({' '.join(str(exc).split())})"
        ) from None
    return client, None


def _worker_signals() -> None:
    """Pool initializer: the parent alone answers Ctrl-C and SIGTERM (module notes)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _local_map(fn: Callable[[T], R], work: list[T], jobs: int) -> Iterator[R]:
    """``fn`` over ``work`` in ``jobs`` forked worker processes, in order."""
    pool = multiprocessing.get_context("fork").Pool(jobs, initializer=_worker_signals)
    try:
        yield from pool.imap(fn, work)
        pool.close()
    finally:
        # Normal end: the workers are idle and exit; early end: kill them now.
        pool.terminate()
        pool.join()


def parallel_map(
    fn: Callable[[T], R],
    items: Iterable[T],
    *,
    jobs: int = 1,
    scheduler: str | None = None,
    option: str = "--scheduler",
) -> Iterator[R]:
    """``fn(item)`` for every item, in order (see the module documentation).

    Raises
    ------
    OptionError
        A bad or unreachable scheduler address, or the dask extra missing.
    BatchError
        A unit failed on a worker.
    """
    work = list(items)
    if scheduler is None:
        if jobs <= 1 or len(work) <= 1:
            yield from map(fn, work)
            return
        yield from _local_map(fn, work, jobs)
        return
    client, cluster = _client(scheduler, jobs, option)
    futures: list[Any] = []
    try:
        futures = client.map(fn, work, pure=False)
        for k, fut in enumerate(futures):
            try:
                result = fut.result()
            except (KeyboardInterrupt, SystemExit):
                raise
            except Exception as exc:
                raise BatchError(
                    f"unit {k} of {len(work)} failed on a Dask worker: "
                    f"{type(exc).__name__}: {' '.join(str(exc).split())}"
                ) from None
            yield result
    finally:
        if futures:
            client.cancel(futures)
        client.close()
        if cluster is not None:
            cluster.close()


@contextmanager
def dask_processes(
    workers: int = 2,
    *,
    env: Mapping[str, str] | None = None,
    timeout: float = 300.0,
) -> Iterator[str]:
    """A ``dask scheduler`` and ``workers`` single-threaded ``dask worker`` processes.

    Started on 127.0.0.1 with ``python -m dask`` (no dashboard, no nanny), as
    ``docs/how-to/cluster.md`` tells a user to start them; stopped (terminated, killed
    after 30 s) when the block ends, however it ends.

    Parameters
    ----------
    workers : int
        Number of worker processes, each with one thread.
    env : mapping, optional
        Environment of the processes (this process's by default). Workers unpickle
        the units' functions by module name, so their ``PYTHONPATH`` must reach them.
    timeout : float
        Seconds to wait for the scheduler and for every worker to join.

    Yields
    ------
    str
        The scheduler's ``tcp://127.0.0.1:PORT`` address.

    Raises
    ------
    BatchError
        The scheduler did not start, or the workers did not join, within ``timeout``.
    OptionError
        The dask extra is not installed.
    """
    try:
        from distributed import Client
    except ImportError:
        raise OptionError(
            "a Dask cluster needs the dask extra: pip install 'thirdhand[dask]'"
        ) from None
    procs: list[subprocess.Popen[bytes]] = []
    quiet: dict[str, Any] = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
    with tempfile.TemporaryDirectory(prefix="thirdhand-dask-") as tmp:
        info = Path(tmp) / "scheduler.json"
        run: dict[str, Any] = {**quiet, "cwd": tmp, "env": dict(env) if env is not None else None}
        try:
            procs.append(
                subprocess.Popen(
                    [sys.executable, "-m", "dask", "scheduler", "--host", "127.0.0.1",
                     "--port", "0", "--scheduler-file", str(info), "--no-dashboard"],
                    **run,
                )
            )  # fmt: skip
            deadline = time.monotonic() + timeout
            while not info.exists() or not info.read_text().strip():
                if procs[0].poll() is not None:
                    raise BatchError(
                        f"the dask scheduler exited at start (code {procs[0].returncode})"
                    )
                if time.monotonic() > deadline:
                    raise BatchError(f"the dask scheduler did not start within {timeout:g} s")
                time.sleep(0.2)
            address = str(json.loads(info.read_text())["address"])
            for _ in range(workers):
                procs.append(
                    subprocess.Popen(
                        [sys.executable, "-m", "dask", "worker", address, "--nthreads", "1",
                         "--nworkers", "1", "--no-nanny", "--host", "127.0.0.1",
                         "--no-dashboard"],
                        **run,
                    )
                )  # fmt: skip
            with Client(address, timeout=30) as client:
                try:
                    client.wait_for_workers(workers, timeout=timeout)
                except TimeoutError:
                    raise BatchError(
                        f"{workers} dask workers did not join {address} within {timeout:g} s"
                    ) from None
            yield address
        finally:
            for p in reversed(procs):
                p.terminate()
            for p in procs:
                try:
                    p.wait(timeout=30)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait()
