"""The episodes of an evaluation as a Minari dataset: ``smartcar-eval --minari DATASET_ID``.

``write_dataset`` stores the ``steps.EpisodeSteps`` episodes (observations, actions, rewards,
terminations, truncations, array infos, each episode's seed) under Minari's local root
(``MINARI_DATASETS_PATH``, else ``~/.minari/datasets``) in Minari's default format. Its env
spec is the registered one with the evaluation's kwargs (engine included), so
``dataset.recover_environment()`` makes the env the episodes ran in. The reference scores are
the mean returns of uniform random actions (``ref_min_score``) and of the shipped policy
trained on the env (``ref_max_score``: ``agents.references.shipped_reference``) over the first
``REFERENCE_EPISODES`` of the same seeds; the description says which policy, engine and seeds
made the dataset. ``check_datasets_root`` refuses a root that cannot hold folders and
``check_dataset_id`` a malformed id or an existing one (unless ``overwrite``; never a folder
that is no dataset) before anything is evaluated; ``missing_minari`` names a missing extra.

The dataset is written under a hidden scratch folder of the root (Minari lists no hidden
folder) and moved to its id only when complete: an existing dataset of the id is replaced
only then, and a failure leaves it, and the root, as they were.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import tempfile
import warnings
from collections.abc import Iterator, Sequence
from importlib import metadata as package_metadata
from pathlib import Path
from typing import Any

import gymnasium as gym

from smartcar_gym.datasets.steps import EpisodeSteps
from smartcar_gym.registration import MAKE_KEYWORDS
from smartcar_gym.sim.engines import DEFAULT_ENGINE, get_engine

__all__ = ["DATASETS_VARIABLE", "MINARI_EXTRA", "REFERENCE_EPISODES", "DatasetError",
           "References", "check_dataset_id", "check_datasets_root", "env_spec",
           "missing_minari", "write_dataset"]

#: the environment variable naming Minari's local root
DATASETS_VARIABLE = "MINARI_DATASETS_PATH"

MINARI_EXTRA = 'pip install "smartcar-gym[minari]"'
#: episodes (the first seeds of the evaluation's) each reference score is averaged over
REFERENCE_EPISODES = 100
CODE_PERMALINK = "https://github.com/smartcar-gym/smartcar-gym"


def missing_minari() -> str | None:
    """One line naming what the ``minari`` extra would bring, or None if it is installed."""
    from smartcar_gym.extras import missing_modules

    missing = missing_modules(("minari", "h5py"))
    if not missing:
        return None
    return f"{', '.join(missing)} not installed; Minari datasets need the minari extra: " \
           f"{MINARI_EXTRA}"


class DatasetError(ValueError):
    """A dataset that cannot be written where asked (one line)."""


def _datasets_root() -> tuple[Path | None, str]:
    """Minari's local root (None for an empty variable) and how to name it in a refusal."""
    value = os.environ.get(DATASETS_VARIABLE)
    if value is None:
        root = Path.home() / ".minari" / "datasets"
        return root, f"Minari's default folder {root} ({DATASETS_VARIABLE} is not set)"
    return (Path(value) if value else None), f"{DATASETS_VARIABLE}={value!r}"


def check_datasets_root() -> str | None:
    """The problem with Minari's local root (one line naming ``MINARI_DATASETS_PATH`` and its
    value), or None: empty, a file, under a file, or a folder that cannot be written."""
    root, named = _datasets_root()
    if root is None:
        return f"{named} is empty; expected the folder Minari keeps its datasets in"
    existing = root
    while not existing.exists() and existing.parent != existing:
        existing = existing.parent  # the nearest part of the path that exists
    if not existing.is_dir():
        where = "is" if existing == root else f"is under {existing}, which is"
        return (f"{named} {where} a file, not a folder; expected the folder Minari keeps "
                "its datasets in")
    if not os.access(existing, os.W_OK | os.X_OK):
        return f"{named}: {existing} is not writable; Minari writes its datasets there"
    return None


def _is_dataset(path: Path) -> bool:
    return (path / "data" / "metadata.json").is_file()


def _holds_files(path: Path) -> bool:
    """Whether ``path`` is, or holds, anything but folders (an empty tree holds nothing)."""
    if path.is_symlink() or not path.is_dir():
        return True
    return any(part.is_symlink() or not part.is_dir() for part in path.rglob("*"))


def check_dataset_id(dataset_id: str, overwrite: bool = False) -> str | None:
    """The problem with writing ``dataset_id`` (one line), or None: a malformed id (Minari's
    ``(namespace/)name-vN``), an existing dataset without ``overwrite``, an id that names
    something other than a dataset or lies inside a dataset or a file (even with
    ``overwrite``: only a dataset, or folders with no file in them, are replaced)."""
    from minari.dataset.minari_dataset import parse_dataset_id
    from minari.storage import get_dataset_path

    try:
        if parse_dataset_id(dataset_id)[2] is None:
            raise ValueError
    except (ValueError, TypeError):
        return (f"{dataset_id!r} is not a Minari dataset id: expected (namespace/)name-vN, "
                "e.g. smartcar/default-pybullet-v0 (letters, digits, - and _)")
    root = get_dataset_path()
    path = get_dataset_path(dataset_id)
    for parent in reversed(path.relative_to(root).parents[:-1]):  # its namespaces
        folder = root / parent
        if folder.exists() and not folder.is_dir():
            return (f"the dataset {dataset_id} would go under {folder}, which is a file; "
                    "pick another id")
        if _is_dataset(folder):
            return (f"the dataset {dataset_id} would go inside the dataset {parent.as_posix()} "
                    f"({folder}); pick another id")
    if _is_dataset(path):
        if not overwrite:
            return f"the dataset {dataset_id} exists ({path}); pass --overwrite to replace it"
    elif path.exists() or path.is_symlink():
        if _holds_files(path):
            return (f"{path} exists and is not a Minari dataset (no data/metadata.json); "
                    "remove it or pick another id")
        if not overwrite:
            return (f"{path} exists, empty folders with no dataset in them; pass --overwrite "
                    "to replace it")
    return None


@dataclasses.dataclass
class References:
    """The reference scores (None where not measured) and what they come from."""

    min_score: float | None
    max_score: float | None
    episodes: int
    max_policy: str | None
    note: str


def _description(n: int, policy: str, algo: str | None, env_id: str, env_kwargs: dict,
                 seed: int, deterministic: bool, vectorization: str,
                 references: References) -> str:
    engine = env_kwargs.get("engine") or DEFAULT_ENGINE
    kwargs = ", ".join(f"{k}={v!r}" for k, v in sorted(env_kwargs.items())) or "none"
    seeds = f"seed {seed}" if n == 1 else f"seeds {seed}..{seed + n - 1}"
    text = (f"{n} episodes of the policy {policy} ({(algo or 'unknown').upper()}, "
            f"{'deterministic' if deterministic else 'sampled'} actions) on {env_id}, engine "
            f"{engine} (env kwargs: {kwargs}), {seeds} (episode i: seed {seed}+i), written by "
            f"smartcar-eval --vectorization {vectorization} --minari.")
    if references.max_score is not None:
        text += (f" Reference scores: uniform random actions {references.min_score:.3f} and "
                 f"the shipped policy {references.max_policy} {references.max_score:.3f} "
                 f"(mean returns over the first {references.episodes} of these seeds).")
    elif references.note:
        text += f" ({references.note}.)"
    return text


def _common_infos(episodes: Sequence[EpisodeSteps.Episode]) -> list[str]:
    """The info keys every episode has, with one shape per step and one dtype."""
    first = episodes[0].infos
    return [key for key in first
            if all(key in ep.infos and ep.infos[key].shape[1:] == first[key].shape[1:]
                   and ep.infos[key].dtype == first[key].dtype for ep in episodes)]


def env_spec(env_id: str, env_kwargs: dict[str, Any]) -> gym.envs.registration.EnvSpec:
    """The registered spec of ``env_id`` with the evaluation's kwargs: gym.make's own keywords
    (``max_episode_steps``: -1 no limit, ``disable_env_checker``) as the spec's fields, the
    others in its kwargs, so ``gym.make(spec)`` makes the env ``gym.make(env_id,
    **env_kwargs)`` made."""
    registered = gym.spec(env_id)
    kwargs = dict(env_kwargs)
    fields: dict[str, Any] = {}
    for key in MAKE_KEYWORDS:
        value = kwargs.pop(key, None)
        if value is not None:
            fields[key] = None if key == "max_episode_steps" and value == -1 else value
    return dataclasses.replace(registered, kwargs={**registered.kwargs, **kwargs}, **fields)


@contextlib.contextmanager
def _datasets_path(path: Path) -> Iterator[None]:
    """Minari's local root is ``path`` inside the block."""
    before = os.environ.get(DATASETS_VARIABLE)
    os.environ[DATASETS_VARIABLE] = str(path)
    try:
        yield
    finally:
        if before is None:
            del os.environ[DATASETS_VARIABLE]
        else:
            os.environ[DATASETS_VARIABLE] = before


def _move_in(new: Path, final: Path, scratch: Path) -> None:
    """``new`` becomes ``final``; what ``final`` was (a dataset, empty folders) goes to
    ``scratch``, and comes back if the move fails."""
    final.parent.mkdir(parents=True, exist_ok=True)
    old = None
    if final.exists() or final.is_symlink():
        old = scratch / "replaced"
        os.replace(final, old)
    try:
        os.replace(new, final)
    except BaseException:
        if old is not None:
            os.replace(old, final)
        raise


def write_dataset(dataset_id: str, episodes: Sequence[EpisodeSteps.Episode], *, env_id: str,
                  env_kwargs: dict[str, Any], policy: str, algo: str | None, seed: int,
                  deterministic: bool, vectorization: str, references: References,
                  overwrite: bool = False) -> Any:
    """Write ``episodes`` as the Minari dataset ``dataset_id`` (see the module docstring):
    complete in a scratch folder first, then moved to the id (replacing an existing dataset
    only with ``overwrite``); returns the ``MinariDataset``. ``DatasetError`` (one line) for a
    root or id the checks refuse; on any failure the root is as it was."""
    import minari
    from minari.data_collector import EpisodeBuffer
    from minari.dataset.minari_dataset import parse_dataset_id
    from minari.namespace import create_namespace, list_local_namespaces
    from minari.storage import get_dataset_path

    problem = check_datasets_root() or check_dataset_id(dataset_id, overwrite)
    if problem:
        raise DatasetError(problem)
    spec = env_spec(env_id, env_kwargs)
    keys = _common_infos(episodes)
    buffers = [EpisodeBuffer(seed=ep.seed, observations=ep.observations, actions=ep.actions,
                             rewards=ep.rewards, terminations=ep.terminations,
                             truncations=ep.truncations,
                             infos={key: ep.infos[key] for key in keys})
               for ep in episodes]
    requirements = [f"smartcar-gym=={package_metadata.version('smartcar-gym')}"]
    requirements += get_engine(env_kwargs.get("engine") or DEFAULT_ENGINE).requirements
    root = get_dataset_path()
    with tempfile.TemporaryDirectory(prefix=".smartcar-eval-", dir=root) as scratch:
        with _datasets_path(Path(scratch) / "datasets"), warnings.catch_warnings():
            # a contact beyond the project's page: none to give
            warnings.filterwarnings("ignore", message="`author_email` is set to None")
            minari.create_dataset_from_buffers(
                dataset_id, buffers, env=spec, eval_env=spec,
                algorithm_name=f"{(algo or 'unknown').upper()} ({policy})",
                code_permalink=CODE_PERMALINK, author="smartcar-eval",
                ref_min_score=references.min_score, ref_max_score=references.max_score,
                num_episodes_average_score=references.episodes,
                description=_description(len(episodes), policy, algo, env_id, env_kwargs,
                                         seed, deterministic, vectorization, references),
                requirements=requirements)
        namespace = parse_dataset_id(dataset_id)[0]
        if namespace is not None and namespace not in list_local_namespaces():
            create_namespace(namespace)
        _move_in(Path(scratch) / "datasets" / dataset_id, get_dataset_path(dataset_id),
                 Path(scratch))
    return minari.load_dataset(dataset_id)
