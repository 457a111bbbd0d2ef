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
import errno
import os
import re
import shutil
import tempfile
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

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


def check_output(
    path: PathLike,
    *,
    force: bool = False,
    inputs: Iterable[PathLike] = (),
    option: str = "--force",
) -> Path:
    """Check that ``path`` may be written; raise :class:`OutputError` if not.

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
    p = Path(path)
    for raw in inputs:
        inp = Path(raw)
        if _same(p, inp):
            raise OutputError(f"{p}: the output is also an input ({inp}); write it to another path")
        if inp.is_dir() and _inside(p, inp):
            raise OutputError(f"{p}: the output lies inside the input folder {inp}")
        if p.is_dir() and _inside(inp, p):
            raise OutputError(f"{p}: the output folder holds the input {inp}")
    if os.path.lexists(p) and not force:
        kind = "folder" if p.is_dir() else "file"
        raise OutputError(
            f"{p}: the {kind} exists; pass {option} to replace it "
            f"(the old one is kept as {next_backup(p).name})"
        )
    if p.parent != p and p.parent.exists() and not p.parent.is_dir():
        raise OutputError(f"{p}: {p.parent} is not a folder")
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


def _replace(built: Path, target: Path, *, backup: bool) -> Path | None:
    """Move the complete ``built`` to ``target``; the previous target becomes a backup."""
    bak: Path | None = None
    folder = target.parent if str(target.parent) else Path(".")
    with _folder_lock(folder):
        exists = os.path.lexists(target)
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
    folder = p.parent if str(p.parent) else Path(".")
    created = _missing_folders(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        tmp_dir = Path(tempfile.mkdtemp(dir=folder, prefix=f".{p.name}.", suffix=".tmp"))
    except OSError as exc:
        _remove_empty(created)
        raise OutputError(_message(p, exc)) from None
    built = tmp_dir / p.name
    done = False
    try:
        try:
            yield built
            if not os.path.lexists(built):
                raise OutputError(f"{p}: the writer produced nothing (nothing was replaced)")
            _fsync_tree(built)
            if verify is not None:
                verify(built)
            _replace(built, p, backup=backup)
            done = True
        except OSError as exc:
            raise OutputError(_message(p, exc)) from None
    finally:
        shutil.rmtree(tmp_dir, ignore_errors=True)
        if not done:  # a failed write leaves no trace, not even the folders made for it
            _remove_empty(created)


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


__all__ = [
    "atomic_output",
    "atomic_write_bytes",
    "backup_existing",
    "check_output",
    "next_backup",
    "write_bytes",
    "write_text",
]
