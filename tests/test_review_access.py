"""The review server beyond loopback: an access token for the page's data and every edit.

Pure helpers first, then a server bound to ``0.0.0.0``: a raw websocket client
without (or with a wrong) token is closed before it receives one message and
can send nothing; one with the token receives the scene. The browser test
opens the printed URL (it edits) and the bare address (no panel, no edit).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.test_review_gui import CHROMIUM, CHROMIUM_ARGS, TIMEOUT_MS, Review
from thirdhand.review.access import (
    REFUSED_CODE,
    AccessGate,
    is_loopback,
    token_of_path,
    token_url,
)
from thirdhand.review.app import app_url
from thirdhand.review.view import selected_constraint
from thirdhand.synth import make_scene
from thirdhand.synth.task import truth_task
from thirdhand.taskfile import save_task


@pytest.mark.parametrize(
    ("host", "loopback"),
    [
        ("127.0.0.1", True),
        ("127.1.2.3", True),
        ("::1", True),
        ("localhost", True),
        ("0.0.0.0", False),
        ("::", False),
        ("192.168.1.20", False),
        ("example.org", False),
    ],
)
def test_loopback_addresses(host: str, loopback: bool) -> None:
    assert is_loopback(host) is loopback


def test_token_travels_in_the_websocket_path() -> None:
    url = token_url("lab-pc", 8080, "abc_DEF-1")
    assert url == "http://lab-pc:8080/?websocket=ws://lab-pc:8080/abc_DEF-1"
    ws = url.split("websocket=", 1)[1]
    path = "/" + ws.split("/", 3)[3]
    gate = AccessGate("abc_DEF-1")
    assert token_of_path(path) == "abc_DEF-1" and gate.accepts(path)
    assert gate.accepts("/abc_DEF-1/") and gate.accepts("/abc_DEF-1?x=1")
    for bad in ("/", "", "/abc_DEF-", "/abc_DEF-12", "/ABC_DEF-1", "/x/abc_DEF-1"):
        assert not gate.accepts(bad), bad
    for token in ("", "a/b", "a?b"):
        with pytest.raises(ValueError, match="access token"):
            AccessGate(token)


@pytest.fixture(scope="module")
def chair() -> Any:
    return make_scene("chair", seed=0)


@pytest.fixture
def public_app(tmp_path: Path, chair: Any) -> Iterator[Any]:
    """The review app bound to every interface (so a token is asked)."""
    from thirdhand.review.app import ReviewApp

    path = tmp_path / "chair.task.json"
    save_task(truth_task(chair), path)
    app = ReviewApp(path, demos=[chair], host="0.0.0.0", port=0, light_rendering=True)
    app.start()
    yield app
    app.stop()


def _subprotocol() -> str:
    import viser

    return f"viser-v{viser.__version__}"


def test_without_the_token_nothing_is_sent_and_nothing_accepted(public_app: Any) -> None:
    from websockets.exceptions import ConnectionClosed
    from websockets.sync.client import connect

    app = public_app
    assert app.gate is not None and len(app.gate.token) >= 20
    assert app.url.endswith(
        f"/?websocket=ws://{app.url.split('//')[1].split('/')[0]}/{app.gate.token}"
    )
    base = f"ws://127.0.0.1:{app.port}"
    for path in ("/", f"/{app.gate.token[:-1]}", f"/{app.gate.token}x"):
        with connect(base + path, subprotocols=[_subprotocol()], open_timeout=20) as ws:  # type: ignore[list-item]
            with pytest.raises(ConnectionClosed) as closed:
                message = ws.recv(timeout=20)
                pytest.fail(f"{path}: received {len(message)} bytes without the token")
            assert closed.value.rcvd is not None and closed.value.rcvd.code == REFUSED_CODE
            with pytest.raises(ConnectionClosed):
                ws.send(b"\x00")
    assert app.gate.refused == 3 and not app.gate.admitted
    assert not app.session.dirty and app.tabs.editor is None
    with connect(
        f"{base}/{app.gate.token}",
        subprotocols=[_subprotocol()],  # type: ignore[list-item]
        open_timeout=20,
    ) as ws:
        assert len(ws.recv(timeout=20)) > 0
    assert len(app.gate.admitted) == 1


@pytest.mark.slow
def test_only_the_printed_url_edits(public_app: Any) -> None:
    """The printed URL edits; the bare address shows no panel and every edit is refused."""
    if not CHROMIUM.exists():
        pytest.skip(f"{CHROMIUM} not found: install Debian's chromium package for browser tests")
    from playwright.sync_api import sync_playwright

    app = public_app
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        try:
            stranger = browser.new_page(viewport={"width": 1280, "height": 900})
            stranger.goto(f"http://127.0.0.1:{app.port}/")
            page = browser.new_page(viewport={"width": 1280, "height": 900})
            page.goto(app_url("127.0.0.1", app.port, app.gate))
            page.get_by_role("button", name="Save", exact=True).wait_for(timeout=TIMEOUT_MS)
            review = Review(app, page, app.task_path)
            review.choose("Object", "leg2")
            review.wait_for(lambda: app.view.selected == "leg2", "selection of leg2")
            review.type_value("x", "12 cm")
            review.button("Apply values").click()
            review.wait_for(
                lambda: selected_constraint(app.task, app.view).pos[0] == 0.12,
                "the edit of the token's tab",
            )
            # The stranger's page has tried (and been refused) at least once meanwhile;
            # viser's client keeps reconnecting, each attempt refused.
            review.wait_for(lambda: app.gate.refused >= 1, "the stranger refused")
            assert stranger.get_by_role("button", name="Save", exact=True).count() == 0
            assert stranger.get_by_text("thirdhand review").count() == 0
            admitted = set(app.gate.admitted)
            assert all(app.tabs.may_edit(c) for c in admitted)
            assert not any(
                app.tabs.may_edit(c) for c in range(max(admitted) + 5) if c not in admitted
            )
            stranger.screenshot(path=str(_artifact("access-refused.png")))
            review.shot("access-token-edits")
        finally:
            browser.close()


def _artifact(name: str) -> Path:
    from tests.test_review_gui import ARTIFACTS

    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    return ARTIFACTS / name
