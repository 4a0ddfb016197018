"""Resolve ``$(find pkg)`` and ``package://pkg`` without ROS: search folders for a ROS package.

Search order, first match wins:

0. when the asking file is one of the shipped descriptions: the shipped descriptions, so the
   shipped model resolves its own includes from the installed package whatever
   ``ROS_PACKAGE_PATH`` holds (a user's workspace with the tutorial's ``smartcar_description``
   on it does not replace our files with the tutorial's);
1. the explicit ``package_path`` folders, then ``ROS_PACKAGE_PATH`` (``os.pathsep``-separated):
   each folder itself, then its subfolders breadth first (hidden folders, ``*_IGNORE``-marked
   folders and the inside of packages are skipped, as rospack does);
2. the folders enclosing the file that asks, closest first (each folder itself only), so a
   description checked out anywhere finds its own package;
3. the description folder shipped with smartcar_gym (ours answers to ``smartcar_description``).

A folder is package ``pkg`` if its ``package.xml`` says ``<name>pkg</name>`` or, having no
``package.xml``, if it is named ``pkg``.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from collections import deque
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path

from smartcar_gym.model.errors import ModelError

SHIPPED_DESCRIPTIONS = Path(__file__).resolve().parent.parent / "description"
MAX_DEPTH = 5
_IGNORE_MARKERS = ("CATKIN_IGNORE", "COLCON_IGNORE", "AMENT_IGNORE")

PackagePath = Iterable[str | os.PathLike] | str | os.PathLike | None


def check_package_path(package_path: object) -> list[str | os.PathLike] | None:
    """``package_path`` as a list of folders (one folder or None accepted as well).

    ModelError naming the argument and what was expected if it is anything else.
    """
    if package_path is None:
        return None
    if isinstance(package_path, str | os.PathLike):
        return [package_path]
    expected = "expected a list of folders (str or os.PathLike), one folder, or None"
    if isinstance(package_path, bytes | Mapping) or not isinstance(package_path, Iterable):
        raise ModelError(f"package_path={package_path!r}: {expected}")
    folders = list(package_path)
    for i, folder in enumerate(folders):
        if not isinstance(folder, str | os.PathLike):
            raise ModelError(f"package_path[{i}]={folder!r}: expected a folder (str or "
                             f"os.PathLike); package_path: {expected}")
    return folders


def _path_roots(package_path: PackagePath) -> list[Path]:
    """package_path folders, then ROS_PACKAGE_PATH folders (searched with their subfolders)."""
    if isinstance(package_path, str | os.PathLike):
        package_path = [package_path]
    roots = [Path(p).expanduser().resolve() for p in package_path or ()]
    env = os.environ.get("ROS_PACKAGE_PATH", "")
    roots += [Path(p).expanduser().resolve() for p in env.split(os.pathsep) if p.strip()]
    return roots


def enclosing_folders(file: str | os.PathLike | None) -> list[Path]:
    """The folders holding ``file``, closest first (none for None)."""
    if file is None:
        return []
    return list(Path(file).expanduser().resolve().parents)


def is_shipped(file: str | os.PathLike | None) -> bool:
    """Whether ``file`` is one of the descriptions shipped with smartcar_gym."""
    return file is not None and Path(file).expanduser().resolve().is_relative_to(
        SHIPPED_DESCRIPTIONS)


def _search_plan(package_path: PackagePath,
                 requested_by: str | os.PathLike | None) -> list[tuple[Path, bool]]:
    """(folder, search its subfolders too) in search order, each folder once."""
    plan = [(SHIPPED_DESCRIPTIONS, True)] if is_shipped(requested_by) else []
    plan += [(root, True) for root in _path_roots(package_path)]
    plan += [(folder, False) for folder in enclosing_folders(requested_by)]
    plan.append((SHIPPED_DESCRIPTIONS, True))
    unique: dict[Path, bool] = {}
    for folder, descend in plan:
        unique.setdefault(folder, descend)
    return list(unique.items())


def search_roots(package_path: PackagePath = None,
                 requested_by: str | os.PathLike | None = None) -> list[Path]:
    """The folders searched for packages, highest priority first (see the module docstring)."""
    return [folder for folder, _ in _search_plan(package_path, requested_by)]


def package_name(folder: Path) -> str | None:
    """The package a folder holds: its package.xml <name>, else None (no or unreadable xml)."""
    manifest = folder / "package.xml"
    if not manifest.is_file():
        return None
    try:
        name = ET.parse(manifest).getroot().findtext("name")
    except (ET.ParseError, OSError):
        return None
    return name.strip() if name else None


def is_package(folder: Path, name: str) -> bool:
    """Whether ``folder`` is package ``name`` (package.xml name, else the folder name)."""
    declared = package_name(folder)
    return declared == name or (declared is None and folder.name == name)


def _candidates(root: Path) -> Iterator[Path]:
    """Folders under root (root included), breadth first, not entering packages."""
    queue: deque[tuple[Path, int]] = deque([(root, 0)])
    while queue:
        folder, depth = queue.popleft()
        yield folder
        if depth >= MAX_DEPTH or (folder / "package.xml").is_file():
            continue
        try:
            children = sorted(p for p in folder.iterdir() if p.is_dir())
        except OSError:
            continue
        for child in children:
            if child.name.startswith(".") or any((child / m).exists() for m in _IGNORE_MARKERS):
                continue
            queue.append((child, depth + 1))


def _searched(package_path: PackagePath, requested_by: str | os.PathLike | None) -> str:
    """Where a package was looked for, in words, for error messages."""
    roots = _path_roots(package_path)
    parts = [f"the shipped descriptions {SHIPPED_DESCRIPTIONS} (asked for by a shipped file)"
             ] if is_shipped(requested_by) else []
    parts += [("package_path/ROS_PACKAGE_PATH folders " + ", ".join(map(str, roots))
              + " and their subfolders") if roots else "no package_path or ROS_PACKAGE_PATH"]
    if requested_by is not None:
        parts.append(f"the folders enclosing {Path(requested_by).name}")
    parts.append(f"the shipped descriptions {SHIPPED_DESCRIPTIONS}")
    return "; ".join(parts)


def find_package(
    name: str,
    package_path: PackagePath = None,
    *,
    requested_by: str | os.PathLike | None = None,
    line: int | None = None,
    asked_as: str | None = None,
) -> Path:
    """Folder of ROS package ``name``, searched in the module docstring's order.

    ``requested_by`` is the file that asks (its enclosing folders are searched); a package
    that is not found is a ModelError naming that file, ``line``, what asked for it
    (``asked_as``, default ``$(find name)``) and the folders searched.
    """
    for folder, descend in _search_plan(package_path, requested_by):
        if not folder.is_dir():
            continue
        for candidate in _candidates(folder) if descend else (folder,):
            if is_package(candidate, name):
                return candidate
    raise ModelError(
        f"package '{name}' not found (asked for by {asked_as or f'$(find {name})'}); "
        f"searched {_searched(package_path, requested_by)}; pass package_path=[...] or set "
        "ROS_PACKAGE_PATH to the folder holding it",
        file=requested_by,
        line=line,
    )
