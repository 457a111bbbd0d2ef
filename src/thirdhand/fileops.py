"""Safe file replacement: nothing a user made is overwritten without a full copy first."""

from __future__ import annotations

import os
import shutil
from pathlib import Path


def backup_existing(path: str | os.PathLike[str]) -> Path | None:
    """Keep a complete copy of ``path`` (file or folder) as ``<path>.bak``.

    Returns the backup's path, or None when ``path`` did not exist. An older
    backup is replaced.
    """
    p = Path(path)
    if not p.exists():
        return None
    bak = p.with_name(p.name + ".bak")
    if bak.is_dir():
        shutil.rmtree(bak)
    elif bak.exists():
        bak.unlink()
    if p.is_dir():
        shutil.copytree(p, bak)
    else:
        shutil.copy2(p, bak)
    return bak


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file, fsync and rename."""
    p = Path(path)
    tmp = p.with_name(p.name + ".tmp")
    with open(tmp, "wb") as fh:
        fh.write(data)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, p)
