"""MkDocs hooks: pages show the envs' docstrings (their specs) as the code has them.

A line ``<!-- docstring: package.module.Class -->`` in a page is replaced, at build time, by that
object's docstring (dedented Markdown), so the env reference cannot drift from the code.
"""

from __future__ import annotations

import importlib
import inspect
import re

MARKER = re.compile(r"^<!-- docstring: ([\w.]+) -->$", re.MULTILINE)


def _docstring(path: str) -> str:
    module, _, name = path.rpartition(".")
    obj = getattr(importlib.import_module(module), name)
    doc = inspect.getdoc(obj)
    if not doc:
        raise ValueError(f"{path} has no docstring")
    # the docstring's own sections start at '##'; in a page they sit one level lower
    return re.sub(r"^## ", "### ", doc, flags=re.MULTILINE)


def on_page_markdown(markdown: str, **_: object) -> str:
    return MARKER.sub(lambda match: _docstring(match.group(1)), markdown)
