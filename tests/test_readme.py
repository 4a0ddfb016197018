"""What the README claims about installing and testing matches pyproject.toml and .ci/run, in
words a newcomer can read, on one front page."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

tomllib = pytest.importorskip("tomllib", reason="Python 3.11 reads pyproject.toml")

ROOT = Path(__file__).resolve().parent.parent
README = (ROOT / "README.md").read_text()
#: kept only so that an old ".[video]" still installs (pyproject.toml says so)
LEGACY_EXTRAS = {"video"}


def _extras() -> set[str]:
    data = tomllib.loads((ROOT / "pyproject.toml").read_text())
    return set(data["project"]["optional-dependencies"]) - LEGACY_EXTRAS


def test_the_readme_and_the_install_page_name_every_extra():
    listed = re.search(r"extras (`[a-z]+`(?:,\s+`[a-z]+`)*)", README)
    assert listed, "the README lists the extras"
    assert set(re.findall(r"`([a-z]+)`", listed.group(1))) == _extras()
    table = re.findall(r"^\| `([a-z]+)` \|", (ROOT / "docs" / "index.md").read_text(), re.M)
    assert set(table) == _extras()


def test_the_readme_says_what_ci_adds_to_its_test_command():
    ci = (ROOT / ".ci" / "run").read_text()
    [installed] = re.findall(r'pip install --quiet -e "(\.\[[a-z,]+\])"', ci)
    assert installed in README and 'pip install -e ".[test]"' in README
    for needed, said in (("xvfb", "Xvfb"), ("ros-core", "ROS 1"), ("libosmesa6", "OSMesa"),
                         ("libegl1", "EGL"), ("chromium", "chromium"), ("mkdocs build", "mkdocs")):
        assert needed in ci and said in README, (needed, said)


def test_results_at_a_glance_are_written_for_a_newcomer():
    glance = README.split("## Results at a glance", 1)[1].split("\n## ", 1)[0]
    for jargon in ("round 1", "main-job", "50,000/s and 20x not met"):
        assert jargon not in glance, jargon
    # the default training run: a range over the seeds and machines measured, not one figure
    assert re.search(r"95-100 %.*seeds 0-3 and two machines", glance)
    assert "4.3-7.6 min" in glance


def test_the_readme_stays_a_front_page():
    assert len(README.splitlines()) <= 300
