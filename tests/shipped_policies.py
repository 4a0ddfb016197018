"""Evaluating a policy shipped in ``smartcar_gym/pretrained`` (shared by the policy gates)."""

from __future__ import annotations

import json
from importlib import resources
from typing import Any

from smartcar_gym.agents.episodes import evaluate_policy_episodes
from smartcar_gym.agents.models import PRETRAINED_POLICIES
from smartcar_gym.agents.records import summarize
from smartcar_gym.policy import Policy


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
    policy = Policy.load(name)
    records = evaluate_policy_episodes(policy, policy.env_id, n_episodes=n_episodes,
                                       n_envs=n_envs, seed=0, env_kwargs=env_kwargs or {})
    return summarize(records), records
