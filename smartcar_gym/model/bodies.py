"""Load a URDF file into pybullet quietly; a file pybullet rejects is a ``ModelError``.

pybullet prints its importer's complaints (``b3Error``/``b3Warning`` lines) on the C-level
stdout and raises a bare ``error('Cannot load URDF file.')``. We silence the former and turn
the latter into a ModelError naming the file and, where we can tell, why: the file is missing,
is no valid URDF, or names a mesh file that does not exist (the line of the mesh).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from smartcar_gym._bullet import bullet_client, pybullet, silenced_output
from smartcar_gym.model.errors import ModelError, read_utf8
from smartcar_gym.model.urdf import parse_xml


def load_body(client: bullet_client.BulletClient, path: str | os.PathLike,
              position: Sequence[float] = (0.0, 0.0, 0.0),
              orientation: Sequence[float] = (0.0, 0.0, 0.0, 1.0), flags: int = 0) -> int:
    """``client.loadURDF`` without pybullet's console output; ModelError if it fails."""
    with silenced_output():
        try:
            return client.loadURDF(os.fspath(path), list(position), list(orientation),
                                   flags=flags)
        except pybullet.error as exc:
            failure = " ".join(str(exc).split())
    reason, line = why_unloadable(Path(path))
    raise ModelError(f"pybullet cannot load this URDF ({failure}): {reason}", file=path,
                     line=line)


def why_unloadable(path: Path) -> tuple[str, int | None]:
    """(why pybullet may have rejected the URDF at ``path``, line or None), best effort."""
    if not path.is_file():
        return "no such file; expected an existing URDF file", None
    try:
        root = parse_xml(read_utf8(path), str(path))
    except ModelError as exc:
        return exc.message, exc.line
    for mesh in root.iter("mesh"):
        filename = mesh.get("filename", "")
        local = filename.removeprefix("file://")
        if not filename or "://" in local:
            continue
        target = Path(os.path.normpath(path.parent / local))
        if not target.is_file():
            return (f"mesh '{filename}' not found (looked for {target}); expected an existing "
                    "mesh file (load_model makes mesh paths absolute and checks them)",
                    getattr(mesh, "line", None))
    return ("pybullet's URDF importer rejected it (its messages are silenced); expected a URDF "
            "that pybullet can import"), None
