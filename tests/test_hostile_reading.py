"""One reading policy for every file thirdhand opens (``thirdhand.readlimits``).

A regular file (a device, FIFO or folder is named as such, never "no such
file"), a size limit for its kind, bounded JSON nesting, keys given once in a
file a person edits, and a bounded network handshake for ``--scheduler``.
Each reader class: runs, meshes, skill libraries, scene files, config files.
"""

from __future__ import annotations

import os
import socket
import struct
import threading
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from cli_helpers import call
from thirdhand.errors import FormatError, OptionError, ThirdhandError
from thirdhand.readlimits import (
    loads_json,
    open_input,
    read_input,
    read_json,
    sniff_bytes,
)

DEEP = "[" * 5000 + "]" * 5000


@pytest.fixture
def hostile(tmp_path: Path) -> dict[str, Path]:
    """Paths that are no regular file, and a deep JSON document."""
    fifo = tmp_path / "fifo.json"
    os.mkfifo(fifo)
    deep = tmp_path / "deep.json"
    deep.write_text(DEEP)
    dev = tmp_path / "zero.json"
    os.symlink("/dev/zero", dev)
    folder = tmp_path / "folder.json"
    folder.mkdir()
    return {"a FIFO": fifo, "a device": dev, "a folder": folder, "deep": deep}


def _kind_message(kind: str) -> str:
    return {"a FIFO": "is a FIFO", "a device": "is a device", "a folder": "is a folder"}[kind]


READERS: dict[str, Callable[[Path], object]] = {}


def _reader(name: str) -> Callable[[Callable[[Path], object]], Callable[[Path], object]]:
    def deco(fn: Callable[[Path], object]) -> Callable[[Path], object]:
        READERS[name] = fn
        return fn

    return deco


@_reader("run")
def _run(p: Path) -> object:
    from thirdhand.export.ros2 import read_execution

    return read_execution(p)


@_reader("trajectory")
def _trajectory(p: Path) -> object:
    from thirdhand.execute.record import read_trajectory

    return read_trajectory(p)


@_reader("mesh")
def _mesh(p: Path) -> object:
    from thirdhand.io.stl import read_stl

    return read_stl(p)


@_reader("skill library")
def _library(p: Path) -> object:
    from thirdhand.primitives.skill_library import read_skill_library

    return read_skill_library(p)


@_reader("scene file")
def _scene(p: Path) -> object:
    from thirdhand.task.scene_file import read_scene

    return read_scene(p)


@_reader("config file")
def _config(p: Path) -> object:
    from thirdhand.config import read_config

    return read_config(p)


@_reader("input hash")
def _hash(p: Path) -> object:
    from thirdhand.task.model import InputFile

    return InputFile.from_path(p)


@_reader("review session")
def _session(p: Path) -> object:
    from thirdhand.review.session import ReviewSession

    return ReviewSession.open(p)


@pytest.mark.parametrize("reader", sorted(READERS))
@pytest.mark.parametrize("kind", ["a FIFO", "a device", "a folder"])
def test_no_regular_file_is_named_as_such(reader: str, kind: str, hostile: dict[str, Path]) -> None:
    """A FIFO does not hang, /dev/zero does not grow, a folder is not "no such file"."""
    if reader == "input hash" and kind == "a folder":
        pytest.skip("a recording may be a folder: every file under it is hashed")
    with pytest.raises(ThirdhandError) as info:
        READERS[reader](hostile[kind])
    message = str(info.value)
    assert "\n" not in message
    assert _kind_message(kind) in message, message
    assert "no such file" not in message


@pytest.mark.parametrize(
    "reader", ["run", "trajectory", "skill library", "scene file", "review session"]
)
def test_deep_json_is_one_line(reader: str, hostile: dict[str, Path]) -> None:
    with pytest.raises(ThirdhandError, match="nested 5000 levels deep"):
        READERS[reader](hostile["deep"])


def test_config_deep_json(tmp_path: Path) -> None:
    p = tmp_path / "c.json"
    p.write_text('{"synth": ' + DEEP + "}")
    with pytest.raises(OptionError, match="nested"):
        READERS["config file"](p)


@pytest.mark.parametrize(
    ("suffix", "text"),
    [
        (".toml", "[synth]\nhead = true\nhead = false\n"),
        (".toml", "[synth]\nhead = true\n[synth]\npointing = 2\n"),
        (".yaml", "synth:\n  head: true\n  head: false\n"),
        (".yaml", "synth:\n  head: true\nsynth:\n  pointing: 2\n"),
        (".json", '{"synth": {"head": true, "head": false}}'),
        (".json", '{"synth": {"head": true}, "synth": {"pointing": 2}}'),
    ],
)
def test_config_keys_given_twice_are_refused(
    suffix: str, text: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Not last-wins: the file says two things and neither is chosen silently."""
    p = tmp_path / f"c{suffix}"
    p.write_text(text)
    rc, _out, err = call(
        capsys, "synth", "chair", "-o", str(tmp_path / "s.parquet"), "--config", str(p)
    )
    assert rc == 1
    assert err.count("\n") == 1 and str(p) in err, err
    assert "twice" in err or "Cannot declare" in err or "overwrite" in err, err
    assert not (tmp_path / "s.parquet").exists()


def test_a_run_with_a_key_twice_or_nan_is_refused(tmp_path: Path) -> None:
    p = tmp_path / "run.json"
    p.write_text('{"schema": "x", "schema": "y"}')
    with pytest.raises(FormatError, match="twice"):
        READERS["run"](p)
    p.write_text('{"t": [NaN]}')
    with pytest.raises(FormatError, match="NaN is not a JSON number"):
        READERS["run"](p)


def test_size_limits_by_kind(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A file over its kind's limit is refused before it is read (sparse: no disk used)."""
    import thirdhand.io.stl as stl

    big = tmp_path / "big.stl"
    with open(big, "wb") as fh:
        fh.truncate(6 * 2**30)  # the 6 GB mesh a task might name
    with pytest.raises(FormatError, match=r"is 6144 MiB; a mesh .STL. file of more than 256 MiB"):
        stl.read_stl(big)
    run = tmp_path / "run.json"
    with open(run, "wb") as fh:
        fh.truncate(2**30)
    with pytest.raises(FormatError, match=r"run .execute --record. of more than"):
        READERS["run"](run)
    conf = tmp_path / "c.toml"
    with open(conf, "wb") as fh:
        fh.truncate(2 * 2**20)
    with pytest.raises(OptionError, match="settings file of more than 1 MiB"):
        READERS["config file"](conf)


def test_mesh_with_nan_vertices_is_refused_before_any_solver(tmp_path: Path) -> None:
    """Non-finite vertices never reach coal or pinocchio (a C++ "eigen: too many iterations")."""
    import numpy as np

    from thirdhand.io.stl import read_stl

    ascii_ = tmp_path / "nan.stl"
    ascii_.write_text(
        "solid x\nfacet normal 0 0 1\nouter loop\nvertex nan 0 0\nvertex 1 0 0\n"
        "vertex 0 1 0\nendloop\nendfacet\nendsolid x\n"
    )
    with pytest.raises(FormatError, match="1 of 1 triangles have a vertex that is not a finite"):
        read_stl(ascii_)
    tri = np.zeros(2, dtype=[("n", "<f4", (3,)), ("v", "<f4", (3, 3)), ("a", "<u2")])
    tri["v"][1, 2, 0] = np.inf
    binary = tmp_path / "inf.stl"
    binary.write_bytes(b"\0" * 80 + struct.pack("<I", 2) + tri.tobytes())
    with pytest.raises(FormatError, match="the first is triangle 1"):
        read_stl(binary)


def test_open_input_and_sniff(hostile: dict[str, Path], tmp_path: Path) -> None:
    f = tmp_path / "a.bin"
    f.write_bytes(b"PAR1xyz")
    with open_input(f) as fh:
        assert fh.read() == b"PAR1xyz"
    assert sniff_bytes(f, 4) == b"PAR1" and sniff_bytes(f, 2, offset=4) == b"xy"
    for kind in ("a FIFO", "a device", "a folder"):
        assert sniff_bytes(hostile[kind], 4) == b""
        with pytest.raises(FormatError, match=_kind_message(kind)), open_input(hostile[kind]):
            pass
    assert sniff_bytes(tmp_path / "missing", 4) == b""


def test_strict_json() -> None:
    def err(m: str) -> FormatError:
        return FormatError("x.json", m)

    assert loads_json('{"a": 1, "b": NaN}', error=err)["a"] == 1
    with pytest.raises(FormatError, match="'a' is given twice"):
        loads_json('{"a": 1, "a": 2}', error=err, strict=True)
    with pytest.raises(FormatError, match="Infinity is not a JSON number"):
        loads_json('{"a": Infinity}', error=err, strict=True)


def test_read_json_and_read_input(tmp_path: Path) -> None:
    p = tmp_path / "a.json"
    p.write_text('{"k": [1, 2]}')
    assert read_json(p) == {"k": [1, 2]}
    with pytest.raises(FormatError, match="a thing of more than"):
        read_input(p, what="thing", limit=4)
    with pytest.raises(FormatError, match="no such file"):
        read_json(tmp_path / "missing.json")


# --scheduler: a peer that is not Dask -------------------------------------------------


@pytest.fixture
def peer() -> Iterator[Callable[[bytes | None], int]]:
    """A TCP server on the loopback that sends ``payload`` to each client (None: silent)."""
    servers: list[socket.socket] = []
    stop = threading.Event()

    def start(payload: bytes | None) -> int:
        srv = socket.create_server(("127.0.0.1", 0))
        srv.settimeout(0.2)
        servers.append(srv)

        def serve() -> None:
            while not stop.is_set():
                try:
                    conn, _ = srv.accept()
                except OSError:
                    continue
                if payload is not None:
                    try:
                        conn.sendall(payload)
                    except OSError:
                        pass
                stop.wait(3.0)
                conn.close()

        threading.Thread(target=serve, daemon=True).start()
        return int(srv.getsockname()[1])

    yield start
    stop.set()
    for s in servers:
        s.close()


def _dask_message(frames: list[bytes]) -> bytes:
    body = struct.pack("<Q", len(frames)) + struct.pack(f"<{len(frames)}Q", *map(len, frames))
    body += b"".join(frames)
    return struct.pack("<Q", len(body)) + body


@pytest.mark.parametrize(
    ("payload", "why"),
    [
        (
            b"HTTP/1.1 200 OK\r\nContent-Length: 5\r\n\r\nhello",
            "announces 3543824036068086856 bytes",
        ),
        (b"SSH-2.0-OpenSSH_9.6\r\n", "announces"),
        (struct.pack("<Q", 2**40) + b"\0" * 8, "announces 1099511627776 bytes"),
        (struct.pack("<QQ", 64, 10**9), "announces 1000000000 frames"),
        (struct.pack("<QQQ", 64, 1, 10**12), "frames hold 1000000000000 bytes"),
        (None, "no Dask handshake within 0.5 s"),
        (b"\x01\x02", "no Dask handshake"),
    ],
)
def test_a_peer_that_is_not_dask_is_refused(
    payload: bytes | None, why: str, peer: Callable[[bytes | None], int]
) -> None:
    from thirdhand.batch import probe_scheduler

    port = peer(payload)
    problem = probe_scheduler("127.0.0.1", port, timeout=0.5)
    assert problem is not None and why in problem, problem


def test_a_dask_shaped_handshake_passes(peer: Callable[[bytes | None], int]) -> None:
    from thirdhand.batch import probe_scheduler

    port = peer(_dask_message([b"\x80" * 40, b"x" * 100]))
    assert probe_scheduler("127.0.0.1", port, timeout=2.0) is None


def test_scheduler_option_is_one_line(
    peer: Callable[[bytes | None], int], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("distributed")
    port = peer(b"HTTP/1.1 400 Bad Request\r\n\r\n")
    rec = tmp_path / "a.parquet"
    from thirdhand import io
    from thirdhand.synth import make_scene

    io.save(make_scene("chair", seed=0), rec)
    rc, _out, err = call(
        capsys, "segment", "batch", str(rec), "-o", str(tmp_path / "o"),
        "--scheduler", f"tcp://127.0.0.1:{port}",
    )  # fmt: skip
    assert rc == 1 and err.count("\n") == 1, err
    assert "not a Dask scheduler" in err, err
