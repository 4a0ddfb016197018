"""Evaluating a policy shipped in ``smartcar_gym/pretrained`` (shared by the policy gates)."""

from __future__ import annotations

import json
from importlib import resources
from typing import Any

from smartcar_gym.agents.evaluate import (
    PRETRAINED_MODEL,
    evaluate_policy_episodes,
    load_model,
    summarize,
)
from smartcar_gym.agents.model_files import PRETRAINED_POLICIES


def folder(name: str = "default"):
    """The package folder of the shipped policy ``name``."""
    place = resources.files("smartcar_gym") / "pretrained"
    return place / PRETRAINED_POLICIES[name] if PRETRAINED_POLICIES[name] else place


def provenance(name: str = "default") -> dict[str, Any]:
    return json.loads((folder(name) / "provenance.json").read_text())


def evaluate_shipped(name: str, n_episodes: int, n_envs: int,
                     env_kwargs: dict[str, Any] | None = None) -> tuple[dict[str, Any], list]:
    """(summary, records) of the shipped policy ``name`` on seeded episodes 0..n_episodes-1 of
    its provenance's env (``env_kwargs``: that env's kwargs; default: none)."""
    info = provenance(name)
    with resources.as_file(folder(name)) as place:
        model = load_model(place / PRETRAINED_MODEL, info["algo"])
        stats = place / "vecnormalize.pkl"
        records = evaluate_policy_episodes(
            model, info["env"], n_episodes=n_episodes, n_envs=n_envs, seed=0,
            env_kwargs=env_kwargs or {},
            vecnormalize_path=stats if stats.is_file() else None)
    return summarize(records), records
