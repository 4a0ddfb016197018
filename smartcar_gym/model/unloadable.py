"""Why a simulator may have rejected a URDF file: missing, not a URDF, or a missing mesh.

``smartcar_gym.sim.pybullet.loading`` asks this when pybullet refuses a file (pybullet only says
``Cannot load URDF file.``), to raise a ``ModelError`` naming the file and the reason.
"""

from __future__ import annotations

import os
from pathlib import Path

from smartcar_gym.model.errors import ModelError, read_utf8
from smartcar_gym.model.urdf import parse_xml


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
