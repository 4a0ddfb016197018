"""The episodes of an evaluation as a Minari dataset: ``smartcar-eval --minari DATASET_ID``.

``write_dataset`` stores the ``steps.EpisodeSteps`` episodes (observations, actions, rewards,
terminations, truncations, array infos, each episode's seed) under Minari's local root
(``MINARI_DATASETS_PATH``, else ``~/.minari/datasets``) in Minari's default format. Its env
spec is the registered one with the evaluation's kwargs (engine included), so
``dataset.recover_environment()`` makes the env the episodes ran in. The reference scores are
the mean returns of uniform random actions (``ref_min_score``) and of the shipped policy
trained on the env (``ref_max_score``: ``shipped_reference``) over the first
``REFERENCE_EPISODES`` of the same seeds; the description says which policy, engine and seeds
made the dataset. ``check_dataset_id`` refuses a malformed id or an existing one (unless
``overwrite``) before anything is evaluated; ``missing_minari`` names a missing extra.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
import warnings
from collections.abc import Sequence
from importlib import metadata as package_metadata
from importlib import resources
from typing import Any

import gymnasium as gym
import numpy as np

from smartcar_gym.datasets.steps import EpisodeSteps

__all__ = ["MINARI_EXTRA", "REFERENCE_EPISODES", "References", "check_dataset_id",
           "missing_minari", "reference_scores", "shipped_reference", "write_dataset"]

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


def shipped_reference(env_id: str, env_kwargs: dict[str, Any]) -> str | None:
    """The shipped policy that stands for the best score on ``env_id`` with ``env_kwargs``:
    among those trained on ``env_id`` (their ``provenance.json``), the one whose env kwargs
    are the most of ``env_kwargs`` (``default`` on SmartCar-v0, ``mujoco`` with
    ``engine="mujoco"``, ``robust`` with ``randomize="default"``); None if none is."""
    from smartcar_gym.agents.models import PRETRAINED_POLICIES

    best, best_size = None, -1
    place = resources.files("smartcar_gym") / "pretrained"
    for name, folder in PRETRAINED_POLICIES.items():
        provenance = json.loads(((place / folder) if folder else place)
                                .joinpath("provenance.json").read_text())
        trained = provenance.get("env_kwargs") or {}
        if provenance.get("env") != env_id:
            continue
        if all(env_kwargs.get(k) == v for k, v in trained.items()) and len(trained) > best_size:
            best, best_size = name, len(trained)
    return best


@dataclasses.dataclass
class References:
    """The reference scores (None where not measured) and what they come from."""

    min_score: float | None
    max_score: float | None
    episodes: int
    max_policy: str | None
    note: str


def reference_scores(env_id: str, env_kwargs: dict[str, Any], seed: int,
                     returns: Sequence[float], policy_source: str) -> References:
    """Random and shipped policies' mean returns over seeds ``seed..seed+n-1`` (``n``: the
    evaluation's episodes, at most ``REFERENCE_EPISODES``), run as a batch. ``returns`` are
    the evaluation's, reused when ``policy_source`` is the reference policy itself
    (``pretrained:NAME``). The shipped policy needs the ``train`` extra; without it only
    the random score is measured, and neither is stored (Minari takes both or none)."""
    from smartcar_gym.agents.episodes import RandomPolicy, evaluate_batched_episodes
    from smartcar_gym.policy import Policy, PolicyError

    n = min(len(returns), REFERENCE_EPISODES)
    name = shipped_reference(env_id, env_kwargs)
    if name is None:
        return References(None, None, n, None, f"no shipped policy is trained on {env_id}, "
                          "so no reference scores")
    common = dict(env_id=env_id, n_episodes=n, seed=seed, env_kwargs=env_kwargs)

    def mean_return(policy: Policy) -> float:
        return float(np.mean([r.episode_return
                              for r in evaluate_batched_episodes(policy, **common)]))

    if policy_source == f"pretrained:{name}":
        high = float(np.mean(returns[:n]))
    else:
        try:
            high = mean_return(Policy.load(name, env_kwargs=env_kwargs))
        except (ImportError, PolicyError) as err:
            return References(None, None, n, name, f"no reference scores: the shipped policy "
                              f"{name} could not be loaded ({err})")
    random = Policy(RandomPolicy(seed), algo="random", env_id=env_id, env_kwargs=env_kwargs)
    return References(mean_return(random), high, n, name, "")


def _description(n: int, policy: str, algo: str | None, env_id: str, env_kwargs: dict,
                 seed: int, deterministic: bool, vectorization: str,
                 references: References) -> str:
    from smartcar_gym.sim.engines import DEFAULT_ENGINE

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
    if env_kwargs.get("engine") == "mujoco":
        requirements.append("mujoco>=3.10")
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
