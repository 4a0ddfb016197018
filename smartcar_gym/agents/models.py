"""Finding a model's files: its run, its VecNormalize statistics, the shipped policy.

Model zips and VecNormalize files are pickles: loading one runs whatever code it holds. So a
normaliser is only taken from a place whose layout says which file belongs to the model:

* a run folder of ``smartcar-train`` (``config.yaml`` with its keys): ``model.zip`` with
  ``vecnormalize.pkl``, ``best_model.zip`` with ``best_model_vecnormalize.pkl``,
  ``checkpoints/ckpt_<n>_steps.zip`` with ``ckpt_<n>_steps_vecnormalize.pkl``;
* a policy exported by ``smartcar_gym.agents.export`` (the shipped one included):
  ``policy.zip`` with ``vecnormalize.pkl`` and ``provenance.json``;
* an rl-baselines3-zoo run folder: ``<env>/vecnormalize.pkl`` when ``<env>/config.yml`` says
  ``normalize`` (see ``zoo_runs``).

Anything else is loaded only when the user names it (``smartcar-eval --vecnormalize``). Also
loading a model zip with its algorithm's class, and telling which algorithm saved one.
"""

from __future__ import annotations

import contextlib
import json
import os
import zipfile
from collections.abc import Iterator
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

from smartcar_gym.agents.hyperparams import HyperparamsError, normalize_kwargs
from smartcar_gym.agents.zoo_runs import ARGS_FILE, PARAMS_FILE, read_zoo_run

PRETRAINED_MODEL = "policy.zip"
#: the shipped policies: name -> folder under smartcar_gym/pretrained ("": the folder itself);
#: ``robust`` was trained with ``randomize="default"`` (docs/sim2real.md), ``ros`` on
#: SmartCarArrive-v0 to drive to 2D Nav Goals and stop there (docs/ros.md),
#: ``mujoco`` with ``engine="mujoco"`` (docs/engines.md), ``barn`` on SmartCarBARN-v0's
#: training worlds on the planar engine without a map (``map_mode="laser"``), ``barn-known``
#: there on the known map (docs/barn.md)
PRETRAINED_POLICIES = {"default": "", "robust": "robust", "nav": "nav", "ros": "ros",
                       "mujoco": "mujoco", "barn": "barn", "barn-known": "barn-known"}
# What smartcar_gym.agents.export writes in provenance.json (the keys that identify it).
PROVENANCE_KEYS = ("algo", "env", "source", "evaluation", "exported")
# Places of a model (ModelFiles.place).
TRAIN_RUN, EXPORTED, SHIPPED, ZOO_RUN = ("smartcar-train run", "exported policy",
                                         "shipped policy", "rl-baselines3-zoo run")


class ModelFilesError(ValueError):
    """A model path that names no model (the message says what was expected)."""


def vecnormalize_path_for(model_path: str | os.PathLike) -> Path:
    """Where ``smartcar-train`` keeps a saved model's VecNormalize statistics:
    ``vecnormalize.pkl`` for ``model.zip``, ``<stem>_vecnormalize.pkl`` for ``<stem>.zip``."""
    model_path = Path(model_path)
    stem = model_path.name.removesuffix(".zip")
    name = "vecnormalize.pkl" if stem == "model" else f"{stem}_vecnormalize.pkl"
    return model_path.with_name(name)


@dataclass(frozen=True)
class ModelFiles:
    """A model zip and what its place says about it.

    ``run`` has what is known of the training (``algo``, ``env``, ``env_kwargs``).
    ``expected_normalizer`` is the statistics file the place assigns to the model and
    ``normalizer`` the same path if the file exists. ``trained_with_normalizer`` is None when
    the place does not say (a lone model file). ``stray_normalizers`` are statistics files near
    a lone model file that are not loaded (they were found where older versions looked).
    """

    model: Path
    place: str | None = None
    folder: Path | None = None
    run: dict[str, Any] = field(default_factory=dict)
    expected_normalizer: Path | None = None
    trained_with_normalizer: bool | None = None
    stray_normalizers: tuple[Path, ...] = ()
    run_file: Path | None = None

    @property
    def normalizer(self) -> Path | None:
        """The statistics to load with the model (None if there are none to load)."""
        if self.expected_normalizer is not None and self.expected_normalizer.is_file():
            return self.expected_normalizer
        return None


def train_run_config(folder: str | os.PathLike) -> dict[str, Any] | None:
    """The ``config.yaml`` of a ``smartcar-train`` run folder (None if ``folder`` is not one:
    no such file, or not a mapping with the keys smartcar-train writes)."""
    from smartcar_gym.agents.runs import REQUIRED_KEYS

    path = Path(folder) / "config.yaml"
    try:
        config = yaml.safe_load(path.read_text())
    except (OSError, UnicodeDecodeError, yaml.YAMLError):
        return None
    if not isinstance(config, dict) or not all(key in config for key in REQUIRED_KEYS):
        return None
    return config


def _provenance(folder: Path) -> dict[str, Any] | None:
    """``provenance.json`` of an exported policy (None if ``folder`` has none)."""
    try:
        data = json.loads((folder / "provenance.json").read_text())
    except (OSError, UnicodeDecodeError, ValueError):
        return None
    if not isinstance(data, dict) or not all(key in data for key in PROVENANCE_KEYS):
        return None
    return data


def _uses_normalizer(hyperparams: Any) -> bool | None:
    if not isinstance(hyperparams, dict):
        return None
    try:
        return normalize_kwargs(hyperparams.get("normalize")) is not None
    except HyperparamsError:
        return None


def _run_info(data: dict[str, Any]) -> dict[str, Any]:
    return {key: data[key] for key in ("algo", "env", "env_kwargs") if key in data}


def locate_model(path: str | os.PathLike) -> ModelFiles:
    """The model at ``path`` (a zip, or a run folder: its final model) and its place.

    Raises ``ModelFilesError`` for a folder without a model, ``ZooRunError`` for a zoo run
    whose YAML files cannot be read.
    """
    path = Path(path)
    if path.is_dir():
        path = _final_model(path)
    model = path.absolute()
    folder = model.parent
    for run_dir in (folder, folder.parent) if folder.name == "checkpoints" else (folder,):
        config = train_run_config(run_dir)
        if config is not None:
            return ModelFiles(path, TRAIN_RUN, run_dir, _run_info(config),
                              vecnormalize_path_for(path),
                              _uses_normalizer(config.get("hyperparams")),
                              run_file=run_dir / "config.yaml")
    provenance = _provenance(folder) if model.name == PRETRAINED_MODEL else None
    if provenance is not None:
        return _exported(path, provenance, EXPORTED)
    zoo = read_zoo_run(folder, model.name.removesuffix(".zip"))
    if zoo is not None:
        run = {"algo": zoo.algo, "env": zoo.env, "env_kwargs": zoo.env_kwargs}
        args = zoo.params / ARGS_FILE
        return ModelFiles(path, ZOO_RUN, zoo.folder, {k: v for k, v in run.items() if v},
                          zoo.vecnormalize, zoo.normalize,
                          run_file=args if args.is_file() else zoo.params / PARAMS_FILE)
    strays = (vecnormalize_path_for(model), folder / "vecnormalize.pkl",
              folder.parent / "vecnormalize.pkl")
    return ModelFiles(path, stray_normalizers=tuple(dict.fromkeys(p for p in strays
                                                                  if p.is_file())))


def _exported(model: Path, provenance: dict[str, Any], place: str) -> ModelFiles:
    return ModelFiles(model, place, model.parent, _run_info(provenance),
                      model.parent / "vecnormalize.pkl",
                      _uses_normalizer(provenance.get("hyperparams")),
                      run_file=model.parent / "provenance.json")


def _final_model(folder: Path) -> Path:
    """The final model of a run folder (smartcar-train's, zoo's, an exported policy's)."""
    if train_run_config(folder) is not None:
        model = folder / "model.zip"
        others = sorted(p.name for p in (*folder.glob("*.zip"), *folder.glob("checkpoints/*.zip")))
        if not model.is_file():
            raise ModelFilesError(
                f"--model: the smartcar-train run {folder} has no model.zip yet (the run has "
                f"not finished){'; pass one of ' + ', '.join(others) if others else ''}")
        return model
    if _provenance(folder) is not None:
        return folder / PRETRAINED_MODEL
    zoo = read_zoo_run(folder)
    if zoo is not None:
        if not zoo.model.is_file():
            raise ModelFilesError(f"--model: the rl-baselines3-zoo run {folder} has no "
                                  f"{zoo.model.name} (the run has not finished)")
        return zoo.model
    raise ModelFilesError(
        f"--model: {folder} is a folder but not a run folder (smartcar-train's has config.yaml "
        "and model.zip; rl-baselines3-zoo's has <env>.zip and <env>/config.yml); pass a model "
        ".zip")


def shipped_model(folder: str | os.PathLike) -> ModelFiles:
    """The shipped policy in the package folder ``folder`` (see ``pretrained_files``): only
    that folder's ``policy.zip``, ``vecnormalize.pkl`` and ``provenance.json`` are read."""
    folder = Path(folder)
    provenance = _provenance(folder) or {}
    return _exported(folder / PRETRAINED_MODEL, provenance, SHIPPED)


def find_run_config(model_path: str | os.PathLike) -> dict[str, Any] | None:
    """What is known of a model's training (``algo``, ``env``, ``env_kwargs``), from its place:
    a smartcar-train run, an exported policy or a zoo run (None for a lone model file)."""
    return locate_model(model_path).run or None


def find_vecnormalize(model_path: str | os.PathLike) -> Path | None:
    """The VecNormalize statistics that the model's place assigns to it (None if there are
    none, or the model is not in a place listed in this module's docstring)."""
    return locate_model(model_path).normalizer


@contextlib.contextmanager
def pretrained_files(name: str = "default") -> Iterator[Path]:
    """The folder of a shipped policy (``policy.zip``, ``vecnormalize.pkl``, provenance):
    ``default`` or another of ``PRETRAINED_POLICIES``."""
    if name not in PRETRAINED_POLICIES:
        raise FileNotFoundError(f"no shipped policy {name!r}; shipped: "
                                f"{', '.join(PRETRAINED_POLICIES)}")
    place = resources.files("smartcar_gym") / "pretrained"
    if PRETRAINED_POLICIES[name]:
        place = place / PRETRAINED_POLICIES[name]
    with resources.as_file(place) as folder:
        if not (folder / PRETRAINED_MODEL).exists():
            raise FileNotFoundError(
                f"no shipped policy: {folder / PRETRAINED_MODEL} does not exist (train one with "
                "smartcar-train and package it with python -m smartcar_gym.agents.export)"
            )
        yield folder


# What a policy needs of an off-policy model's replay buffer: none (a buffer of one entry, of
# the default class: a saved HerReplayBuffer cannot be rebuilt without the training env).
_NO_BUFFER = {"buffer_size": 1, "replay_buffer_class": None, "replay_buffer_kwargs": {}}


class ActingOnly:
    """The optimizer of a model loaded only to act (``load_model(..., act=True)``): none.

    Stable-Baselines3 builds a policy with its optimizer, and a torch optimizer's first
    parameter group imports ``torch._dynamo``: about a second of every evaluation's start, for
    an optimizer that never steps. This one holds nothing, takes (and drops) the saved state,
    and refuses what only training does, with the way to load the model for training."""

    def __init__(self, params: Any, *args: Any, **kwargs: Any) -> None:
        pass

    def load_state_dict(self, state: Any, **kwargs: Any) -> None:
        pass

    def _refuse(self, *args: Any, **kwargs: Any) -> Any:
        raise RuntimeError("this model was loaded only to act (smartcar_gym.policy.Policy.load): "
                           "it has no optimizer to train or save; load it with "
                           "smartcar_gym.agents.models.load_model(path, algo) to train it")

    step = zero_grad = state_dict = _refuse


def load_model(path: str | os.PathLike, algo: str, device: str = "cpu",
               act: bool = False) -> Any:
    """Load an SB3 model zip with the class for ``algo`` (a pickle: only from a trusted source),
    for its policy: an off-policy model comes without its replay buffer. ``act``: only to act
    (``predict``), without its optimizer (``ActingOnly``: a second less to load; the same
    network, the same actions to the bit)."""
    from smartcar_gym.agents.hyperparams import algo_class

    custom = dict(_NO_BUFFER)
    if act:
        custom["policy_kwargs"] = {**_saved_policy_kwargs(path), "optimizer_class": ActingOnly}
    return algo_class(algo).load(str(path), device=device, custom_objects=custom)


def _saved_policy_kwargs(path: str | os.PathLike) -> dict[str, Any]:
    """The ``policy_kwargs`` a model zip was saved with (SB3's own decoding of its "data")."""
    from stable_baselines3.common.save_util import json_to_data

    with zipfile.ZipFile(path) as archive:
        saved = json.loads(archive.read("data")).get("policy_kwargs") or {}
    return dict(json_to_data(json.dumps({"policy_kwargs": saved}))["policy_kwargs"])


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
