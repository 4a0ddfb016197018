"""What an exported policy says about itself: the env it acts in and where it came from.

``smartcar-export`` writes this dict twice: as the ONNX model's metadata property
``METADATA_KEY`` (what ``Policy.load`` reads, so the ``.onnx`` file alone is enough) and as
``<name>.json`` beside the model (``side_file``), for people and other tools.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

__all__ = ["FORMAT", "METADATA_KEY", "REQUIRED_KEYS", "check_metadata", "side_file"]

METADATA_KEY = "smartcar_gym"
FORMAT = "smartcar-gym policy 1"
#: the keys ``Policy.load`` needs
REQUIRED_KEYS = ("format", "algo", "env_id", "env_kwargs", "engine", "observation_names",
                 "observation_shape", "action_shape", "input", "output", "versions")


def side_file(model_path: str | Path) -> Path:
    """The metadata file beside a model: ``policy.json`` for ``policy.onnx``."""
    return Path(model_path).with_suffix(".json")


def check_metadata(text: str | None, where: str) -> dict[str, Any]:
    """The metadata of the model at ``where`` from its JSON ``text``; ``ValueError`` with
    one line when it is missing, not JSON, or lacks a key."""
    if text is None:
        raise ValueError(f"{where} has no {METADATA_KEY!r} metadata property: it was not "
                         "written by smartcar-export, so the env it acts in is unknown")
    try:
        data = json.loads(text)
    except ValueError as err:
        raise ValueError(f"{where}: its {METADATA_KEY!r} metadata is not JSON ({err})") from None
    missing = [key for key in REQUIRED_KEYS if not isinstance(data, dict) or key not in data]
    if missing:
        raise ValueError(f"{where}: its {METADATA_KEY!r} metadata lacks "
                         f"{', '.join(missing)}")
    if data["format"] != FORMAT:
        raise ValueError(f"{where}: metadata format {data['format']!r}; this version reads "
                         f"{FORMAT!r}")
    return data
