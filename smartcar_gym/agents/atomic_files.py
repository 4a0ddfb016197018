"""Files written atomically, and whether a file can be written at all.

Files are written atomically (a temporary file in the same folder, then ``os.replace``), so a
run killed at any moment leaves either the previous file or the new one, never half a file.
A model ``<stem>.zip`` keeps its ``VecNormalize`` statistics in ``<stem>_vecnormalize.pkl``
(``model.zip`` in ``vecnormalize.pkl``); ``save_model_atomic``, ``move_model_atomic`` and
``remove_model`` handle both. The names of checkpoints are ``runs``'s.
"""

from __future__ import annotations

import contextlib
import os
import pickle
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from smartcar_gym.agents.models import vecnormalize_path_for

if TYPE_CHECKING:
    from stable_baselines3.common.base_class import BaseAlgorithm



def file_mode() -> int:
    """The mode of a new file as ``open()`` makes it: 0666 less the process's umask."""
    umask = os.umask(0o022)  # reading the umask means setting it; it is put back at once
    os.umask(umask)
    return 0o666 & ~umask


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """A temporary path next to ``path`` (same suffix) that replaces ``path`` once written.

    If the body raises (or the process dies), ``path`` is left as it was. The file gets the
    mode of any new file (``file_mode``), as the Monitor and TensorBoard files do.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=path.suffix)
    os.close(fd)
    try:
        yield Path(tmp)
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())
        os.chmod(tmp, file_mode())  # mkstemp makes 0600 files; a run's files are all alike
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` to ``path`` atomically."""
    atomic_write_bytes(path, text.encode())


def save_model_atomic(model: BaseAlgorithm, path: str | os.PathLike) -> Path:
    """Save ``model`` (and its VecNormalize statistics, if any) atomically; returns the zip path.

    Both files are written to temporary files first, then renamed: the statistics, then the
    zip. So a new zip (a checkpoint) always has its statistics beside it. When an existing pair
    is replaced (``model.zip``, ``best_model.zip``), a kill in the few milliseconds between the
    two renames leaves the new statistics beside the old model; nothing is ever half-written.
    """
    path = Path(path)
    vec_normalize = model.get_vec_normalize_env()
    with contextlib.ExitStack() as stack:  # exits (renames) in reverse order: statistics first
        tmp_zip = stack.enter_context(atomic_path(path))
        if vec_normalize is not None:
            tmp_stats = stack.enter_context(atomic_path(vecnormalize_path_for(path)))
            tmp_stats.write_bytes(pickle.dumps(vec_normalize))
        model.save(tmp_zip)
    return path


def move_model_atomic(source: str | os.PathLike, path: str | os.PathLike) -> Path:
    """Move a model saved by ``save_model_atomic`` (and its statistics) onto ``path``, in
    ``save_model_atomic``'s order: the statistics, then the zip, each by one rename."""
    source, path = Path(source), Path(path)
    stats = vecnormalize_path_for(source)
    if stats.exists():
        os.replace(stats, vecnormalize_path_for(path))
    os.replace(source, path)
    return path


def remove_model(path: str | os.PathLike) -> None:
    """Remove a model saved by ``save_model_atomic`` and its statistics, if they exist."""
    path = Path(path)
    vecnormalize_path_for(path).unlink(missing_ok=True)
    path.unlink(missing_ok=True)


def output_path_error(path: Path) -> str | None:
    """Why a file cannot be written at ``path`` (None if it can; missing folders are created)."""
    if path.is_dir():
        return f"{path} is a directory"
    if path.exists() and not os.access(path, os.W_OK):
        return f"{path} is not writable"
    folder = path.parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir():
        return f"cannot create {path}: {folder} is not a folder"
    if not os.access(folder, os.W_OK | os.X_OK):
        return f"cannot create {path}: {folder} is not writable"
    return None
