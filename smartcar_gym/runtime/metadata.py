"""What an exported policy says about itself: the env it acts in and where it came from.

``smartcar-export`` writes this dict twice: as the ONNX model's metadata property
``METADATA_KEY`` (what ``Policy.load`` reads, so the ``.onnx`` file alone is enough) and as
``<name>.json`` beside the model (``side_file``), for people and other tools. Whoever reads
either reads it with ``check_metadata``: every key's type and shape is checked, and the env
with ``registration.check_policy_env``, before anything is imported or built for it.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from smartcar_gym.registration import check_policy_env

__all__ = ["FORMAT", "METADATA_KEY", "REQUIRED_KEYS", "check_metadata", "side_file"]

METADATA_KEY = "smartcar_gym"
FORMAT = "smartcar-gym policy 1"
#: the keys ``Policy.load`` needs
REQUIRED_KEYS = ("format", "algo", "env_id", "env_kwargs", "engine", "observation_names",
                 "observation_shape", "action_shape", "action_low", "action_high", "input",
                 "output", "versions")


def side_file(model_path: str | Path) -> Path:
    """The metadata file beside a model: ``policy.json`` for ``policy.onnx``."""
    return Path(model_path).with_suffix(".json")


def _is_text(value: Any) -> bool:
    return isinstance(value, str) and bool(value)


def _is_size(value: Any) -> bool:
    return type(value) is int and value > 0


def _is_number(value: Any) -> bool:
    return type(value) in (int, float) and math.isfinite(value)


#: key -> (whether its value is right, what was expected); env_id, env_kwargs and engine are
#: ``check_policy_env``'s, action_low and action_high checked against action_shape after
_TYPES = {
    "format": (_is_text, "a string"),
    "algo": (_is_text, "a string (ppo, sac, td3)"),
    "input": (_is_text, "the graph input's name (a string)"),
    "output": (_is_text, "the graph output's name (a string)"),
    "observation_names": (lambda v: isinstance(v, list) and all(isinstance(n, str) for n in v),
                          "a list of strings"),
    "observation_shape": (lambda v: isinstance(v, list) and len(v) == 1 and _is_size(v[0]),
                          "[D], one whole number > 0"),
    "action_shape": (lambda v: isinstance(v, list) and len(v) == 1 and _is_size(v[0]),
                     "[A], one whole number > 0"),
    "versions": (lambda v: isinstance(v, dict) and all(
        isinstance(x, str) or x is None for x in v.values()), "a mapping of package names to "
        "version strings (or null)"),
    "source": (lambda v: isinstance(v, str), "a string"),
    "normalizer": (lambda v: isinstance(v, str), "a string"),
}


def check_metadata(text: str | None, where: str) -> dict[str, Any]:
    """The metadata of the model at ``where`` (an ONNX file's property, or its ``.json``)
    from its JSON ``text``; ``ValueError`` with one line naming the key and what was expected
    when it is missing, not JSON, lacks a key or has one of the wrong type or shape, or names
    an env that ``check_policy_env`` refuses."""
    if text is None:
        raise ValueError(f"{where} has no {METADATA_KEY!r} metadata property: it was not "
                         "written by smartcar-export, so the env it acts in is unknown")
    try:
        data = json.loads(text)
    except (ValueError, RecursionError) as err:
        raise ValueError(f"{where}: its {METADATA_KEY!r} metadata is not JSON ({err})") from None
    if not isinstance(data, dict):
        raise ValueError(f"{where}: its {METADATA_KEY!r} metadata is a "
                         f"{type(data).__name__}; expected a JSON object")
    missing = [key for key in REQUIRED_KEYS if key not in data]
    if missing:
        raise ValueError(f"{where}: its {METADATA_KEY!r} metadata lacks "
                         f"{', '.join(missing)}")
    if data["format"] != FORMAT:
        raise ValueError(f"{where}: metadata format {data['format']!r}; this version reads "
                         f"{FORMAT!r}")
    for key, (right, expected) in _TYPES.items():
        if key in data and not right(data[key]):
            raise ValueError(f"{where}: metadata {key} is {_short(data[key])}; expected "
                             f"{expected}")
    size = data["action_shape"][0]
    for key in ("action_low", "action_high"):
        value = data[key]
        if not (isinstance(value, list) and len(value) == size
                and all(_is_number(v) for v in value)):
            raise ValueError(f"{where}: metadata {key} is {_short(value)}; expected a list of "
                             f"{size} finite numbers (action_shape {data['action_shape']})")
    if any(lo > hi for lo, hi in zip(data["action_low"], data["action_high"], strict=True)):
        raise ValueError(f"{where}: metadata action_low {data['action_low']} lies above "
                         f"action_high {data['action_high']}; expected low <= high")
    if len(data["observation_names"]) != data["observation_shape"][0]:
        raise ValueError(f"{where}: metadata names {len(data['observation_names'])} "
                         f"observations but observation_shape is {data['observation_shape']}; "
                         "expected one name a value")
    data["env_id"], data["env_kwargs"] = check_policy_env(
        f"{where}: metadata", data["env_id"], data["env_kwargs"], data["engine"])
    return data


def _short(value: Any) -> str:
    """``value`` for a message: its repr, cut to one short piece."""
    text = " ".join(repr(value).split())
    return text if len(text) <= 60 else f"{text[:57]}..."
