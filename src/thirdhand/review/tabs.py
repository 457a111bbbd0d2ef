"""Which browser tab may edit: the first to connect with the access token; the others
only view until it closes, and are told so (:mod:`~thirdhand.review.dialogs`)."""

from __future__ import annotations

import threading
from collections.abc import Callable

import viser

from thirdhand.review.access import AccessGate
from thirdhand.review.dialogs import EDITOR_HANDED_OVER, READ_ONLY_ON_CONNECT, Notice, next_editor


def tell(client: viser.ClientHandle, notice: Notice) -> None:
    """Show ``notice`` in ``client``'s tab."""
    client.add_notification(
        notice.title, notice.body, color=notice.color, auto_close_seconds=notice.auto_close_seconds
    )


class EditorTabs:
    """The tabs of one review app and the one among them that edits.

    Parameters
    ----------
    gate : AccessGate or None
        Who may connect (None: anyone who reaches a loopback address).
    lock : threading.RLock
        The app's lock.

    Attributes
    ----------
    editor : int or None
        The viser client id of the tab that edits (None: none connected yet).
    """

    def __init__(self, gate: AccessGate | None, lock: threading.RLock) -> None:
        self.gate = gate
        self.lock = lock
        self.editor: int | None = None

    def admits(self, client_id: int) -> bool:
        """Whether the tab presented the access token (always, when none is asked)."""
        return self.gate is None or self.gate.allowed(client_id)

    def may_edit(self, client_id: int | None) -> bool:
        """Whether the tab ``client_id`` may change the task (None: the server itself).

        A client without the access token never may; of the others, the editing tab.
        """
        if client_id is None:
            return True
        if not self.admits(client_id):
            return False
        return self.editor is None or client_id == self.editor

    def connected(
        self,
        client: viser.ClientHandle,
        camera: Callable[[], tuple[tuple[float, float, float], tuple[float, float, float]]],
    ) -> None:
        """A tab connected: its camera goes to ``camera()`` (position and target, world
        frame, m); the first tab (with the token) edits, a later one is told it views."""
        if not self.admits(client.client_id):
            return
        position, look_at = camera()
        client.camera.position = position
        client.camera.look_at = look_at
        with self.lock:
            if self.editor is None:
                self.editor = client.client_id
                return
        tell(client, READ_ONLY_ON_CONNECT)

    def disconnected(self, client: viser.ClientHandle, server: viser.ViserServer) -> None:
        """The editing tab closed: the oldest other tab edits now, and is told so."""
        with self.lock:
            if client.client_id != self.editor:
                return
            clients = server.get_clients()
            allowed = [c for c in clients if self.admits(c)]
            self.editor = next_editor(list(clients), client.client_id, allowed)
            heir = clients.get(self.editor) if self.editor is not None else None
        if heir is not None:
            tell(heir, EDITOR_HANDED_OVER)


__all__ = ["EditorTabs", "tell"]
