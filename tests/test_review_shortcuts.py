"""Keyboard shortcuts bound to the app (bug 4: Ctrl+Z garbled a pose field) and framing.

The browser test presses the keys in Debian's Chromium; without the listener
(:mod:`thirdhand.review.shortcuts`) Ctrl+Z in a field ran the browser's text
undo and left the app's edit in place.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.test_review_gui import (  # noqa: F401  (fixtures)
    Review,
    chair,
    chromium_browser,
    open_review,
    review,
)
from thirdhand.review.panel_html import fmt_value
from thirdhand.review.scene3d import framed_view
from thirdhand.review.shortcuts import SHORTCUTS, shortcuts_html
from thirdhand.review.view import selected_constraint
from thirdhand.taskfile import load_task


def test_framed_view_keeps_the_direction_and_frames_the_part() -> None:
    eye, target = framed_view(
        np.array([1.0, -1.0, 1.0]), np.zeros(3), np.array([0.2, 0.1, 0.3]), 0.1
    )
    assert target == (0.2, 0.1, 0.3)
    d = np.subtract(eye, target)
    assert np.linalg.norm(d) == pytest.approx(0.3)
    np.testing.assert_allclose(d / np.linalg.norm(d), np.array([1.0, -1.0, 1.0]) / math.sqrt(3))
    # A camera on its target has no direction: a default diagonal; a tiny part gets 5 cm.
    eye, _ = framed_view(np.zeros(3), np.zeros(3), np.zeros(3), 0.001)
    assert np.linalg.norm(eye) == pytest.approx(0.15)


def test_the_listener_presses_only_panel_buttons() -> None:
    text = shortcuts_html()
    for label in set(SHORTCUTS.values()):
        assert f"'{label}'" in text
    assert "<script" not in text and '"' not in text.split('onerror="', 1)[1].split('">', 1)[0]


@pytest.mark.slow
def test_ctrl_z_undoes_the_edit_not_the_text(review: Review) -> None:  # noqa: F811
    """Bug 4: apply x = 12 cm, then Ctrl+Z with the caret in the field: the app's undo
    runs (x back, the field shows it), Ctrl+Y redoes, Ctrl+S saves, F frames leg2."""
    app, page = review.app, review.page
    review.choose("Object", "leg2")
    review.wait_for(lambda: app.view.selected == "leg2", "selection of leg2")
    x0 = selected_constraint(app.task, app.view).pos[0]
    review.type_value("x", "12 cm")
    review.button("Apply values").click()
    review.wait_for(
        lambda: selected_constraint(app.task, app.view).pos[0] == pytest.approx(0.12), "the edit"
    )
    field = review.text_input("x")
    field.click()
    page.keyboard.press("Control+z")
    review.wait_for(lambda: selected_constraint(app.task, app.view).pos[0] == x0, "the app's undo")
    shown = fmt_value("x", x0)
    review.wait_for(lambda: field.input_value() == shown, f"the field to show {shown}")
    assert app.panels.values["x"].value == shown  # the server never got a garbled text
    page.keyboard.press("Control+y")
    review.wait_for(
        lambda: selected_constraint(app.task, app.view).pos[0] == pytest.approx(0.12), "the redo"
    )
    page.keyboard.press("Control+s")
    review.wait_for(lambda: not app.session.dirty, "the save")
    assert load_task(review.path).constraint_by_id(selected_constraint(app.task, app.view).id).pos[
        0
    ] == pytest.approx(0.12)
    page.locator("#th-selected").click()  # the focus leaves the fields (F types there)
    page.keyboard.press("f")
    client = next(iter(app.server.get_clients().values()))
    centre = app.scene.parts.world_centroid("leg2")
    review.wait_for(
        lambda: np.linalg.norm(np.asarray(client.camera.look_at) - centre) < 1e-3,
        "the camera on leg2",
    )
    review.shot("shortcut-frame-selection")
