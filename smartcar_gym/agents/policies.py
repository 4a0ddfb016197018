"""A trained policy as one object: its SB3 model, its observation normaliser and its env.

The implementation of ``smartcar_gym.policy``, the public way in (its docstring says how to
use it). It belongs with the agents' model files (``models``, ``zoo_runs``), which it reads;
every module of the package imports it from here.
"""

from __future__ import annotations

import contextlib
import os
import pickle
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from smartcar_gym.agents.hyperparams import ALGOS
from smartcar_gym.agents.models import (
    PRETRAINED_POLICIES,
    ModelFiles,
    ModelFilesError,
    load_model,
    locate_model,
    pretrained_files,
    saved_algo,
    shipped_model,
)
from smartcar_gym.agents.zoo_runs import ZooRunError
from smartcar_gym.extras import TRAIN_EXTRA, missing_modules
from smartcar_gym.registration import PolicyEnvError, check_policy_env
from smartcar_gym.runtime.onnx_policy import is_onnx_path

if TYPE_CHECKING:
    import gymnasium as gym

    from smartcar_gym.envs.policy_settings import PolicySettings

__all__ = ["DEFAULT_ENV_ID", "PRETRAINED_POLICIES", "ObsNormalizer", "Policy", "PolicyError",
           "as_policy", "choose_normalizer"]

DEFAULT_ENV_ID = "SmartCar-v0"
#: what loading a model imports (the ``train`` extra brings them)
POLICY_MODULES = ("stable_baselines3", "torch")


class PolicyError(ValueError):
    """A policy that cannot be loaded: one line naming the file and what was expected."""


class ObsNormalizer:
    """Applies saved ``VecNormalize`` observation statistics (frozen) to raw observations.

    Unpickles ``vecnormalize_path``: only for a file the user named or the model's place
    assigns to it (see ``smartcar_gym.policy``)."""

    def __init__(self, vecnormalize_path: str | os.PathLike) -> None:
        with open(vecnormalize_path, "rb") as f:
            self.vec_normalize = pickle.load(f)

    def __call__(self, obs: np.ndarray | dict[str, np.ndarray]) -> Any:
        return self.vec_normalize.normalize_obs(obs)


@dataclass(eq=False)
class Policy:
    """A model with its normaliser and the env it acts in (see ``smartcar_gym.policy``).

    Attributes:
        model: the SB3 model (or anything with SB3's ``predict(obs, deterministic=...)``);
            ``load`` loads it only to act, without its optimizer (``models.ActingOnly``:
            a second less to start; ``models.load_model`` loads one to train).
        normalizer: the observation statistics applied before ``predict`` (None: raw obs).
        algo: ``"ppo"``, ``"sac"``, ``"td3"`` (None when not known).
        env_id, env_kwargs: the env the policy acts in: the run's, with ``load``'s overrides.
        model_path: the model zip (None for a model made in memory).
        normalizer_path: the statistics file loaded (None if none was).
        normalizer_source: where the statistics come from, or why none were loaded.
        warning: one line when no statistics were loaded although the model may need them.
    """

    model: Any
    normalizer: ObsNormalizer | None = None
    algo: str | None = None
    env_id: str = DEFAULT_ENV_ID
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    model_path: Path | None = None
    normalizer_path: Path | None = None
    normalizer_source: str = "none"
    warning: str | None = None

    @classmethod
    def load(cls, source: str | os.PathLike, *, algo: str | None = None,
             env_id: str | None = None, env_kwargs: Mapping[str, Any] | None = None,
             normalizer: str | os.PathLike | None = None, device: str = "cpu",
             runtime: str = "auto") -> Policy:
        """Load a policy from ``source``: a shipped policy's name (a ``str`` among
        ``PRETRAINED_POLICIES``; pass a ``Path`` for a folder of that name), a model ``.zip``,
        a run folder of ``smartcar-train``, rl-baselines3-zoo or an exported policy, or an
        ``.onnx`` file of ``smartcar-export`` (run without torch, by onnxruntime or, with
        ``runtime="numpy"`` or where onnxruntime is missing, by numpy: ``smartcar_gym.runtime``;
        its normalisation is in the graph, so ``model.predict`` takes raw observations).

        ``algo``: the model's algorithm (default: its run's; it must match the saved model).
        ``env_id`` replaces the run's env id; ``env_kwargs`` are added to the run's (an
        ``engine`` among them leaves out what only the run's engine took: ``planar_params``).
        ``normalizer``: VecNormalize statistics to load (a pickle: only a trusted file); by
        default, the ones the model's place assigns to it. ``device``: torch's.

        Raises ``PolicyError`` for a missing or unreadable file, an unknown shipped name or
        algorithm, or a model of another algorithm; ``ImportError`` without the train extra
        (an ``.onnx`` file needs no extra).
        """
        if is_onnx_path(source):
            return _load_onnx(Path(source), algo=algo, env_id=env_id, env_kwargs=env_kwargs,
                              normalizer=normalizer, runtime=runtime)
        missing = missing_modules(POLICY_MODULES)
        if missing:
            raise ImportError(f"{', '.join(missing)} not installed; loading a policy needs the "
                              f"train extra: {TRAIN_EXTRA}")
        with contextlib.ExitStack() as stack:
            files = _model_files(source, stack)
            run = files.run
            algo = _algo(files.model, algo, run.get("algo"))
            env_id, run_kwargs = _run_env(files, env_id)
            env_kwargs = _run_env_kwargs(run_kwargs, dict(env_kwargs or {}), env_id)
            if normalizer is not None and not Path(normalizer).is_file():
                raise PolicyError(f"--vecnormalize: no such file: {normalizer}")
            named = None if normalizer is None else Path(normalizer)
            stats, where, warning = choose_normalizer(files, named)
            model = _load_model(files.model, algo, device)
            try:
                obs_normalizer = None if stats is None else ObsNormalizer(stats)
            except Exception as err:  # a pickle from anywhere: whatever fails, the file is why
                raise PolicyError(f"cannot load the normaliser {stats}: {type(err).__name__}: "
                                  f"{err}") from err
        return cls(model, obs_normalizer, algo=algo, env_id=env_id, env_kwargs=env_kwargs,
                   model_path=files.model, normalizer_path=stats, normalizer_source=where,
                   warning=warning)

    def act(self, obs: np.ndarray | Mapping[str, np.ndarray],
            deterministic: bool = True) -> np.ndarray:
        """The action (float32, shape ``(2,)``, before the env's clipping) for one observation:
        an array, or a dict of arrays for a ``Dict`` space (``SmartCarGoal-v0``). It is
        normalised with ``normalizer``, then given to the model as a batch of one.
        ``deterministic=False`` samples (seed the model with ``model.set_random_seed``).
        An array of another shape than ``observation_space``'s: ``ValueError``."""
        if isinstance(obs, Mapping):
            batch: Any = {key: np.asarray(value, dtype=np.float32)[None]
                          for key, value in obs.items()}
        else:
            obs = np.asarray(obs)
            expected = getattr(self.observation_space, "shape", None)
            if expected is not None and obs.shape != tuple(expected):
                raise ValueError(f"an observation of shape {obs.shape}; the policy expects "
                                 f"{tuple(expected)} (the observation_space it was trained on)")
            batch = obs[None].astype(np.float32)
        if self.normalizer is not None:
            batch = self.normalizer(batch)
        action, _ = self.model.predict(batch, deterministic=deterministic)
        return np.asarray(action, dtype=np.float32).reshape(-1)

    @property
    def observation_space(self) -> Any:
        """The observation space the model was trained on (None if the model has none)."""
        return getattr(self.model, "observation_space", None)

    @cached_property
    def settings(self) -> PolicySettings:
        """What acting outside the env needs of it (``envs.policy_settings.PolicySettings``: wheel
        joints, task, action scales, controller rate) for ``env_id`` with ``env_kwargs``,
        computed on first use. Raises ``ValueError`` (or ``ModelError``, ``OSError``) for env
        settings that the env would refuse, or an env that is not a ``SmartCarEnv``."""
        from smartcar_gym.envs.policy_settings import policy_settings

        return policy_settings(self.env_id, self.env_kwargs)

    def make_env(self, **env_kwargs: Any) -> gym.Env:
        """``gym.make(env_id, **self.env_kwargs, **env_kwargs)``: the env the policy acts in.
        ``PolicyError`` for an ``env_id`` that is not a plain id smartcar-gym registered
        (``registration.check_policy_env``): Gymnasium would import the module before a ``:``."""
        from smartcar_gym.agents.env_factory import make_env

        try:
            check_policy_env("env_id", self.env_id, {})
        except PolicyEnvError as err:
            raise PolicyError(str(err)) from None
        return make_env(self.env_id, {**self.env_kwargs, **env_kwargs})


def as_policy(model: Any, vecnormalize_path: str | os.PathLike | None = None) -> Policy:
    """``model`` if it is a ``Policy``; else a ``Policy`` of an SB3-like model (anything with
    ``predict``) with the statistics at ``vecnormalize_path`` (a trusted file) if given."""
    if isinstance(model, Policy):
        if vecnormalize_path is not None:
            raise ValueError("a Policy brings its own normaliser: pass vecnormalize_path only "
                             "with a bare model")
        return model
    if vecnormalize_path is None:
        return Policy(model)
    return Policy(model, ObsNormalizer(vecnormalize_path), normalizer_path=Path(vecnormalize_path),
                  normalizer_source=str(vecnormalize_path))


def choose_normalizer(files: ModelFiles, named: Path | None) -> tuple[Path | None, str,
                                                                       str | None]:
    """The normaliser to load with a model: ``named`` (``--vecnormalize``), else the one its
    place assigns to it. Returns the path (or None), where it comes from, and a warning when
    none is loaded although the model may need one."""
    if named is not None:
        return named, f"{named} (named with --vecnormalize)", None
    where = f"the {files.place} {files.folder}" if files.place else None
    if files.normalizer is not None:
        return files.normalizer, f"{files.normalizer} (that of {where})", None
    if files.trained_with_normalizer is False:
        return None, f"none ({where} trained without VecNormalize)", None
    cost = ("a policy trained on normalised observations mostly fails on raw ones, so its "
            "score would be meaningless")
    if where is not None:
        return None, "none (see the warning)", (
            f"no normaliser loaded: {where} trained with VecNormalize but "
            f"{files.expected_normalizer} does not exist; {cost}; pass --vecnormalize FILE")
    strays = ", ".join(map(str, files.stray_normalizers))
    return None, "none (see the warning)", (
        f"no normaliser loaded: {files.model} is not in a smartcar-train run folder, an exported "
        f"policy's folder or an rl-baselines3-zoo run folder, so none is looked for; {cost}. If "
        "it was trained with VecNormalize (the shipped hyperparameters use it), pass "
        "--vecnormalize FILE" + (f" ({strays} lies near the model but is not loaded unnamed: it "
                                 "is a pickle)" if strays else ""))


def _run_env(files: ModelFiles, env_id: str | None) -> tuple[str, dict[str, Any]]:
    """The env id (``env_id``, else the run's) and the run's env kwargs, as
    ``registration.check_policy_env`` lets them through: what a run's file says is data, checked
    before anything is imported or built for it."""
    where = str(files.run_file or files.model)
    try:
        if env_id is not None:
            check_policy_env("--env", env_id, {})
        return check_policy_env(where, env_id or files.run.get("env", DEFAULT_ENV_ID),
                                files.run.get("env_kwargs") or {})
    except PolicyEnvError as err:
        raise PolicyError(str(err)) from None


def _run_env_kwargs(run: dict[str, Any], overrides: dict[str, Any],
                    env_id: str) -> dict[str, Any]:
    """The run's env kwargs with ``overrides`` added; an overriding ``engine`` first leaves
    out what only another engine takes (a planar run's ``planar_params`` on pybullet). A
    ``map_mode`` other than the one the policy was trained in (SmartCarBARN-v0's: the known
    map or the laser's) is one line naming both."""
    from smartcar_gym.envs.settings import own_keywords
    from smartcar_gym.envs.tasks.registry import task_of
    from smartcar_gym.sim.engines import engine_names, on_engine

    if overrides.get("engine") in engine_names():  # an unknown engine: gym.make names it
        run = on_engine(run, overrides["engine"])
    entry = task_of(env_id) if "map_mode" in overrides else None
    if entry is not None and "map_mode" in (modes := own_keywords(entry.load().__init__)):
        trained = run.get("map_mode", modes["map_mode"])
        if overrides["map_mode"] != trained:
            raise PolicyError(f"the policy was trained with map_mode={trained!r} (its waypoint "
                              f"from that map's path) and cannot run with map_mode="
                              f"{overrides['map_mode']!r}: pass a policy trained for it")
    return {**run, **overrides}


def _load_onnx(path: Path, *, algo: str | None, env_id: str | None,
               env_kwargs: Mapping[str, Any] | None, normalizer: str | os.PathLike | None,
               runtime: str) -> Policy:
    """``Policy.load`` of an exported ``.onnx`` file (``smartcar_gym.runtime``)."""
    from smartcar_gym.runtime.onnx_policy import OnnxPolicyError, load_onnx

    if normalizer is not None:
        raise PolicyError(f"--vecnormalize: {path} has its normalisation in the graph; an "
                          "exported policy takes no statistics file")
    if not path.is_file():
        raise PolicyError(f"--model: no such file: {path}")
    try:
        model = load_onnx(path, runtime)  # type: ignore[arg-type]
    except OnnxPolicyError as err:
        raise PolicyError(str(err)) from None
    meta = model.metadata
    if meta["algo"] not in ALGOS:
        raise PolicyError(f"{path}: metadata algo {meta['algo']!r}; expected one of "
                          f"{', '.join(ALGOS)}")
    if env_id is not None:
        try:
            check_policy_env("--env", env_id, {})
        except PolicyEnvError as err:
            raise PolicyError(str(err)) from None
    if algo is not None and algo != meta["algo"]:
        raise PolicyError(f"--algo {algo}: {path} was exported from a {meta['algo']} model")
    return Policy(model, None, algo=meta["algo"], env_id=env_id or meta["env_id"],
                  env_kwargs=_run_env_kwargs(dict(meta["env_kwargs"]), dict(env_kwargs or {}),
                                             env_id or meta["env_id"]),
                  model_path=path, normalizer_source=f"folded into {path.name} ({model.runtime})")


def _model_files(source: str | os.PathLike, stack: contextlib.ExitStack) -> ModelFiles:
    """The model ``source`` names and its place (a shipped policy's folder stays open in
    ``stack``)."""
    if isinstance(source, str) and source in PRETRAINED_POLICIES:
        try:
            return shipped_model(stack.enter_context(pretrained_files(source)))
        except FileNotFoundError as err:
            raise PolicyError(str(err)) from None
    path = Path(source)
    if not path.exists():
        hint = (f" (nor the name of a shipped policy: {', '.join(PRETRAINED_POLICIES)})"
                if isinstance(source, str) else "")
        raise PolicyError(f"--model: no such file: {source}{hint}")
    try:
        files = locate_model(path)
    except (ModelFilesError, ZooRunError) as err:
        raise PolicyError(str(err)) from None
    if not zipfile.is_zipfile(files.model):
        raise PolicyError(f"--model: {files.model} is not a model (SB3 models are .zip files)")
    return files


def _algo(model: Path, algo: str | None, run_algo: str | None) -> str:
    if algo is None and run_algo is None:
        raise PolicyError(f"cannot tell the algorithm of {model}: it is not in a run folder that "
                          "says (smartcar-train's config.yaml, rl-baselines3-zoo's "
                          "<env>/args.yml); pass --algo")
    if algo is None:
        if run_algo not in ALGOS:
            raise PolicyError(f"unknown algorithm {run_algo!r} in the run's config; pass --algo")
        return run_algo
    if algo not in ALGOS:
        raise PolicyError(f"--algo: unknown algorithm {algo!r}; expected one of "
                          f"{', '.join(ALGOS)}")
    return algo


def _load_model(path: Path, algo: str, device: str) -> Any:
    """``load_model``, with one line for the wrong algorithm or a file that is no model."""
    saved = saved_algo(path)
    if saved is not None and saved != algo:
        raise PolicyError(f"{path} holds a {saved.upper()} model, not {algo.upper()}: pass "
                          f"--algo {saved}")
    try:
        return load_model(path, algo, device=device, act=True)
    except Exception as err:  # a file from anywhere: whatever fails, the file is the cause
        raise PolicyError(f"--model: cannot load {path} as a {algo.upper()} model: "
                          f"{type(err).__name__}: {err}") from err
