"""The package as it was at an earlier commit, for tests that compare rollouts bit for bit."""

from __future__ import annotations

import shutil
import subprocess
import tarfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def package_at(commit: str, tmp: Path, name: str) -> Path | None:
    """A folder holding ``smartcar_gym`` as it was at ``commit`` (``git archive`` into
    ``tmp / name``), to put on PYTHONPATH; None without git or without that commit (a shallow
    clone), so the caller can skip with its reason."""
    if shutil.which("git") is None:
        return None
    archive = tmp / f"{name}.tar"
    done = subprocess.run(["git", "-C", str(REPO), "archive", "-o", str(archive), commit,
                           "smartcar_gym"], capture_output=True, timeout=60, check=False)
    if done.returncode != 0:
        return None
    with tarfile.open(archive) as tar:
        tar.extractall(tmp / name, filter="data")
    return tmp / name
