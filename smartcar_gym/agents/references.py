"""The reference scores a Minari dataset carries: uniform random actions' and the shipped
policy's mean returns on the dataset's env and seeds (``smartcar-eval --minari``)."""

from __future__ import annotations

import json
from collections.abc import Sequence
from importlib import resources
from typing import Any

import numpy as np

from smartcar_gym.agents.episodes import evaluate_batched_episodes
from smartcar_gym.agents.models import PRETRAINED_POLICIES
from smartcar_gym.agents.policies import Policy, PolicyError
from smartcar_gym.agents.random_policy import RandomPolicy
from smartcar_gym.datasets.minari_writer import REFERENCE_EPISODES, References


def shipped_reference(env_id: str, env_kwargs: dict[str, Any]) -> str | None:
    """The shipped policy that stands for the best score on ``env_id`` with ``env_kwargs``:
    among those trained on ``env_id`` (their ``provenance.json``), the one whose env kwargs
    are the most of ``env_kwargs`` (``default`` on SmartCar-v0, ``mujoco`` with
    ``engine="mujoco"``, ``robust`` with ``randomize="default"``); None if none is."""
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


def reference_scores(env_id: str, env_kwargs: dict[str, Any], seed: int,
                     returns: Sequence[float], policy_source: str) -> References:
    """Random and shipped policies' mean returns over seeds ``seed..seed+n-1`` (``n``: the
    evaluation's episodes, at most ``REFERENCE_EPISODES``), run as a batch. ``returns`` are
    the evaluation's, reused when ``policy_source`` is the reference policy itself
    (``pretrained:NAME``). The shipped policy needs the ``train`` extra; without it only
    the random score is measured, and neither is stored (Minari takes both or none)."""
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
