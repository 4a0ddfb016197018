"""Hyperparameters in rl-baselines3-zoo's format: load, override from the command line, build.

A file ``smartcar_gym/config/<algo>.yaml`` maps env ids (or ``default``, for any env the file
does not name) to hyperparameters::

    SmartCar-v0:
      n_timesteps: 300000        # not passed to the algorithm (see RUN_KEYS)
      n_envs: 8
      policy: MlpPolicy          # or an import path of a policy class
      normalize: true            # VecNormalize; or "dict(norm_obs=True, norm_reward=False)"
      learning_rate: 3.0e-4      # or "lin_3e-4" for a linear decay to 0
      policy_kwargs: "dict(net_arch=[64, 64], activation_fn=nn.Tanh)"
      monitor_kwargs: "dict(info_keywords=('is_success',))"

``env_wrapper``, ``vec_env_wrapper``, ``frame_stack``, ``callback``, ``monitor_kwargs`` and
``env_kwargs`` shape the run (``zoo_keys``). Everything else is a keyword argument of the SB3
algorithm's constructor, plus zoo's ``noise_type`` / ``noise_std`` for an action noise (TD3,
SAC). Strings of Python (``dict(...)``) are read as literals, never evaluated.
"""

from __future__ import annotations

import ast
import copy
import inspect
from collections.abc import Sequence
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

ALGOS = ("ppo", "sac", "td3")
# Keys of a zoo entry that configure the run, not the algorithm's constructor.
RUN_KEYS = ("n_envs", "n_timesteps", "policy", "normalize", "env_wrapper", "vec_env_wrapper",
            "frame_stack", "callback", "monitor_kwargs", "env_kwargs", "eval_engine",
            "eval_async", "eval_freq", "eval_episodes")
DEFAULT_ENTRY = "default"  # zoo: the entry for env ids the file does not name
NOISE_KEYS = ("noise_type", "noise_std")
SCHEDULE_KEYS = ("learning_rate", "clip_range", "clip_range_vf")
# Constructor arguments that smartcar-train sets itself: what to use instead.
RESERVED_KEYS = {
    "seed": "use --seed",
    "device": "use --device",
    "verbose": "smartcar-train shows a progress bar and a summary instead",
    "tensorboard_log": "TensorBoard logs always go to <run-dir>/tb",
    "_init_setup_model": "it is internal to Stable-Baselines3",
    "normalize_kwargs": "it is not a key of the zoo format; VecNormalize's arguments go in "
                        "normalize itself, e.g. normalize: \"dict(norm_obs=True, "
                        "norm_reward=False)\"",
}
# VecNormalize arguments that normalize may set (training is set by smartcar-train).
NORMALIZE_KEYS = ("norm_obs", "norm_reward", "clip_obs", "clip_reward", "gamma", "epsilon",
                  "norm_obs_keys")


class HyperparamsError(ValueError):
    """A hyperparameter file or override is invalid (the message says where and why)."""


def algo_class(algo: str) -> type:
    """The SB3 algorithm class for ``algo`` ("ppo", "sac" or "td3")."""
    from stable_baselines3 import PPO, SAC, TD3

    classes = {"ppo": PPO, "sac": SAC, "td3": TD3}
    if algo not in classes:
        raise HyperparamsError(f"unknown algorithm {algo!r}; expected one of {', '.join(ALGOS)}")
    return classes[algo]


def default_hyperparams_file(algo: str) -> Path:
    """Path of the shipped ``config/<algo>.yaml``."""
    if algo not in ALGOS:
        raise HyperparamsError(f"unknown algorithm {algo!r}; expected one of {', '.join(ALGOS)}")
    return Path(str(resources.files("smartcar_gym") / "config" / f"{algo}.yaml"))


def load_hyperparams(algo: str, env_id: str, path: str | Path | None = None,
                     variant: str | Sequence[str] | None = None) -> dict[str, Any]:
    """The hyperparameters for ``env_id`` from ``path`` (default: the shipped ``<algo>.yaml``);
    its ``default`` entry if it has none for ``env_id``, as in rl-baselines3-zoo. A
    ``variant`` (``"batched"``, or several tried in order such as ``("batched-mujoco",
    "batched")``) picks the first entry ``<env_id>-<variant>`` the file has (rl-baselines3-zoo
    never reads those)."""
    path = Path(path) if path is not None else default_hyperparams_file(algo)
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as err:
        raise HyperparamsError(f"{path}: not valid YAML: {err}") from err
    if not isinstance(data, dict):
        raise HyperparamsError(f"{path}: expected a mapping of env id -> hyperparameters")
    key = env_id if env_id in data else DEFAULT_ENTRY
    variants = [variant] if isinstance(variant, str) else list(variant or [])
    for name in variants:
        if f"{env_id}-{name}" in data:
            key = f"{env_id}-{name}"
            break
    if key not in data:
        raise HyperparamsError(
            f"{path}: no hyperparameters for env {env_id!r} and no {DEFAULT_ENTRY!r} entry; it "
            f"has {', '.join(map(str, data))}"
        )
    entry = data[key]
    if not isinstance(entry, dict):
        raise HyperparamsError(f"{path}: entry {key!r} must be a mapping, got {entry!r}")
    return copy.deepcopy(entry)


def hyperparams_variant(vectorization: str, engine: str | None) -> tuple[str, ...] | None:
    """The ``variant`` of ``load_hyperparams`` for a run of ``vectorization`` on ``engine``
    (None: the default engine): a batched run's ``batched-<engine>``, then ``batched``
    entry; None (the env's own entry) for a subproc run."""
    if vectorization != "batched":
        return None
    return ("batched",) if engine is None else (f"batched-{engine}", "batched")


def parse_value(text: str) -> Any:
    """A command-line value as YAML (``3e-4`` is a float, ``[1, 2]`` a list, ``true`` a bool)."""
    try:
        value = yaml.safe_load(text) if text.strip() else ""
    except yaml.YAMLError:
        return text
    if isinstance(value, str):
        # YAML 1.1 reads "3e-4" (no dot) as a string; numbers are what is meant.
        for convert in (int, float):
            try:
                return convert(value)
            except ValueError:
                pass
    return value


def parse_key_value(text: str) -> tuple[str, Any]:
    """``"key=value"`` -> ``(key, parsed value)``; raises ``HyperparamsError`` if malformed."""
    key, sep, raw = text.partition("=")
    key = key.strip()
    if not sep or not key.isidentifier():
        raise HyperparamsError(
            f"expected key=value with a Python-identifier key (e.g. learning_rate=3e-4), "
            f"got {text!r}"
        )
    return key, parse_value(raw)


def parse_key_values(items: list[str] | None) -> dict[str, Any]:
    """A list of ``key=value`` strings as a dict (later keys win)."""
    return dict(parse_key_value(item) for item in items or [])


_MODULES = {"nn": "torch.nn", "th.nn": "torch.nn", "torch.nn": "torch.nn",
            "th.optim": "torch.optim", "torch.optim": "torch.optim"}


def _literal(node: ast.AST, source: str) -> Any:
    """Evaluate a small safe subset of Python: literals, ``dict(...)`` and ``nn.X`` classes."""
    if isinstance(node, ast.Constant):
        return node.value
    if isinstance(node, (ast.List, ast.Tuple)):
        items = [_literal(e, source) for e in node.elts]
        return items if isinstance(node, ast.List) else tuple(items)
    if isinstance(node, ast.Dict):
        pairs = zip(node.keys, node.values, strict=True)
        return {_literal(k, source): _literal(v, source) for k, v in pairs}
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
        return -_literal(node.operand, source)
    if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "dict"
            and not node.args):
        return {kw.arg: _literal(kw.value, source) for kw in node.keywords}
    if isinstance(node, ast.Attribute):
        module = ast.unparse(node.value)
        if module in _MODULES:
            import importlib

            obj = getattr(importlib.import_module(_MODULES[module]), node.attr, None)
            if isinstance(obj, type):
                return obj
    raise HyperparamsError(
        f"cannot read {ast.unparse(node)!r} in {source!r}: only literals, dict(...) and "
        "torch classes such as nn.ReLU or th.optim.Adam are allowed"
    )


def _torch_class(text: str) -> Any:
    module, _, name = text.rpartition(".")
    if module not in _MODULES:
        return text
    return _literal(ast.parse(text, mode="eval").body, text)


def parse_kwargs(value: str | dict[str, Any] | None, key: str) -> dict[str, Any]:
    """Keyword arguments from a dict or a zoo string like ``"dict(net_arch=[64, 64])"``
    (``key`` names the setting in errors)."""
    if value is None:
        return {}
    if isinstance(value, dict):
        # A YAML mapping may name torch classes as strings: {activation_fn: nn.Tanh}.
        return {k: _torch_class(v) if isinstance(v, str) else v for k, v in value.items()}
    if not isinstance(value, str):
        raise HyperparamsError(f"{key} must be a dict or a string, got {value!r}")
    try:
        tree = ast.parse(value, mode="eval")
    except SyntaxError as err:
        raise HyperparamsError(f"{key} {value!r} is not a Python expression") from err
    result = _literal(tree.body, value)
    if not isinstance(result, dict):
        raise HyperparamsError(f"{key} {value!r} must be a dict, got {result!r}")
    return result


def parse_policy_kwargs(value: str | dict[str, Any] | None) -> dict[str, Any]:
    """``policy_kwargs`` from a dict or a zoo string like ``"dict(net_arch=[64, 64])"``."""
    return parse_kwargs(value, "policy_kwargs")


def policy_class(hyperparams: dict[str, Any]) -> Any:
    """``policy``: a name SB3 knows (``MlpPolicy``) or, with a dot, the class at that path."""
    policy = hyperparams.get("policy", "MlpPolicy")
    if isinstance(policy, str) and "." in policy:
        from smartcar_gym.agents.zoo_keys import import_object

        return import_object(policy, "policy")
    if not isinstance(policy, str):
        raise HyperparamsError(f"policy must be a policy name or an import path, got {policy!r}")
    return policy


def normalize_kwargs(value: Any) -> dict[str, Any] | None:
    """VecNormalize keyword arguments from zoo's ``normalize`` (bool, dict or dict string)."""
    if value is None or value is False:
        return None
    if value is True:
        return {"norm_obs": True, "norm_reward": True}
    if isinstance(value, str):
        try:
            value = parse_kwargs(value, "normalize")
        except HyperparamsError as err:
            raise HyperparamsError(
                f"normalize must be true, false or a dict such as "
                f"\"dict(norm_obs=True, norm_reward=False)\", got {value!r}"
            ) from err
        return normalize_kwargs(value)
    if isinstance(value, dict):
        unknown = sorted(set(value) - set(NORMALIZE_KEYS))
        if unknown:
            raise HyperparamsError(f"normalize: unknown VecNormalize argument(s) "
                                   f"{', '.join(map(str, unknown))}; accepted: "
                                   f"{', '.join(NORMALIZE_KEYS)}")
        return {"norm_obs": True, "norm_reward": True, **value}
    raise HyperparamsError(f"normalize must be a bool or a dict, got {value!r}")


def vecnormalize_settings(hyperparams: dict[str, Any]) -> tuple[dict[str, Any] | None, float]:
    """VecNormalize's arguments (without ``gamma``) and its discount: the entry's ``gamma`` if
    it sets one (as the zoo does), else ``normalize``'s own, else 0.99."""
    normalize = normalize_kwargs(hyperparams.get("normalize"))
    if normalize is None:
        return None, discount(hyperparams)
    own = normalize.pop("gamma", None)
    if "gamma" in hyperparams or own is None:
        return normalize, discount(hyperparams)
    return normalize, discount({"gamma": own})


def discount(hyperparams: dict[str, Any]) -> float:
    """``gamma`` (default 0.99), also used by VecNormalize; raises ``HyperparamsError``."""
    gamma = hyperparams.get("gamma", 0.99)
    if isinstance(gamma, bool) or not isinstance(gamma, (int, float)) or not 0 <= gamma <= 1:
        raise HyperparamsError(f"gamma must be a number in [0, 1], got {gamma!r}")
    return float(gamma)


def _schedule(key: str, value: Any) -> Any:
    """zoo's ``lin_<start>`` strings as a linear decay to 0 over the run."""
    if isinstance(value, str) and value.startswith("lin_"):
        from stable_baselines3.common.utils import LinearSchedule

        try:
            start = float(value[4:])
        except ValueError as err:
            raise HyperparamsError(f"{key}: expected lin_<number>, got {value!r}") from err
        return LinearSchedule(start, 0.0, 1.0)
    if isinstance(value, str):
        raise HyperparamsError(f"{key}: expected a number or lin_<number>, got {value!r}")
    return value


def run_int(hyperparams: dict[str, Any], key: str, least: int = 1) -> int | None:
    """``hyperparams[key]`` as a whole number >= ``least`` (None if absent); ``2e5`` is
    allowed."""
    value = hyperparams.get(key)
    if value is None:
        return None
    if (isinstance(value, bool) or not isinstance(value, (int, float))
            or value != int(value) or value < least):
        raise HyperparamsError(f"{key} must be a whole number >= {least}, got {value!r}")
    return int(value)


def build_algo_kwargs(algo: str, hyperparams: dict[str, Any], n_actions: int) -> dict[str, Any]:
    """Constructor keyword arguments for the SB3 algorithm from a zoo entry (RUN_KEYS dropped)."""
    cls = algo_class(algo)
    kwargs = {k: v for k, v in hyperparams.items() if k not in RUN_KEYS + NOISE_KEYS}
    reserved = sorted(set(kwargs) & set(RESERVED_KEYS))
    if reserved:
        raise HyperparamsError("; ".join(
            f"hyperparameter {key} cannot be set: {RESERVED_KEYS[key]}" for key in reserved
        ))
    accepted = (set(inspect.signature(cls.__init__).parameters) - {"self", "policy", "env"}
                - set(RESERVED_KEYS))
    unknown = sorted(set(kwargs) - accepted)
    if unknown:
        raise HyperparamsError(
            f"unknown hyperparameter(s) for {algo}: {', '.join(unknown)}; "
            f"{cls.__name__} accepts {', '.join(sorted(accepted))} "
            f"(plus {', '.join(RUN_KEYS + NOISE_KEYS)})"
        )
    for key in SCHEDULE_KEYS:
        if key in kwargs:
            kwargs[key] = _schedule(key, kwargs[key])
    for key in ("policy_kwargs", "replay_buffer_kwargs"):
        if key in kwargs:
            kwargs[key] = parse_kwargs(kwargs[key], key)
    if isinstance(kwargs.get("replay_buffer_class"), str):
        kwargs["replay_buffer_class"] = _buffer_class(kwargs["replay_buffer_class"])
    if isinstance(kwargs.get("train_freq"), list):
        kwargs["train_freq"] = tuple(kwargs["train_freq"])
    noise_type = hyperparams.get("noise_type")
    if noise_type is not None:
        import numpy as np
        from stable_baselines3.common.noise import NormalActionNoise, OrnsteinUhlenbeckActionNoise

        noises = {"normal": NormalActionNoise, "ornstein-uhlenbeck": OrnsteinUhlenbeckActionNoise}
        if noise_type not in noises:
            raise HyperparamsError(
                f"noise_type must be one of {', '.join(noises)}, got {noise_type!r}"
            )
        std = float(hyperparams.get("noise_std", 0.1))
        kwargs["action_noise"] = noises[noise_type](
            mean=np.zeros(n_actions), sigma=std * np.ones(n_actions)
        )
    return kwargs


def _buffer_class(name: str) -> type:
    """``replay_buffer_class``: an SB3 buffer name (``HerReplayBuffer``) or an import path."""
    from smartcar_gym.agents.zoo_keys import import_object

    if "." not in name:
        import stable_baselines3
        from stable_baselines3.common import buffers

        found = getattr(stable_baselines3, name, None) or getattr(buffers, name, None)
        if not isinstance(found, type):
            raise HyperparamsError(f"replay_buffer_class: Stable-Baselines3 has no buffer "
                                   f"{name!r}; give an import path such as module.Name")
        return found
    return import_object(name, "replay_buffer_class")
