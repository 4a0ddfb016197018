"""Resolve ``$(find pkg)`` without ROS: search folders for a ROS package by name.

Search order: the explicit ``package_path`` folders, then ``ROS_PACKAGE_PATH``
(``os.pathsep``-separated), then the description folder shipped with smartcar_gym.
A folder is package ``pkg`` if its ``package.xml`` says ``<name>pkg</name>`` or, having
no ``package.xml``, if it is named ``pkg``. Each root is searched itself, then its
subfolders breadth first (hidden folders, ``*_IGNORE``-marked folders and the inside of
packages are skipped, as rospack does).
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from collections import deque
from collections.abc import Iterable, Iterator
from pathlib import Path

from smartcar_gym.model.errors import ModelError

SHIPPED_DESCRIPTIONS = Path(__file__).resolve().parent.parent / "description"
MAX_DEPTH = 5
_IGNORE_MARKERS = ("CATKIN_IGNORE", "COLCON_IGNORE", "AMENT_IGNORE")

PackagePath = Iterable[str | os.PathLike] | str | os.PathLike | None


def search_roots(package_path: PackagePath = None) -> list[Path]:
    """The folders searched for packages, highest priority first."""
    if isinstance(package_path, str | os.PathLike):
        package_path = [package_path]
    roots = [Path(p).expanduser().resolve() for p in package_path or ()]
    env = os.environ.get("ROS_PACKAGE_PATH", "")
    roots += [Path(p).expanduser().resolve() for p in env.split(os.pathsep) if p.strip()]
    roots.append(SHIPPED_DESCRIPTIONS)
    unique: list[Path] = []
    for root in roots:
        if root not in unique:
            unique.append(root)
    return unique


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


def find_package(
    name: str,
    package_path: PackagePath = None,
    *,
    requested_by: str | os.PathLike | None = None,
    line: int | None = None,
) -> Path:
    """Folder of ROS package ``name``; ModelError naming the asker and the folders searched."""
    roots = search_roots(package_path)
    for root in roots:
        if not root.is_dir():
            continue
        for folder in _candidates(root):
            declared = package_name(folder)
            if declared == name or (declared is None and folder.name == name):
                return folder
    searched = ", ".join(str(r) for r in roots)
    raise ModelError(
        f"package '{name}' not found (asked for by $(find {name})); searched {searched} "
        "and their subfolders; pass package_path=[...] or set ROS_PACKAGE_PATH to the folder "
        "holding it",
        file=requested_by,
        line=line,
    )
