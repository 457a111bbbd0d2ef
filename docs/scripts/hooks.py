"""MkDocs hooks of the documentation site (mkdocs.yml ``hooks``).

The docstrings cross-reference with Sphinx roles (``:func:`learn_task```), which
mkdocstrings leaves as text before the code span; the API pages show the code span
alone.
"""

from __future__ import annotations

import re
from typing import Any

_ROLE = re.compile(r":(?:py:)?(?:func|class|mod|meth|data|attr|obj|exc|const):(?=<code>)")


def on_page_content(html: str, **kwargs: Any) -> str:
    """Drop the Sphinx role prefixes in front of code spans."""
    return _ROLE.sub("", html)
