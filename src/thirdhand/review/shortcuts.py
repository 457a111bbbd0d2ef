"""Keyboard shortcuts of the review GUI, installed in the browser through an HTML element.

viser 1.1 sends no keyboard events to the server and runs no ``<script>`` of
an HTML element (React's ``dangerouslySetInnerHTML``), but the browser does run
an element's inline event handlers. :func:`shortcuts_html` is an invisible
image whose ``onerror`` handler (an empty ``data:`` image always fails to
decode) installs one ``keydown`` listener on the document, once per page (a
``window`` flag: re-rendering the element does not add a second one). The
listener presses the panel's own buttons, so a shortcut is exactly the click a
person could make (the same checks, the one-editor rule, the access token):

- **Ctrl+Z** (Cmd+Z) → Undo, **Ctrl+Shift+Z** and **Ctrl+Y** → Redo,
  **Ctrl+S** → Save: the browser's default is prevented, also inside a text
  field, so its text undo no longer garbles a pose field (bug 4:
  ``-12.00 cm11.70 cm``) and Ctrl+S no longer opens "save page";
- **F** (no modifier, not while typing in a field) → Frame selection.

The HTML is the server's own constant; no user text goes into it.
"""

from __future__ import annotations

#: Shortcut -> the label of the panel button it presses.
SHORTCUTS: dict[str, str] = {
    "Ctrl+Z": "Undo",
    "Ctrl+Shift+Z": "Redo",
    "Ctrl+Y": "Redo",
    "Ctrl+S": "Save",
    "F": "Frame selection",
}

_LISTENER = (
    "if(!window.__thShortcuts){window.__thShortcuts=1;"
    "var press=function(label){var b=Array.from(document.querySelectorAll('button'))"
    ".find(function(x){return x.textContent.trim()===label;});"
    "if(b&&!b.disabled){b.click();}};"
    "document.addEventListener('keydown',function(e){"
    "var k=(e.key||'').toLowerCase();var mod=e.ctrlKey||e.metaKey;"
    "var t=e.target;var typing=t&&(t.tagName==='INPUT'||t.tagName==='TEXTAREA'"
    "||t.isContentEditable);var label=null;"
    "if(mod&&!e.altKey){if(k==='z'){label=e.shiftKey?'Redo':'Undo';}"
    "else if(k==='y'){label='Redo';}else if(k==='s'){label='Save';}}"
    "else if(!e.altKey&&!typing&&k==='f'){label='Frame selection';}"
    "if(label){e.preventDefault();e.stopPropagation();"
    "if(typing&&label!=='Frame selection'){t.blur();}"
    "setTimeout(function(){press(label);},0);}},true);}"
)


def shortcuts_html() -> str:
    """The HTML element that installs the shortcut listener (see the module docstring)."""
    return (
        '<img alt="" src="data:," style="display:none" id="th-shortcuts" '
        f'onerror="{_LISTENER}">'
        '<div style="padding:0 0.75em;font-size:0.75em;color:#495057">'
        "Ctrl+Z undo, Ctrl+Y redo, Ctrl+S save, F frame the selection; in the 3D view "
        "shift-click a part: new parent of the selection, ctrl-click: animate its DOFs</div>"
    )


__all__ = ["SHORTCUTS", "shortcuts_html"]
