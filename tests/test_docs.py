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



DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
#: pip installing the package by its PyPI name, which has no release yet
PYPI_INSTALL = re.compile(r"pip install (?:-U )?\"?smartcar-gym\b")


def _version() -> str:
    return re.search(r'^version = "([^"]+)"', (ROOT / "pyproject.toml").read_text(), re.M).group(1)


def test_install_lines_use_a_checkout_or_its_wheel_and_pypi_only_once_released():
    assert PYPI_INSTALL.search('pip install "smartcar-gym[train]"')
    assert not PYPI_INSTALL.search('pip install -e ".[train]"')
    lines = [(path.name, line) for path in DOCS for line in path.read_text().splitlines()]
    wrong = [f"{name}: {line.strip()}" for name, line in lines if PYPI_INSTALL.search(line)
             # a PyPI line says it is for later; "error:" quotes a message the package prints
             and "once released" not in line.lower() and "error:" not in line]
    assert not wrong, f"install lines that name a PyPI release (there is none yet): {wrong}"


def test_the_wheel_the_docs_name_is_this_version():
    names = {name for path in DOCS for name in re.findall(r"smartcar_gym-[^\s/`\"\[]+\.whl",
                                                          path.read_text())}
    assert names == {f"smartcar_gym-{_version()}-py3-none-any.whl"}


def test_the_env_cards_are_written_once_in_the_docstrings():
    import inspect

    import mkdocs_hooks
    from smartcar_gym.envs.smartcar_env import SmartCarEnv
    from smartcar_gym.envs.tasks.barn.task import BarnTask
    from smartcar_gym.envs.tasks.goal import GoalTask
    from smartcar_gym.envs.tasks.nav import NavTask
    from smartcar_gym.envs.tasks.reach import ReachTask

    source = (ROOT / "docs" / "env.md").read_text()
    page = mkdocs_hooks.on_page_markdown(source)
    for env in (SmartCarEnv, ReachTask, NavTask, GoalTask, BarnTask):
        first = inspect.getdoc(env).split("\n\n")[1]            # the description's first paragraph
        assert first in page and first not in source, env.__name__
    assert "<!-- docstring" not in page
    # no hand-made copy of the card beside them: not in the page, not in the README
    for text in (source, (ROOT / "README.md").read_text()):
        assert not re.search(r"^\| (Action|Observation|Reward) \|", text, re.M)


def _layout() -> str:
    page = (ROOT / "docs" / "development.md").read_text()
    return re.search(r"```\n(smartcar_gym/ .*?)```", page, flags=re.S).group(1)


def test_the_layout_names_every_package_and_only_folders_that_exist():
    package = ROOT / "smartcar_gym"
    packages = sorted(str(init.parent.relative_to(package)) for init in package.rglob("__init__.py")
                      if init.parent != package)
    named = re.findall(r"^  ([\w/]+)/ ", _layout(), flags=re.M)
    assert "sim/pybullet" in packages and "envs/vector" in packages, packages
    missing = [path for path in packages if path not in named]
    assert not missing, f"docs/development.md's layout omits {missing}"
    stale = [path for path in named if not (package / path).is_dir()]
    assert not stale, f"docs/development.md's layout names folders that are gone: {stale}"
