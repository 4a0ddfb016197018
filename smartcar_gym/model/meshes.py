"""Mesh file names of a URDF made absolute, so pybullet finds them wherever the URDF is written.

``package://pkg/rest`` becomes ``<folder of pkg>/rest`` (pkg searched by :func:`find_package`
as for ``$(find pkg)``, asked for by the file holding the mesh); ``file://`` URIs and plain paths
are taken relative to the model file's folder unless absolute. A mesh file that does not exist
is a ModelError naming the file, the line, the mesh filename and where it was looked for.
"""

from __future__ import annotations

import os
import urllib.parse
from collections.abc import Callable
from pathlib import Path

from smartcar_gym.model.errors import ModelError
from smartcar_gym.model.packages import PackagePath, find_package
from smartcar_gym.model.urdf import parse_xml, serialize_xml

#: (mesh filename as written, its line in the URDF text) -> (file, line) to name in errors
Locator = Callable[[str, int | None], tuple[str, int | None]]

PACKAGE = "package://"
FILE = "file://"
EXPECTED = "expected package://PACKAGE/PATH, file://PATH or a file path"


class _Resolver:
    """Resolves the mesh filenames of one model, caching package folders."""

    def __init__(self, base_dir: Path, package_path: PackagePath) -> None:
        self.base_dir = base_dir
        self.package_path = package_path
        self.packages: dict[str, Path] = {}
        self._found: dict[tuple[str, str], Path] = {}

    def package(self, name: str, file: str, line: int | None, filename: str) -> Path:
        """Folder of package ``name`` as asked for by ``file``."""
        if (name, file) not in self._found:
            folder = find_package(name, self.package_path, requested_by=file, line=line,
                                  asked_as=f"mesh '{filename}'")
            self._found[name, file] = folder
            self.packages.setdefault(name, folder)
        return self._found[name, file]

    def target(self, filename: str, file: str, line: int | None) -> tuple[Path, str]:
        """(absolute path of the mesh, how it was found in words)."""
        if filename.startswith(PACKAGE):
            name, _, rest = filename[len(PACKAGE):].partition("/")
            if not name or not rest:
                raise ModelError(f"mesh '{filename}': no package or path; {EXPECTED}",
                                 file=file, line=line)
            folder = self.package(name, file, line, filename)
            return Path(os.path.normpath(folder / rest)), f"package '{name}' is {folder}"
        path = filename
        if filename.startswith(FILE):
            path = urllib.parse.unquote(filename[len(FILE):])
        elif "://" in filename:
            raise ModelError(f"mesh '{filename}': unsupported URI scheme; {EXPECTED}",
                             file=file, line=line)
        resolved = Path(path).expanduser()
        if resolved.is_absolute():
            return resolved, "an absolute path"
        return Path(os.path.normpath(self.base_dir / resolved)), f"relative to {self.base_dir}"


def resolve_meshes(text: str, label: str, *, base_dir: Path, package_path: PackagePath = None,
                   locate: Locator | None = None) -> tuple[str, dict[str, Path]]:
    """URDF text with absolute mesh filenames, and the packages that ``package://`` named.

    ``label`` names the text in errors; ``locate`` maps a mesh to the file and line that hold
    it (default: ``label`` and the line in ``text``). The text is returned unchanged when all
    mesh filenames already are absolute paths of existing files (or there are no meshes).
    """
    locate = locate or (lambda filename, line: (label, line))
    resolver = _Resolver(base_dir, package_path)
    root = parse_xml(text, label)
    changed = False
    for link in root.findall("link"):
        for mesh in link.findall("./*/geometry/mesh"):
            filename = (mesh.get("filename") or "").strip()
            if not filename:
                continue  # parse_urdf reports the missing attribute
            file, line = locate(filename, getattr(mesh, "line", None))
            path, how = resolver.target(filename, file, line)
            if not path.is_file():
                raise ModelError(f"mesh '{filename}' not found: looked for {path} ({how}); "
                                 "expected an existing mesh file", file=file, line=line)
            if os.fspath(path) != filename:
                mesh.set("filename", os.fspath(path))
                changed = True
    return (serialize_xml(root) if changed else text), resolver.packages
