"""The episodes of an evaluation as a Minari dataset: ``smartcar-eval --minari DATASET_ID``.

``write_dataset`` stores the ``steps.EpisodeSteps`` episodes (observations, actions, rewards,
terminations, truncations, array infos, each episode's seed) under Minari's local root
(``MINARI_DATASETS_PATH``, else ``~/.minari/datasets``) in Minari's default format. Its env
spec is the registered one with the evaluation's kwargs (engine included), so
``dataset.recover_environment()`` makes the env the episodes ran in. The reference scores are
the mean returns of uniform random actions (``ref_min_score``) and of the shipped policy
trained on the env (``ref_max_score``: ``agents.references.shipped_reference``) over the first
``REFERENCE_EPISODES`` of the same seeds; the description says which policy, engine and seeds
made the dataset. ``check_dataset_id`` refuses a malformed id or an existing one (unless
``overwrite``) before anything is evaluated; ``missing_minari`` names a missing extra.
"""

from __future__ import annotations

import dataclasses
import shutil
import warnings
from collections.abc import Sequence
from importlib import metadata as package_metadata
from typing import Any

import gymnasium as gym

from smartcar_gym.datasets.steps import EpisodeSteps
from smartcar_gym.sim.engines import DEFAULT_ENGINE, get_engine

__all__ = ["MINARI_EXTRA", "REFERENCE_EPISODES", "References", "check_dataset_id",
           "missing_minari", "write_dataset"]

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


def check_dataset_id(dataset_id: str, overwrite: bool = False) -> str | None:
    """The problem with writing ``dataset_id`` (one line), or None: a malformed id (Minari's
    ``(namespace/)name-vN``) or an existing dataset without ``overwrite``."""
    from minari.dataset.minari_dataset import parse_dataset_id
    from minari.storage import get_dataset_path

    try:
        if parse_dataset_id(dataset_id)[2] is None:
            raise ValueError
    except (ValueError, TypeError):
        return (f"{dataset_id!r} is not a Minari dataset id: expected (namespace/)name-vN, "
                "e.g. smartcar/default-pybullet-v0 (letters, digits, - and _)")
    path = get_dataset_path(dataset_id)
    if path.exists() and not overwrite:
        return f"the dataset {dataset_id} exists ({path}); pass --overwrite to replace it"
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


def write_dataset(dataset_id: str, episodes: Sequence[EpisodeSteps.Episode], *, env_id: str,
                  env_kwargs: dict[str, Any], policy: str, algo: str | None, seed: int,
                  deterministic: bool, vectorization: str, references: References,
                  overwrite: bool = False) -> Any:
    """Write ``episodes`` as the Minari dataset ``dataset_id`` (see the module docstring);
    returns the ``MinariDataset``. ``ValueError`` (one line) for an id ``check_dataset_id``
    refuses."""
    import minari
    from minari.data_collector import EpisodeBuffer
    from minari.storage import get_dataset_path

    problem = check_dataset_id(dataset_id, overwrite)
    if problem:
        raise ValueError(problem)
    if get_dataset_path(dataset_id).exists():
        shutil.rmtree(get_dataset_path(dataset_id))
    spec = dataclasses.replace(gym.spec(env_id), kwargs={**gym.spec(env_id).kwargs,
                                                         **env_kwargs})
    keys = _common_infos(episodes)
    buffers = [EpisodeBuffer(seed=ep.seed, observations=ep.observations, actions=ep.actions,
                             rewards=ep.rewards, terminations=ep.terminations,
                             truncations=ep.truncations,
                             infos={key: ep.infos[key] for key in keys})
               for ep in episodes]
    requirements = [f"smartcar-gym=={package_metadata.version('smartcar-gym')}"]
    requirements += get_engine(env_kwargs.get("engine") or DEFAULT_ENGINE).requirements
    with warnings.catch_warnings():  # a contact beyond the project's page: none to give
        warnings.filterwarnings("ignore", message="`author_email` is set to None")
        return minari.create_dataset_from_buffers(
            dataset_id, buffers, env=spec, eval_env=spec,
            algorithm_name=f"{(algo or 'unknown').upper()} ({policy})",
            code_permalink=CODE_PERMALINK, author="smartcar-eval",
            ref_min_score=references.min_score, ref_max_score=references.max_score,
            num_episodes_average_score=references.episodes,
            description=_description(len(episodes), policy, algo, env_id, env_kwargs, seed,
                                     deterministic, vectorization, references),
            requirements=requirements)
