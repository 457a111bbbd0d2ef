"""Undo and redo over immutable task snapshots."""

from __future__ import annotations

from thirdhand.review.edits import Edit, apply_edit
from thirdhand.task.model import TaskFile


class History:
    """The sequence of tasks made by edits, with a cursor for undo and redo.

    Every :meth:`apply` stores the new task (edits never change a task in place,
    so snapshots are cheap to keep and exact to restore). A new edit after undos
    drops the undone branch.

    Parameters
    ----------
    task : TaskFile
        The starting point (also the state marked as saved).
    """

    def __init__(self, task: TaskFile) -> None:
        self._states: list[TaskFile] = [task]
        self._edits: list[Edit | None] = [None]
        self._cursor = 0
        self._saved: int | None = 0

    @property
    def current(self) -> TaskFile:
        """The task as the person sees it now."""
        return self._states[self._cursor]

    @property
    def can_undo(self) -> bool:
        """True when there is an edit to undo."""
        return self._cursor > 0

    @property
    def can_redo(self) -> bool:
        """True when an undone edit can be redone."""
        return self._cursor < len(self._states) - 1

    @property
    def dirty(self) -> bool:
        """True when the current task is not the one last marked as saved."""
        return self._saved != self._cursor

    @property
    def edits(self) -> list[Edit]:
        """The edits from the start to the current task, in order."""
        return [e for e in self._edits[1 : self._cursor + 1] if e is not None]

    def apply(self, edit: Edit, *, who: str = "user") -> TaskFile:
        """Apply ``edit`` to the current task and make the result current.

        Raises
        ------
        EditError
            If the edit is refused; the history is unchanged.
        """
        task = apply_edit(self.current, edit, who=who)
        del self._states[self._cursor + 1 :]
        del self._edits[self._cursor + 1 :]
        if self._saved is not None and self._saved > self._cursor:
            self._saved = None
        self._states.append(task)
        self._edits.append(edit)
        self._cursor += 1
        return task

    def undo(self) -> TaskFile:
        """Go back one edit (nothing happens at the start) and return the current task."""
        if self.can_undo:
            self._cursor -= 1
        return self.current

    def redo(self) -> TaskFile:
        """Redo the last undone edit (nothing happens at the end) and return the current task."""
        if self.can_redo:
            self._cursor += 1
        return self.current

    def mark_saved(self) -> None:
        """Remember the current task as the one on disk."""
        self._saved = self._cursor

    def replace_current(self, task: TaskFile) -> None:
        """Swap the current snapshot for ``task`` (bookkeeping that is not an edit, e.g.
        the effort block written on save); undo history is kept."""
        self._states[self._cursor] = task
