"""The bounding box of a collision mesh's vertices (OBJ and STL files), for ``footprint``."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

_STL_HEADER = 84  # 80 bytes of header, then a uint32 triangle count
_STL_TRIANGLE = np.dtype([("normal", "<f4", 3), ("vertices", "<f4", (3, 3)), ("attr", "<u2")])


def mesh_bounds(filename: str | os.PathLike, link: str = "") -> tuple[np.ndarray, np.ndarray]:
    """The lowest and highest x, y, z of the vertices in mesh file ``filename`` (its own units
    and frame, unscaled). ValueError naming the file (and ``link``) if it cannot be read, is
    not OBJ or STL, or has no vertices."""
    path = Path(filename)
    where = f"link {link!r}: collision mesh {path}" if link else f"collision mesh {path}"
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise ValueError(f"{where}: cannot read it ({exc.strerror})") from None
    suffix = path.suffix.lower()
    if suffix == ".obj":
        vertices = _obj_vertices(data, where)
    elif suffix == ".stl":
        vertices = _stl_vertices(data, where)
    else:
        raise ValueError(f"{where}: the planar footprint reads OBJ and STL meshes, not "
                         f"{suffix or 'this file'}")
    if len(vertices) == 0:
        raise ValueError(f"{where}: no vertices")
    return vertices.min(axis=0), vertices.max(axis=0)


def _obj_vertices(data: bytes, where: str) -> np.ndarray:
    rows = []
    for number, line in enumerate(data.decode("utf-8", errors="replace").splitlines(), 1):
        fields = line.split()
        if fields[:1] == ["v"]:
            try:
                rows.append([float(v) for v in fields[1:4]])
            except ValueError:
                raise ValueError(f"{where}: line {number}: a vertex of three numbers expected, "
                                 f"got {line.strip()!r}") from None
            if len(rows[-1]) != 3:
                raise ValueError(f"{where}: line {number}: a vertex of three numbers expected, "
                                 f"got {line.strip()!r}")
    return np.array(rows, dtype=float).reshape(-1, 3)


def _stl_vertices(data: bytes, where: str) -> np.ndarray:
    if len(data) >= _STL_HEADER:
        count = int(np.frombuffer(data, "<u4", 1, 80)[0])
        if len(data) == _STL_HEADER + count * _STL_TRIANGLE.itemsize:  # binary
            triangles = np.frombuffer(data, _STL_TRIANGLE, count, _STL_HEADER)
            return triangles["vertices"].reshape(-1, 3).astype(float)
    text = data.decode("utf-8", errors="replace")
    if not text.lstrip().startswith("solid"):
        raise ValueError(f"{where}: neither a binary STL (size does not match its triangle "
                         "count) nor an ASCII STL (no 'solid')")
    rows = [line.split()[1:4] for line in text.splitlines() if line.strip().startswith("vertex")]
    try:
        return np.array(rows, dtype=float).reshape(-1, 3)
    except ValueError:
        raise ValueError(f"{where}: an ASCII STL vertex is not three numbers") from None
