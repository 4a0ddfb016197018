"""The README's links, which ``mkdocs build --strict`` (run by .ci/run) does not check."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
LINK = re.compile(r"\]\(([^)\s]+)\)")


def _local_links(text: str) -> list[str]:
    return [target for target in LINK.findall(text)
            if not re.match(r"^[a-z][a-z0-9+.-]*:", target) and not target.startswith("#")]


def test_local_links_are_found():
    assert _local_links("[a](docs/env.md) [b](https://x.org) [c](#top) [d](img.png#x)") == [
        "docs/env.md", "img.png#x"]


def test_readme_links_point_to_files_in_the_repository():
    links = _local_links((ROOT / "README.md").read_text())
    assert links, "the README links the docs pages"
    missing = [link for link in links if not (ROOT / link.partition("#")[0]).exists()]
    assert not missing, f"README.md links to missing files: {missing}"

