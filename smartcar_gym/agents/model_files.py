"""Finding a model's files: its run config, VecNormalize statistics, the shipped policy.

Also loading a model zip with its algorithm's class, and telling which algorithm saved one.
"""

from __future__ import annotations

import contextlib
import json
import os
import zipfile
from collections.abc import Iterator
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

PRETRAINED_MODEL = "ppo_smartcar.zip"


def find_run_config(model_path: str | os.PathLike) -> dict[str, Any] | None:
    """What is known of a model's training: the run's ``config.yaml`` (in the model's folder or
    the one above, for checkpoints) or an exported policy's ``provenance.json`` beside it.

    Both have ``algo``, ``env`` and ``env_kwargs``.
    """
    model_path = Path(model_path).resolve()
    for folder in (model_path.parent, model_path.parent.parent):
        path = folder / "config.yaml"
        if path.exists():
            return yaml.safe_load(path.read_text())
    provenance = model_path.parent / "provenance.json"
    if provenance.exists():
        return json.loads(provenance.read_text())
    return None


def find_vecnormalize(model_path: str | os.PathLike) -> Path | None:
    """VecNormalize statistics for a model: ``<stem>_vecnormalize.pkl``, else the folder's or
    the run's ``vecnormalize.pkl`` (None if there are none)."""
    model_path = Path(model_path)
    stem = model_path.name.removesuffix(".zip")
    candidates = [
        model_path.with_name(f"{stem}_vecnormalize.pkl"),
        model_path.with_name("vecnormalize.pkl"),
    ]
    if (model_path.parent.parent / "config.yaml").exists():
        candidates.append(model_path.parent.parent / "vecnormalize.pkl")
    return next((c for c in candidates if c.exists()), None)


@contextlib.contextmanager
def pretrained_files() -> Iterator[Path]:
    """The folder of the shipped policy (``ppo_smartcar.zip``, ``vecnormalize.pkl``, provenance)."""
    with resources.as_file(resources.files("smartcar_gym") / "pretrained") as folder:
        if not (folder / PRETRAINED_MODEL).exists():
            raise FileNotFoundError(
                f"no shipped policy: {folder / PRETRAINED_MODEL} does not exist (train one with "
                "smartcar-train and package it with python -m smartcar_gym.agents.export)"
            )
        yield folder


def load_model(path: str | os.PathLike, algo: str, device: str = "cpu") -> Any:
    """Load an SB3 model zip with the class for ``algo``."""
    from smartcar_gym.agents.hyperparams import algo_class

    return algo_class(algo).load(str(path), device=device)


# The module of each algorithm's policy classes, as recorded in a saved model's "data".
_POLICY_MODULES = {"stable_baselines3.common.policies": "ppo",
                   "stable_baselines3.sac.policies": "sac", "stable_baselines3.td3.policies": "td3"}


def saved_algo(path: str | os.PathLike) -> str | None:
    """The algorithm a model zip was saved by, from its policy class (None if unknown)."""
    try:
        with zipfile.ZipFile(path) as archive:
            policy = json.loads(archive.read("data"))["policy_class"]
    except (OSError, KeyError, ValueError, zipfile.BadZipFile):
        return None
    return _POLICY_MODULES.get(policy.get("__module__")) if isinstance(policy, dict) else None
