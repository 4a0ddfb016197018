"""rl-baselines3-zoo run folders, read without running code from them.

``python -m rl_zoo3.train --algo ppo --env SmartCar-v0 --gym-packages smartcar_gym`` writes
``<log>/<algo>/<env>_<n>/``::

    <env>.zip                     the final model
    best_model.zip                the best evaluation's (with --eval-freq)
    rl_model_<steps>_steps.zip    checkpoints (with --save-freq)
    <env>/config.yml              the hyperparameters: ``normalize`` says whether VecNormalize ran
    <env>/args.yml                the command line: algo, env, env_kwargs
    <env>/vecnormalize.pkl        the VecNormalize statistics (with ``normalize``)

Every model of the run is evaluated with ``<env>/vecnormalize.pkl``, as ``rl_zoo3.enjoy`` does
(zoo saves no statistics with its checkpoints). zoo writes the YAML files with ``yaml.dump`` of
``OrderedDict`` objects and reads them back with ``yaml.UnsafeLoader``; here a safe loader turns
``OrderedDict`` and tuples into plain values and constructs no other Python object.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from smartcar_gym.agents.hyperparams import ALGOS, HyperparamsError, normalize_kwargs

PARAMS_FILE = "config.yml"
ARGS_FILE = "args.yml"
NORMALIZER_FILE = "vecnormalize.pkl"


class ZooRunError(ValueError):
    """A zoo run folder whose files cannot be read (the message names the file and key)."""


@dataclass(frozen=True)
class Unreadable:
    """A Python object in a zoo YAML file, left unconstructed (its tag is kept)."""

    tag: str


class _ZooLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` plus zoo's ``OrderedDict`` and tuples; other Python tags become
    ``Unreadable`` instead of objects."""


def _ordered_dict(loader: _ZooLoader, node: yaml.Node) -> dict[Any, Any]:
    args = loader.construct_sequence(node, deep=True)  # [[[key, value], ...]]
    return {key: value for key, value in args[0]} if args else {}


def _unreadable(loader: _ZooLoader, suffix: str, node: yaml.Node) -> Unreadable:
    return Unreadable(f"!!python/{suffix}")


_ZooLoader.add_constructor("tag:yaml.org,2002:python/object/apply:collections.OrderedDict",
                           _ordered_dict)
_ZooLoader.add_constructor("tag:yaml.org,2002:python/tuple",
                           lambda loader, node: tuple(loader.construct_sequence(node, deep=True)))
_ZooLoader.add_multi_constructor("tag:yaml.org,2002:python/", _unreadable)


def load_zoo_yaml(path: str | os.PathLike) -> dict[str, Any]:
    """A zoo ``config.yml`` or ``args.yml`` as a plain dict; ``ZooRunError`` if unreadable."""
    path = Path(path)
    try:
        data = yaml.load(path.read_text(), Loader=_ZooLoader)  # noqa: S506 (a safe loader)
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as err:
        raise ZooRunError(f"cannot read {path}: {err}") from err
    if not isinstance(data, dict):
        raise ZooRunError(f"{path} is not a zoo {path.name} (expected a mapping)")
    return data


def _has_unreadable(value: Any) -> bool:
    if isinstance(value, Unreadable):
        return True
    if isinstance(value, dict):
        return any(_has_unreadable(k) or _has_unreadable(v) for k, v in value.items())
    if isinstance(value, (list, tuple)):
        return any(_has_unreadable(v) for v in value)
    return False


@dataclass(frozen=True)
class ZooRun:
    """A zoo run folder: what is known of its training, and where its files are."""

    folder: Path
    params: Path  # <folder>/<env>
    env: str
    algo: str | None
    normalize: bool
    env_kwargs: dict[str, Any] = field(default_factory=dict)

    @property
    def model(self) -> Path:
        """The final model, ``<folder>/<env>.zip``."""
        return self.folder / f"{self.params.name}.zip"

    @property
    def vecnormalize(self) -> Path:
        """``<folder>/<env>/vecnormalize.pkl`` (it exists only when ``normalize`` is on)."""
        return self.params / NORMALIZER_FILE


def zoo_params_folder(folder: str | os.PathLike, model_stem: str | None = None) -> Path | None:
    """The ``<env>/`` folder (with ``config.yml``) of a zoo run folder, or None.

    ``<model_stem>/`` if it has one (the final model ``<env>.zip``), else the only subfolder
    that has a ``config.yml``.
    """
    folder = Path(folder)
    if model_stem and (folder / model_stem / PARAMS_FILE).is_file():
        return folder / model_stem
    try:
        found = [d for d in folder.iterdir() if (d / PARAMS_FILE).is_file()]
    except OSError:
        return None
    return found[0] if len(found) == 1 else None


def read_zoo_run(folder: str | os.PathLike, model_stem: str | None = None) -> ZooRun | None:
    """The zoo run in ``folder`` (None if it is not one); ``ZooRunError`` if its files cannot
    be read. ``env_kwargs`` are ``config.yml``'s, replaced by ``args.yml``'s when given there
    (as ``rl_zoo3.enjoy`` does)."""
    folder = Path(folder)
    params = zoo_params_folder(folder, model_stem)
    if params is None:
        return None
    config_path, args_path = params / PARAMS_FILE, params / ARGS_FILE
    config = load_zoo_yaml(config_path)
    args = load_zoo_yaml(args_path) if args_path.is_file() else {}
    try:
        normalize = normalize_kwargs(config.get("normalize", False)) is not None
    except HyperparamsError as err:
        raise ZooRunError(f"{config_path}: {err}") from err
    env_kwargs: Any = config.get("env_kwargs") or {}
    source = config_path
    if args.get("env_kwargs") is not None:
        env_kwargs, source = args["env_kwargs"], args_path
    if not isinstance(env_kwargs, dict) or _has_unreadable(env_kwargs):
        raise ZooRunError(f"{source}: env_kwargs must be a mapping of plain values, got "
                          f"{env_kwargs!r}; pass --env-kwargs instead")
    env = args.get("env") if isinstance(args.get("env"), str) else params.name
    algo = args.get("algo")  # else the <algo>/ folder of <log>/<algo>/<env>_<n>
    if not isinstance(algo, str):
        algo = folder.parent.name if folder.parent.name in ALGOS else None
    return ZooRun(folder=folder, params=params, env=env, algo=algo and algo.lower(),
                  normalize=normalize, env_kwargs=dict(env_kwargs))
