"""Load a URDF file into pybullet quietly; a file pybullet rejects is a ``ModelError``.

pybullet prints its importer's complaints (``b3Error``/``b3Warning`` lines) on the C-level
stdout and raises a bare ``error('Cannot load URDF file.')``. We silence the former and turn
the latter into a ModelError naming the file and, where we can tell, why (the file is missing,
is no valid URDF, or names a mesh file that does not exist: the line of the mesh).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from smartcar_gym.model.errors import ModelError
from smartcar_gym.model.unloadable import why_unloadable
from smartcar_gym.sim.pybullet.bullet import bullet_client, pybullet, silenced_output


def load_body(client: bullet_client.BulletClient, path: str | os.PathLike,
              position: Sequence[float] = (0.0, 0.0, 0.0),
              orientation: Sequence[float] = (0.0, 0.0, 0.0, 1.0), flags: int = 0,
              fixed: bool = False) -> int:
    """``client.loadURDF`` without pybullet's console output; ModelError if it fails."""
    with silenced_output():
        try:
            return client.loadURDF(os.fspath(path), list(position), list(orientation),
                                   useFixedBase=fixed, flags=flags)
        except pybullet.error as exc:
            failure = " ".join(str(exc).split())
    reason, line = why_unloadable(Path(path))
    raise ModelError(f"pybullet cannot load this URDF ({failure}): {reason}", file=path,
                     line=line)
