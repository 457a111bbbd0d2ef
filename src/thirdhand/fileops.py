"""The output policy of every command: nothing a user made is lost.

- :func:`check_output`: refuse to write over one of the command's inputs, and
  refuse an existing output unless the user passed ``--force``.
- :func:`atomic_output`: a context manager giving a path inside a fresh,
  uniquely named temporary folder beside the target (so concurrent writers never
  share a temporary name); once the writer is done the result is flushed to disk
  and renamed over the target in one step. A previous target is first kept as a
  numbered backup (``name.bak``, ``name.bak.1``, …; an existing backup, or any
  other file, is never replaced). A failed or short write (full disk, file-size
  limit) raises :class:`~thirdhand.errors.OutputError` and leaves the old target
  and nothing else behind.
- :func:`write_bytes` / :func:`write_text`: the same for bytes in memory.

The backup and the rename happen under an advisory lock on the target's folder
(POSIX ``flock``), so two processes replacing the same file one after the
other each back up what they replace: no version is lost, and a reader only
ever sees a complete old or a complete new file.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import os
import re
import shutil
import signal
import stat
import sys
import tempfile
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

from thirdhand.errors import OutputError

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows: no advisory folder lock
    fcntl = None  # type: ignore[assignment]

PathLike = str | os.PathLike[str]


def _same(a: Path, b: Path) -> bool:
    """True when ``a`` and ``b`` name the same file (same inode, or same resolved path)."""
    try:
        if a.exists() and b.exists():
            return os.path.samefile(a, b)
    except OSError:
        pass
    return a.resolve() == b.resolve()


def _inside(inner: Path, outer: Path) -> bool:
    try:
        inner.resolve().relative_to(outer.resolve())
    except ValueError:
        return False
    return True


#: Extensions of the files thirdhand writes: a folder with one of them is never
#: what a command means to write.
FILE_SUFFIXES = frozenset(
    {
        ".parquet",
        ".csv",
        ".c3d",
        ".bag",
        ".mcap",
        ".log",
        ".txt",
        ".json",
        ".rrd",
        ".png",
        ".pdf",
        ".svg",
        ".html",
        ".npz",
        ".npy",
        ".mp4",
        ".stl",
    }
)
#: Outputs :func:`check_output` found missing and no ``--force``: the atomic
#: rename must then create them exclusively (a concurrent writer that got there
#: first keeps its file; neither is moved to a backup).
_NEW_OUTPUTS: set[str] = set()
#: Outputs completed (renamed into place) since the command started, in order.
_COMPLETED: list[str] = []
#: How many :func:`atomic_output` blocks are open (an output written inside
#: another's temporary folder is a part of that one, not an output of its own).
_OPEN: list[int] = [0]


def _key(p: Path) -> str:
    return os.path.abspath(p)


def _special(mode: int) -> str | None:
    """The name of a file type thirdhand never writes or moves, or None."""
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "device"
    if stat.S_ISFIFO(mode):
        return "FIFO (named pipe)"
    if stat.S_ISSOCK(mode):
        return "socket"
    return None


def _stat(p: Path) -> os.stat_result | None:
    """``stat`` of ``p`` following links (a dangling link: the link itself); None if missing."""
    try:
        return os.stat(p)
    except OSError:
        try:
            return os.lstat(p)
        except OSError:
            return None


def thirdhand_folder(p: Path) -> bool:
    """True for a folder ``--force`` may move aside: empty, a recording or a dataset folder.

    thirdhand writes folders only as recordings (an MLR folder holding
    ``poses.dat`` and ``meta.kvg``, a ROS 2 bag holding ``metadata.yaml``) and
    LeRobot datasets (``meta/info.json``); any other folder is the user's and
    is never moved.
    """
    try:
        names = set(os.listdir(p))
    except OSError:
        return False
    return (
        not names
        or {"poses.dat", "meta.kvg"} <= names
        or "metadata.yaml" in names
        or (p / "meta" / "info.json").is_file()
    )


def check_path_shape(path: PathLike, *, what: str = "output") -> Path:
    """Refuse a path that cannot name an output file or folder; one line each.

    Empty, ``.``, ``..`` (or ending in them), ``-`` (thirdhand writes no
    recording or report to standard output, and a file named ``-`` is too easily
    taken for it), and a path whose parent is a file.
    """
    raw = os.fspath(path)
    p = Path(raw)
    if not raw.strip():
        raise OutputError(f"an empty {what} path: name a file")
    if p.name in ("", ".", "..") or raw.rstrip("/").endswith(("/.", "/..")):
        raise OutputError(
            f"{raw!r}: names a folder ('.' or '..'), not a file for the {what}; "
            "name a file inside it"
        )
    if p.name == "-":
        raise OutputError(
            f"{raw!r}: thirdhand writes no {what} to standard output, and a file named '-' "
            "is easily taken for it; name the file (for example out.json)"
        )
    for anc in p.parents:
        if os.path.lexists(anc):
            if not anc.is_dir():
                raise OutputError(f"{p}: {anc} is a file, not a folder")
            break
    return p


def check_distinct_inputs(paths: Iterable[PathLike], *, what: str = "input") -> None:
    """Refuse the same file or folder given twice (``rec``, ``./rec``, a link to it).

    Raises
    ------
    OutputError
        Naming both spellings.
    """
    seen: list[Path] = []
    for raw in paths:
        p = Path(raw)
        for k, q in enumerate(seen):
            if _same(p, q):
                raise OutputError(
                    f"{p} ({what} {len(seen) + 1}) is the same file as {what} {k + 1} ({q}); "
                    f"give each {what} once"
                )
        seen.append(p)


def check_outputs(
    outputs: Iterable[tuple[str, PathLike | None]],
    *,
    force: bool = False,
    inputs: Iterable[PathLike | None] = (),
    option: str = "--force",
) -> list[Path]:
    """Check every output of one command: each against the others, then :func:`check_output`.

    The one policy of a command that writes several files (``merge -o --report``,
    ``primitives library -o --plot``): two outputs naming the same file (the
    same spelling, ``./x``, a link to it, the same inode) would leave only the
    last one written, so they are refused before anything is read; then each
    output is checked against every input.

    Parameters
    ----------
    outputs : iterable of (str, path-like or None)
        Each output with the option that names it (``("--report", path)``); None
        (an output not asked for) is skipped.
    force, option
        As for :func:`check_output`.
    inputs : iterable of path-like or None
        The command's inputs (None skipped).

    Returns
    -------
    list of pathlib.Path
        The outputs given, in order.

    Raises
    ------
    OutputError
        Naming both options and the file, in one line.
    """
    named = [(name, Path(p)) for name, p in outputs if p is not None]
    for i, (name, p) in enumerate(named):
        for other, q in named[:i]:
            if _same(p, q):
                raise OutputError(
                    f"{name} {p} and {other} {q} name the same file; one would replace the "
                    "other: give each output its own file"
                )
    ins = [Path(p) for p in inputs if p is not None]
    for _name, p in named:
        check_output(p, force=force, inputs=ins, option=option)
    return [p for _name, p in named]


def check_output(
    path: PathLike,
    *,
    force: bool = False,
    inputs: Iterable[PathLike] = (),
    option: str = "--force",
) -> Path:
    """Check that ``path`` may be written; raise :class:`OutputError` if not.

    The one output-path policy of every command (see ``docs/reference/reliability.md``):
    the shape of the path (:func:`check_path_shape`), never one of the inputs,
    never a device, FIFO or socket, never a folder where a file is meant, and an
    existing output only with ``force``, which moves aside only a regular file
    or a folder thirdhand wrote (:func:`thirdhand_folder`). An output found
    missing without ``force`` is created exclusively by :func:`atomic_output`:
    a concurrent writer that created it meanwhile wins, and this one fails.

    Parameters
    ----------
    path : path-like
        The output (file or folder) a command is about to write.
    force : bool
        The user allowed replacing an existing output (it is then kept as a
        numbered backup by :func:`atomic_output`).
    inputs : iterable of path-like
        The command's inputs: the output may be none of them (compared by inode
        and by resolved path), lie inside none of them, nor contain one.
    option : str
        The option that allows replacing, for the message.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    p = check_path_shape(path)
    for raw in inputs:
        inp = Path(raw)
        if _same(p, inp):
            raise OutputError(f"{p}: the output is also an input ({inp}); write it to another path")
        if inp.is_dir() and _inside(p, inp):
            raise OutputError(f"{p}: the output lies inside the input folder {inp}")
        if p.is_dir() and _inside(inp, p):
            raise OutputError(f"{p}: the output folder holds the input {inp}")
    st = _stat(p)
    if st is None:
        if not force:
            _NEW_OUTPUTS.add(_key(p))
        return p
    _NEW_OUTPUTS.discard(_key(p))
    special = _special(st.st_mode)
    if special:
        raise OutputError(
            f"{p}: is a {special}, not a regular file; thirdhand writes only files and "
            f"folders and never moves a {special} aside"
        )
    is_dir = stat.S_ISDIR(st.st_mode)
    if is_dir and p.suffix.lower() in FILE_SUFFIXES:
        raise OutputError(f"{p}: is a folder; a {p.suffix} output is a file (name a file)")
    if is_dir and not thirdhand_folder(p):
        raise OutputError(
            f"{p}: is a folder that holds no recording; {option} replaces only files and "
            "recording folders thirdhand wrote (name a new path)"
        )
    if not force:
        kind = "folder" if is_dir else "file"
        raise OutputError(
            f"{p}: the {kind} exists; pass {option} to replace it "
            f"(the old one is kept as {next_backup(p).name})"
        )
    return p


_BACKUP = re.compile(r"\.bak(?:\.(\d+))?$")


def next_backup(path: PathLike) -> Path:
    """The name the next backup of ``path`` gets: ``.bak``, then ``.bak.1``, ``.bak.2``…

    Always one more than the highest existing number, so the newest backup has
    the highest number and no existing file is ever chosen.
    """
    p = Path(path)
    folder = p.parent if str(p.parent) else Path(".")
    prefix = p.name
    highest = -1
    try:
        names = os.listdir(folder)
    except OSError:
        names = []
    for name in names:
        if not name.startswith(prefix):
            continue
        m = _BACKUP.fullmatch(name[len(prefix) :])
        if m:
            highest = max(highest, int(m.group(1) or 0))
    n = highest + 1
    return p.with_name(prefix + ".bak" + (f".{n}" if n else ""))


@contextlib.contextmanager
def _folder_lock(folder: Path) -> Iterator[None]:
    """Hold an exclusive advisory lock on ``folder`` (no-op where flock is missing)."""
    if fcntl is None:
        yield
        return
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        yield
        return
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
        except OSError:
            pass  # a file system without locks: rely on the unique names alone
        yield
    finally:
        os.close(fd)  # releases the lock


def _fsync_dir(folder: Path) -> None:
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _fsync_tree(p: Path) -> None:
    """Flush a written file, or every file of a written folder, to disk."""
    paths = [p] if not p.is_dir() else [p, *sorted(p.rglob("*"))]
    for q in paths:
        if q.is_dir():
            _fsync_dir(q)
            continue
        fd = os.open(q, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _copy_backup(p: Path) -> Path:
    """A complete copy of ``p`` under a fresh numbered backup name (never replacing a file)."""
    while True:
        bak = next_backup(p)
        try:
            if p.is_dir():
                os.mkdir(bak)
                shutil.copytree(p, bak, symlinks=True, dirs_exist_ok=True)
                return bak
            try:
                os.link(p, bak)
            except FileExistsError:
                continue
            except OSError:
                with open(p, "rb") as src, open(bak, "xb") as dst:
                    shutil.copyfileobj(src, dst)
                shutil.copystat(p, bak)
            return bak
        except FileExistsError:
            continue  # another process took the name meanwhile


def backup_existing(path: PathLike) -> Path | None:
    """Keep a complete copy of ``path`` (file or folder) under the next numbered backup name.

    Returns the backup's path, or None when ``path`` did not exist. No existing
    file is replaced: an older ``.bak`` stays and the new one is ``.bak.1`` etc.
    """
    p = Path(path)
    if not os.path.lexists(p):
        return None
    with _folder_lock(p.parent if str(p.parent) else Path(".")):
        return _copy_backup(p)


def _rename_noreplace(src: Path, dst: Path) -> None:
    """Rename ``src`` to ``dst`` only if ``dst`` does not exist, in one step.

    Linux ``renameat2(RENAME_NOREPLACE)``; elsewhere a hard link for a file (also
    exclusive), and for a folder a check then a rename under the folder lock
    (exclusive among thirdhand's writers). Raises ``FileExistsError``.
    """
    libc = _libc()
    if libc is not None:
        at_fdcwd, rename_noreplace = -100, 1
        rc = libc.renameat2(
            at_fdcwd, os.fsencode(src), at_fdcwd, os.fsencode(dst), rename_noreplace
        )
        if rc == 0:
            return
        err = ctypes.get_errno()
        if err == errno.EEXIST:
            raise FileExistsError(errno.EEXIST, os.strerror(errno.EEXIST), str(dst))
        if err not in (errno.EINVAL, errno.ENOSYS, errno.ENOTSUP):
            raise OSError(err, os.strerror(err), str(dst))
    if os.path.lexists(dst):
        raise FileExistsError(errno.EEXIST, os.strerror(errno.EEXIST), str(dst))
    if src.is_dir():
        os.rename(src, dst)
    else:
        os.link(src, dst)
        os.unlink(src)


_LIBC: list[Any] = []


def _libc() -> Any:
    if not _LIBC:
        lib = None
        if sys.platform.startswith("linux"):
            try:
                lib = ctypes.CDLL(None, use_errno=True)
                lib.renameat2  # noqa: B018 - glibc >= 2.28
            except (OSError, AttributeError):
                lib = None
        _LIBC.append(lib)
    return _LIBC[0]


def _replace(built: Path, target: Path, *, backup: bool, exclusive: bool = False) -> Path | None:
    """Move the complete ``built`` to ``target``; the previous target becomes a backup.

    With ``exclusive`` the target must still be missing (it was when the command
    checked it): a target another process created meanwhile is kept, and this
    write fails.
    """
    bak: Path | None = None
    folder = target.parent if str(target.parent) else Path(".")
    with _folder_lock(folder):
        if exclusive:
            try:
                _rename_noreplace(built, target)
            except FileExistsError:
                raise OutputError(
                    f"{target}: was created by another process while this one ran; it is kept "
                    "and nothing was written (pass --force to replace it)"
                ) from None
            _fsync_dir(folder)
            return None
        exists = os.path.lexists(target)
        st = _stat(target) if exists else None
        special = None if st is None else _special(st.st_mode)
        if special or (
            st is not None and stat.S_ISDIR(st.st_mode) and not thirdhand_folder(target)
        ):
            raise OutputError(
                f"{target}: is a {special or 'folder that holds no recording'}; it is never "
                "moved aside (nothing was written)"
            )
        if exists and (target.is_dir() or built.is_dir()):
            if backup:
                bak = next_backup(target)
                os.rename(target, bak)
                try:
                    os.rename(built, target)
                except OSError:
                    os.rename(bak, target)
                    raise
            else:
                old = Path(tempfile.mkdtemp(dir=folder, prefix=f".{target.name}.", suffix=".old"))
                os.rename(target, old / target.name)
                os.rename(built, target)
                shutil.rmtree(old, ignore_errors=True)
        else:
            if exists and backup:
                bak = _copy_backup(target)
            os.replace(built, target)
        _fsync_dir(folder)
    return bak


def _message(p: Path, exc: OSError) -> str:
    if exc.errno in (errno.ENOSPC, errno.EFBIG, errno.EDQUOT):
        what = {
            errno.ENOSPC: "the disk is full",
            errno.EFBIG: "the file-size limit was reached",
            errno.EDQUOT: "the disk quota is exceeded",
        }[exc.errno]
        return f"{p}: cannot write: {what} (nothing was replaced)"
    return f"{p}: cannot write: {exc.strerror or exc} (nothing was replaced)"


@contextlib.contextmanager
def atomic_output(
    path: PathLike,
    *,
    backup: bool = True,
    verify: Callable[[Path], None] | None = None,
) -> Iterator[Path]:
    """Write an output file or folder atomically: yield a temporary path, then rename it.

    The yielded path has the target's name inside a fresh hidden folder beside
    the target (``.<name>.<random>.tmp/<name>``), so a writer can tell the
    format from the name and may create a file or a folder there. When the block
    ends without an exception, the result is flushed to disk, ``verify`` (if
    given) checks it, and it replaces the target; the previous target is kept as
    a numbered backup when ``backup``. On any exception (also Ctrl-C) the
    temporary folder is removed and the target is left as it was. Missing
    folders of the target are created, and removed again when the write fails.

    Raises
    ------
    OutputError
        The folder cannot be written, or the write was short (``ENOSPC``,
        ``EFBIG``) or failed for another operating-system reason.
    """
    p = Path(path)
    exclusive = _key(p) in _NEW_OUTPUTS
    _NEW_OUTPUTS.discard(_key(p))
    folder = p.parent if str(p.parent) else Path(".")
    created = _missing_folders(folder)
    # Ctrl-C or SIGTERM while the temporary folder is made, while it replaces the
    # target or while it is removed would leave a half-done step behind: the
    # signal waits until the step is over (signals_deferred).
    with signals_deferred():
        try:
            folder.mkdir(parents=True, exist_ok=True)
            tmp_dir = Path(tempfile.mkdtemp(dir=folder, prefix=f".{p.name}.", suffix=".tmp"))
        except OSError as exc:
            _remove_empty(created)
            raise OutputError(_message(p, exc)) from None
        _UNDER_WAY[tmp_dir] = created
        built = tmp_dir / p.name
        done = False
        _OPEN[0] += 1
    try:
        try:
            yield built
            if not os.path.lexists(built):
                raise OutputError(f"{p}: the writer produced nothing (nothing was replaced)")
            _fsync_tree(built)
            if verify is not None:
                verify(built)
            with signals_deferred():
                _replace(built, p, backup=backup, exclusive=exclusive)
                done = True
                if _OPEN[0] == 1:
                    _COMPLETED.append(os.fspath(p))
        except OutputError:
            raise
        except OSError as exc:
            raise OutputError(_message(p, exc)) from None
    finally:
        with signals_deferred():
            _OPEN[0] -= 1
            shutil.rmtree(tmp_dir, ignore_errors=True)
            if not done:  # a failed write leaves no trace, not even the folders made for it
                _remove_empty(created)
            _UNDER_WAY.pop(tmp_dir, None)


#: The temporary folder of every write under way, with the folders made for it.
_UNDER_WAY: dict[Path, list[Path]] = {}


def remove_leftovers() -> None:
    """Remove what writes cut short by a signal left behind (the CLI calls it on exit).

    A signal that comes in the few instructions between a write's last step and its
    clean-up (where :func:`signals_deferred` cannot be entered in time) would leave
    the temporary folder: the command removes it on its way out.
    """
    for tmp_dir, created in list(_UNDER_WAY.items()):
        shutil.rmtree(tmp_dir, ignore_errors=True)
        _remove_empty(created)
        _UNDER_WAY.pop(tmp_dir, None)


#: Signals that came while :func:`signals_deferred` was in force, and its depth.
_DEFERRED: list[int] = []
_DEFER_DEPTH = [0]


def defer_signal(signum: int) -> bool:
    """Called by a signal handler first: True when the signal must wait (it is kept).

    Inside :func:`signals_deferred` the handler returns at once and the signal's
    exception is raised when the outermost deferral ends.
    """
    if _DEFER_DEPTH[0] > 0:
        _DEFERRED.append(signum)
        return True
    return False


@contextlib.contextmanager
def signals_deferred() -> Iterator[None]:
    """Make Ctrl-C and SIGTERM wait until the block is over, then raise as they would.

    The CLI's handlers (:func:`thirdhand.cli.main`) ask :func:`defer_signal` first.
    Unlike a signal mask this holds whichever thread the operating system gave the
    signal to (Python runs every handler in the main thread).

    Raises
    ------
    KeyboardInterrupt, Terminated
        After the block, for a Ctrl-C or SIGTERM that came during it.
    """
    _DEFER_DEPTH[0] += 1
    try:
        yield
    finally:
        _DEFER_DEPTH[0] -= 1
    if _DEFER_DEPTH[0] == 0 and _DEFERRED:
        came = _DEFERRED[:]
        _DEFERRED.clear()
        raise signal_exception(signal.SIGTERM if signal.SIGTERM in came else signal.SIGINT)


def signal_exception(signum: int) -> BaseException:
    """What a signal ends a command with: Terminated for SIGTERM, else KeyboardInterrupt."""
    from thirdhand.errors import Terminated

    return Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()


def _missing_folders(folder: Path) -> list[Path]:
    """The folders ``mkdir(parents=True)`` of ``folder`` would create, outermost first."""
    missing = []
    f = folder
    while not os.path.lexists(f) and f != f.parent:
        missing.append(f)
        f = f.parent
    return missing[::-1]


def _remove_empty(folders: list[Path]) -> None:
    """Remove ``folders`` (outermost first) from the innermost out, while they are empty."""
    for f in reversed(folders):
        try:
            f.rmdir()
        except OSError:
            return


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        n = os.write(fd, view)
        if n <= 0:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        view = view[n:]


def write_bytes(path: PathLike, data: bytes, *, backup: bool = True) -> None:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_output`).

    Raises
    ------
    OutputError
        On a short or failed write; the old file is left as it was.
    """
    with atomic_output(path, backup=backup) as tmp:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        try:
            _write_all(fd, data)
        finally:
            os.close(fd)


def write_text(path: PathLike, text: str, *, backup: bool = True) -> None:
    """Write ``text`` (UTF-8, ``\\n`` line ends) to ``path`` atomically."""
    write_bytes(path, text.encode("utf-8"), backup=backup)


def atomic_write_bytes(path: PathLike, data: bytes, *, backup: bool = True) -> None:
    """Alias of :func:`write_bytes`, kept for existing callers."""
    write_bytes(path, data, backup=backup)


def forget_checked_outputs() -> None:
    """Forget the outputs found missing and those completed (a command ends)."""
    _NEW_OUTPUTS.clear()
    _COMPLETED.clear()


def completed_outputs() -> list[str]:
    """The outputs :func:`atomic_output` put in place, complete, since the command started."""
    return list(_COMPLETED)


def interrupted_message(what: str = "interrupted") -> str:
    """One line for a command stopped by a signal: which outputs it left, complete, if any.

    Every output is written to a temporary path and renamed in one step, so an
    output is either complete or absent; the line says which.
    """
    done = completed_outputs()
    if not done:
        return f"{what}; no output was written"
    shown = ", ".join(done) if len(done) <= 3 else f"{', '.join(done[:3])} and {len(done) - 3} more"
    return f"{what} after {shown} was written complete; nothing else was written"


__all__ = [
    "FILE_SUFFIXES",
    "atomic_output",
    "atomic_write_bytes",
    "backup_existing",
    "check_distinct_inputs",
    "check_output",
    "check_outputs",
    "check_path_shape",
    "completed_outputs",
    "forget_checked_outputs",
    "interrupted_message",
    "next_backup",
    "thirdhand_folder",
    "write_bytes",
    "write_text",
]
