"""A review session: one task file, its edit history, the effort log, and a safe save.

The file's SHA-256 is remembered when it is loaded (and after every save); a
save over a file that another program changed meanwhile is refused with a
:class:`ConflictError`, so nobody's work is overwritten. The person's version is
not lost: it stays in the session and can be written under another name
(:meth:`ReviewSession.save_as`), or over the file with ``force=True`` (the
other version is then kept as ``<file>.bak``).
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

from thirdhand.errors import ThirdhandError
from thirdhand.readlimits import read_input
from thirdhand.review.edits import Edit, MoveStep, SetParent, SetPrimitivePoint
from thirdhand.review.effort import ACTIONS, EffortLog, changed_parameters, operation_of
from thirdhand.review.history import History
from thirdhand.task.model import TaskFile
from thirdhand.task.store import parse_task, save_task


class ConflictError(ThirdhandError):
    """The task file on disk changed since the session loaded (or last saved) it."""


def _sha256(path: Path) -> str | None:
    if not os.path.lexists(path):
        return None
    data = read_input(
        path,
        what="task file",
        error=lambda m: ThirdhandError(f"{path}: cannot read task file: {m}"),
    )
    return hashlib.sha256(data).hexdigest()


def _object_of(task: TaskFile, edit: Edit) -> str:
    """The object an edit is about (the constrained child), for the effort log."""
    if isinstance(edit, SetParent):
        return edit.child
    if isinstance(edit, MoveStep):
        return ACTIONS
    if isinstance(edit, SetPrimitivePoint):
        block = task.stages.primitives
        entry = None if block is None else block.constraints.get(edit.key)
        return entry.child if entry is not None else ACTIONS
    cid = getattr(edit, "constraint", None)
    for c in task.constraints:
        if c.id == cid:
            return c.child
    return ACTIONS


class ReviewSession:
    """The task file under review.

    Attributes
    ----------
    path : Path
        The file the session saves to.
    history : History
        Edits, undo and redo.
    effort : EffortLog
        GUI operations per object, continued from the file's
        ``stages.review.effort`` when present.
    original : TaskFile
        The task as loaded, the reference of the changed-parameter count.
    """

    def __init__(self, path: str | os.PathLike[str], task: TaskFile, sha256: str | None) -> None:
        self.path = Path(path)
        self.history = History(task)
        self.original = task
        review = task.stages.review
        effort = None if review is None else review.effort
        self.effort = EffortLog(None if effort is None else effort.operations)
        self._sha256 = sha256

    @classmethod
    def open(cls, path: str | os.PathLike[str]) -> ReviewSession:
        """Load and validate a task file and remember its content's hash.

        Raises
        ------
        TaskFileError
            If the file cannot be read or is not a valid task file.
        """
        from thirdhand.errors import TaskFileError

        p = Path(path)
        data = read_input(
            p, what="task file", error=lambda m: TaskFileError(f"{p}: cannot read task file: {m}")
        )
        try:
            text = data.decode("utf-8")
        except UnicodeDecodeError as exc:
            from thirdhand.errors import TaskFileError

            raise TaskFileError(f"{p}: not UTF-8 text: {exc}") from None
        task = parse_task(text, name=str(p))
        return cls(p, task, hashlib.sha256(data).hexdigest())

    @property
    def task(self) -> TaskFile:
        """The current task (``history.current``)."""
        return self.history.current

    @property
    def dirty(self) -> bool:
        """True when there are changes not saved yet."""
        return self.history.dirty

    def apply(self, edit: Edit, *, operation: str | None = None, who: str = "user") -> TaskFile:
        """Apply an edit and count its operation in the effort log.

        Parameters
        ----------
        edit : Edit
        operation : str, optional
            The GUI operation to count (:data:`~thirdhand.review.effort.OPERATIONS`);
            by default the one the edit stands for (:func:`~thirdhand.review.effort.operation_of`).
        who : str
            Author recorded in the provenance.

        Raises
        ------
        EditError
            If the edit is refused (nothing changes, nothing is counted).
        """
        obj = _object_of(self.task, edit)
        task = self.history.apply(edit, who=who)
        self.effort.record(operation or operation_of(edit), obj)
        return task

    def undo(self) -> TaskFile:
        """Undo the last edit."""
        return self.history.undo()

    def redo(self) -> TaskFile:
        """Redo the last undone edit."""
        return self.history.redo()

    def changed_parameters(self) -> list[str]:
        """Parameters changed since the file was loaded (:func:`changed_parameters`)."""
        return changed_parameters(self.original, self.task)

    def conflict(self) -> bool:
        """True when the file on disk is not the one loaded or last saved."""
        on_disk = _sha256(self.path)
        return on_disk is not None and on_disk != self._sha256

    def save(self, path: str | os.PathLike[str] | None = None, *, force: bool = False) -> Path:
        """Write the current task (with the effort block in ``stages.review``).

        Parameters
        ----------
        path : path-like, optional
            Another file to write to (the session then continues on it); default
            the session's file.
        force : bool
            Overwrite the session's file even if it changed on disk (its other
            version is kept as ``<file>.bak``).

        Returns
        -------
        Path
            The file written.

        Raises
        ------
        ConflictError
            Saving to the session's file, which changed on disk since it was loaded
            or last saved (nothing is written; save elsewhere or with ``force``).
        TaskFileError
            If the file cannot be written (the previous one is left as it was).
        """
        target = Path(path) if path is not None else self.path
        same = target.resolve() == self.path.resolve()
        if same and not force and self.conflict():
            raise ConflictError(
                f"{self.path}: the file changed on disk since it was loaded; your changes are "
                "kept in the session: save them under another name, or overwrite with force"
            )
        task = self.task.model_copy(deep=True)
        task.stages.ensure_review().effort = self.effort.to_stage(self.changed_parameters())
        save_task(task, target)
        self.history.replace_current(task)
        self.history.mark_saved()
        self.path = target
        self._sha256 = _sha256(target)
        return target

    def save_as(self, path: str | os.PathLike[str]) -> Path:
        """Write the current task to another file and continue the session on it."""
        return self.save(path)
