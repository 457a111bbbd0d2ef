"""Who may see and edit: an access token when the review server is reachable beyond loopback.

Bound to a loopback address (the default, ``127.0.0.1``) only this machine's
users reach the server and no token is asked. With ``--host`` beyond loopback
(``0.0.0.0``, a LAN address), :class:`AccessGate` asks for a random token:

- it travels in the **websocket path**. viser's page connects to the websocket
  named by its ``?websocket=`` query parameter, so the start line prints
  ``http://HOST:PORT/?websocket=ws://HOST:PORT/TOKEN`` (:func:`token_url`);
- a websocket whose path does not carry the token is **closed before any
  message is sent** (code 1008, policy violation): the task, the scene and the
  panels travel only over the websocket, so a client without the token sees
  none of them and can send nothing;
- every edit also checks the client (:meth:`AccessGate.allowed`): a client
  the gate did not admit is refused, should one ever get through.

What the token does not cover: viser 1.1 serves its static client bundle (the
generic viewer, no task data) over HTTP to anyone, with no hook to refuse it;
the connection carries no TLS, so the token is as private as the network.

viser 1.1 has no public hook on the websocket handshake either: the gate reads
the raw connection of a new client from the server's websocket layer
(``ViserServer._websock_server._live_connections``, its request path), pinned by
the project's ``viser>=1.1,<1.2`` and by ``tests/test_review_access.py``.
"""

from __future__ import annotations

import asyncio
import hmac
import ipaddress
import secrets
import socket
import threading
from typing import Any

#: Websocket close code of a refused client: RFC 6455 "policy violation".
REFUSED_CODE = 1008
REFUSED_REASON = "thirdhand review: access token required (open the URL printed at start)"


def is_loopback(host: str) -> bool:
    """True when ``host`` is reachable from this machine only (127.0.0.0/8, ::1, localhost).

    A name other than ``localhost`` counts as beyond loopback: it may resolve
    to any address.
    """
    if host.strip().lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def new_token() -> str:
    """A fresh URL-safe random token (128 bits)."""
    return secrets.token_urlsafe(16)


def shown_host(host: str) -> str:
    """The host to print in a URL: this machine's name for an unspecified address."""
    try:
        unspecified = ipaddress.ip_address(host).is_unspecified
    except ValueError:
        unspecified = False
    name = socket.gethostname() if unspecified else host
    return f"[{name}]" if ":" in name else name


def token_url(host: str, port: int, token: str) -> str:
    """The page address that carries ``token`` to the websocket.

    Returns
    -------
    str
        ``http://HOST:PORT/?websocket=ws://HOST:PORT/TOKEN``.
    """
    return f"http://{host}:{port}/?websocket=ws://{host}:{port}/{token}"


def token_of_path(path: str) -> str:
    """The token a websocket request path carries: ``/TOKEN`` or ``/TOKEN?…`` → ``TOKEN``."""
    return path.partition("?")[0].strip("/")


class AccessGate:
    """Admit the websocket clients whose request path carries the token; close the others.

    Parameters
    ----------
    token : str
        The access token (:func:`new_token`).

    Attributes
    ----------
    admitted : set of int
        viser client ids that presented the token.
    refused : int
        Connections closed for a missing or wrong token.
    """

    def __init__(self, token: str) -> None:
        if not token or "/" in token or "?" in token:
            raise ValueError(f"access token must be a non-empty URL path segment, got {token!r}")
        self.token = token
        self.admitted: set[int] = set()
        self.refused = 0
        self._lock = threading.Lock()

    def accepts(self, path: str) -> bool:
        """Whether a websocket request ``path`` carries the token (constant-time compare)."""
        return hmac.compare_digest(token_of_path(path).encode(), self.token.encode())

    def allowed(self, client_id: int) -> bool:
        """Whether the client ``client_id`` presented the token."""
        with self._lock:
            return client_id in self.admitted

    def install(self, server: Any) -> None:
        """Check every websocket client of a running :class:`viser.ViserServer`.

        Registered on the websocket layer, the check runs when a client connects,
        before the server sends it anything; clients that connected while the
        server was starting are checked at once.
        """
        ws_server = server._websock_server
        live: dict[int, Any] = ws_server._live_connections

        async def check(conn: Any) -> None:
            await self._check(conn.client_id, live.get(conn.client_id))

        ws_server.on_client_connect(check)
        loop = ws_server._background_event_loop
        for client_id, connection in tuple(live.items()):
            if loop is not None:
                asyncio.run_coroutine_threadsafe(self._check(client_id, connection), loop)

    async def _check(self, client_id: int, connection: Any) -> None:
        request = getattr(connection, "request", None)
        path = getattr(request, "path", "") or ""
        if connection is not None and self.accepts(path):
            with self._lock:
                self.admitted.add(client_id)
            return
        with self._lock:
            self.refused += 1
        if connection is not None:
            await connection.close(REFUSED_CODE, REFUSED_REASON)


__all__ = [
    "REFUSED_CODE",
    "AccessGate",
    "is_loopback",
    "new_token",
    "shown_host",
    "token_of_path",
    "token_url",
]
