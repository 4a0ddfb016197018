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


def _pybullet_rates_of_the_main_command() -> list[int]:
    """Success on pybullet of every seed of docs/planar.md's table for the README's main run."""
    section = (ROOT / "docs" / "planar.md").read_text().split("## Training on planar", 1)[1]
    table = section[section.index("| seed |"):].split("\n\n", 1)[0].splitlines()
    column = [cell.strip() for cell in table[0].split("|")].index("on pybullet")
    return [int(re.search(r"\d+", row.split("|")[column]).group()) for row in table[2:]]


def test_the_first_screen_says_what_it_is_and_installs_trains_and_evaluates_apart():
    lines = README.splitlines()
    first = next(i for i, line in enumerate(lines) if line.startswith("```bash"))
    assert first < 30, "the first command is on screen"
    blocks = re.findall(r"```bash\n(.*?)```", README, flags=re.S)
    # the main job is one copyable block: install, train and evaluate, a command a line
    install, train, evaluate = blocks[0].strip().splitlines()
    assert install.strip() == ("python3 -m venv .venv && . .venv/bin/activate && "
                               'pip install torch==2.13.0 && pip install -e ".[train,fast]"')
    assert train.strip().startswith("smartcar-train ") and "&&" not in train
    assert evaluate.strip().startswith("smartcar-eval ") and "&&" not in evaluate
    assert 'pip install -e ".[test]" && ruff check . && python -m pytest -q' in blocks[1]


def test_the_first_screen_gives_the_success_range_over_every_seed_measured():
    rates = _pybullet_rates_of_the_main_command()
    assert len(rates) >= 8, rates
    screen = README.split("## Quick start", 1)[0]
    assert f"every seed measured (0-{len(rates) - 1})" in screen
    assert f"**{min(rates)}-{max(rates)} %**" in screen
    policies = README.split("## Results", 1)[1]
    assert f"| {min(rates)}-{max(rates)} % (seeds 0-{len(rates) - 1}) |" in policies


def _tables(text: str) -> list[list[str]]:
    return [block.splitlines() for block in re.findall(r"(?:^\|.*\n)+", text, flags=re.M)]


def test_results_are_three_short_tables_each_linking_its_page():
    results = README.split("## Results", 1)[1].split("\n## ", 1)[0]
    tables = _tables(results)
    assert len(tables) == 3
    assert tables[0][0] == ("| env | algorithm | trained on | evaluated on | success | "
                            "training time |")
    for intro in re.split(r"(?:^\|.*\n)+", results, flags=re.M)[:3]:
        assert re.search(r"\]\(docs/[a-z_]+\.md", intro), intro
    for jargon in ("round 1", "main-job", "gate", "interleaved"):
        assert jargon not in results, jargon


def test_the_readme_stays_a_front_page():
    assert len(re.findall(r"\S+", README)) < 1200
    longest = max(len(line) for table in _tables(README) for line in table)
    assert longest <= 300, longest
    assert "![" in README, "a picture"
