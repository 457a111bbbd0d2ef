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
import struct
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
#: Largest first message (Dask's handshake) read from a scheduler, bytes: a real one
#: is a few hundred bytes; a peer announcing more is not a Dask scheduler.
HANDSHAKE_MAX_BYTES = 2**16


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


def _recv_exactly(sock: socket.socket, n: int) -> bytes:
    """``n`` bytes from ``sock`` (its timeout applies to each receive); short: ``OSError``."""
    got = bytearray()
    while len(got) < n:
        chunk = sock.recv(n - len(got))
        if not chunk:
            raise ConnectionError("the peer closed the connection")
        got += chunk
    return bytes(got)


def check_handshake(message: bytes, *, limit: int = HANDSHAKE_MAX_BYTES) -> str | None:
    """What is wrong with the first bytes a Dask scheduler sends, or None.

    A Dask TCP message is a little-endian uint64 ``size``, then ``size`` bytes:
    a uint64 frame count and one uint64 length per frame, then the frames. Only
    the header is judged here (``message`` holds its first 8 bytes, or more).
    """
    if len(message) < 8:
        return "fewer than 8 bytes"
    (size,) = struct.unpack_from("<Q", message)
    if not 16 <= size <= limit:
        return f"its first message announces {size} bytes (a Dask handshake is 16 to {limit})"
    if len(message) >= 16:
        (n_frames,) = struct.unpack_from("<Q", message, 8)
        if not 1 <= n_frames <= 64 or 8 + 8 * n_frames > size:
            return f"its first message announces {n_frames} frames"
        if len(message) >= 16 + 8 * n_frames:
            lengths = struct.unpack_from(f"<{n_frames}Q", message, 16)
            if 8 + 8 * n_frames + sum(lengths) > limit:
                return f"its first message's frames hold {sum(lengths)} bytes"
    return None


def probe_scheduler(host: str, port: int, *, timeout: float = CONNECT_TIMEOUT_S) -> str | None:
    """Connect to ``host:port`` and judge the peer's first message; None for a Dask scheduler.

    Every receive waits at most ``timeout`` seconds and at most
    :data:`HANDSHAKE_MAX_BYTES` are read, so a silent peer or one that streams
    bytes cannot hang the command or size an allocation.

    Returns
    -------
    str or None
        Why the peer is not a Dask scheduler, in a few words.

    Raises
    ------
    OSError
        The connection was refused or could not be made within ``timeout``.
    """
    with socket.create_connection((host, port), timeout=timeout) as sock:
        sock.settimeout(timeout)
        try:
            head = _recv_exactly(sock, 16)
            problem = check_handshake(head)
            if problem is None:
                (size,) = struct.unpack_from("<Q", head)
                (n_frames,) = struct.unpack_from("<Q", head, 8)
                lengths = _recv_exactly(sock, 8 * n_frames)
                problem = check_handshake(head + lengths)
                if problem is None:
                    _recv_exactly(sock, size - 8 - 8 * n_frames)
        except TimeoutError:
            return f"no Dask handshake within {timeout:g} s"
        except ConnectionError as exc:
            return f"no Dask handshake ({exc})"
    return problem


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
    try:  # a bounded probe first: a refused, silent or foreign peer fails fast, never hangs
        problem = probe_scheduler(host, port)
    except OSError as exc:
        raise OptionError(
            f"{option} {address}: no Dask scheduler answers there "
            f"({exc.strerror or type(exc).__name__}); start one with 'dask scheduler' "
            "and workers with 'dask worker ADDRESS' (docs/how-to/cluster.md)"
        ) from None
    if problem is not None and problem.startswith("no Dask handshake"):
        raise OptionError(
            f"{option} {address}: no Dask scheduler answers there within "
            f"{CONNECT_TIMEOUT_S:g} s ({problem})"
        )
    if problem is not None:
        raise OptionError(f"{option} {address}: not a Dask scheduler: {problem}")
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


def _local_map(fn: Callable[[T], R], work: list[T], jobs: int, method: str) -> Iterator[R]:
    """``fn`` over ``work`` in ``jobs`` worker processes (``fork`` or ``spawn``), in order."""
    pool = multiprocessing.get_context(method).Pool(jobs, initializer=_worker_signals)
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
    spawn: bool = False,
) -> Iterator[R]:
    """``fn(item)`` for every item, in order (see the module documentation).

    ``spawn``: local workers start as fresh interpreters instead of forks of this
    process, for units that open an OpenGL context (a fork inherits this
    process's, broken).

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
        yield from _local_map(fn, work, jobs, "spawn" if spawn else "fork")
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
