"""The review's dialogs and notices: what is asked or told, and when.

Pure records and functions; :class:`~thirdhand.review.panels.Panels` shows a
:class:`Dialog` as a viser modal and a :class:`Notice` as a notification.
"""

from __future__ import annotations

import html
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

Discard = Literal["reload", "quit"]


@dataclass(frozen=True)
class Dialog:
    """A modal question with two buttons: ``confirm`` (red) does it, ``cancel`` closes.

    Attributes
    ----------
    title : str
    markdown : str
        The question (markdown, names escaped).
    confirm, cancel : str
        The buttons' labels.
    """

    title: str
    markdown: str
    confirm: str
    cancel: str


@dataclass(frozen=True)
class Notice:
    """A notification: ``title``, ``body``, a colour, and seconds until it closes
    (None: the person closes it)."""

    title: str
    body: str
    color: Literal["red", "yellow", "green", "blue"]
    auto_close_seconds: float | None


def discard_dialog(what: Discard) -> Dialog:
    """Ask before ``what`` (reload, quit) throws away unsaved changes."""
    return Dialog(
        "Unsaved changes",
        f"The task has unsaved changes. {what.capitalize()} and lose them?",
        f"Discard and {what}",
        "Cancel",
    )


def overwrite_dialog(task_name: str, kept_name: str) -> Dialog:
    """After a refused save: offer to overwrite the file that changed on disk
    (``task_name``), the edits being kept meanwhile in ``kept_name``."""
    return Dialog(
        "File changed on disk",
        f"**{html.escape(task_name)}** changed on disk since it was loaded. "
        f"Your edits are kept in this session and in **{html.escape(kept_name)}**.",
        "Overwrite (keep theirs as .bak)",
        "Keep both",
    )


def conflict_path(task_path: Path) -> Path:
    """Where the edits go when a save is refused: ``STEM.unsaved.json`` beside the task."""
    return task_path.with_name(task_path.stem + ".unsaved.json")


def conflict_message(task_name: str, kept_name: str) -> str:
    """The status line after a refused save."""
    return (
        f"{task_name} changed on disk since it was loaded: not saved. "
        f"Your edits are kept here and in {kept_name}"
    )


def refusal_notice(*, has_token: bool) -> Notice:
    """Why a tab's input changed nothing: no access token, or another tab edits."""
    if not has_token:
        return Notice("Refused", "This tab has no access token.", "red", 6.0)
    return Notice(
        "Read-only",
        "Another tab is editing this task; this one only shows it (one editor at a time). "
        "Close the other tab to edit here.",
        "yellow",
        6.0,
    )


#: What a tab that connects while another edits is told (it stays up).
READ_ONLY_ON_CONNECT = Notice(
    "Read-only",
    "Another tab is editing this task; this one only shows it (one editor at a time).",
    "yellow",
    None,
)
#: What the oldest other tab is told when the editing tab closes.
EDITOR_HANDED_OVER = Notice("You can edit now", "The editing tab closed.", "green", 6.0)


def message_notice(text: str, *, error: bool) -> Notice:
    """A status message as a notification in every tab (an error stays up)."""
    if error:
        return Notice("Refused", text, "red", None)
    return Notice("Review", text, "blue", 4.0)


def next_editor(clients: list[int], leaving: int, allowed: list[int]) -> int | None:
    """The tab that edits after ``leaving`` closes: the oldest other allowed one."""
    others = sorted(c for c in clients if c != leaving and c in allowed)
    return others[0] if others else None


__all__ = [
    "EDITOR_HANDED_OVER",
    "READ_ONLY_ON_CONNECT",
    "Dialog",
    "Discard",
    "Notice",
    "conflict_message",
    "conflict_path",
    "discard_dialog",
    "message_notice",
    "next_editor",
    "overwrite_dialog",
    "refusal_notice",
]
