"""Read an ArbotiX driver YAML file strictly: a key given twice in one mapping is an error.

PyYAML keeps the last of two equal keys without a word (``ticks_meter: 4100`` and, further
down, ``ticks_meter: 10``: the car never moves), and so does roslaunch, which uses PyYAML.
"""

from __future__ import annotations

import os
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

from smartcar_gym.controller.config_values import ControllerConfigError

DEFAULT_CONFIG = "smartcar_arbotix.yaml"
CALIBRATED_CONFIG = "smartcar_arbotix_calibrated.yaml"  # base_width 0.33: SmartCarNav-v0's
_MERGE = "tag:yaml.org,2002:merge"


def default_config_path() -> str:
    """Path of the shipped ``smartcar_gym/config/smartcar_arbotix.yaml``."""
    return str(resources.files("smartcar_gym") / "config" / DEFAULT_CONFIG)


def calibrated_config_path() -> str:
    """Path of the shipped ``smartcar_arbotix_calibrated.yaml`` (odometry calibrated:
    ``base_width`` 0.33 m, the car's effective track; everything else as the shipped one)."""
    return str(resources.files("smartcar_gym") / "config" / CALIBRATED_CONFIG)


def _shown(node: yaml.Node) -> str:
    if isinstance(node, yaml.ScalarNode):
        return repr(node.value) if node.value == "" else node.value
    return "a mapping" if isinstance(node, yaml.MappingNode) else "a list"


class UniqueKeyLoader(yaml.SafeLoader):
    """PyYAML's ``SafeLoader`` that refuses a key repeated in one mapping (``<<`` merges, whose
    keys a mapping may override, are left to YAML). ``source`` names the file in errors."""

    source = "<string>"

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict:
        seen: dict[Any, tuple[yaml.Node, yaml.Node]] = {}
        for key_node, value_node in node.value:
            if not isinstance(key_node, yaml.ScalarNode) or key_node.tag == _MERGE:
                continue  # a list or mapping as a key: SafeLoader refuses it itself
            key = self.construct_object(key_node)
            if key in seen:
                first_key, first_value = seen[key]
                line, again = first_key.start_mark.line + 1, key_node.start_mark.line + 1
                lines = f"line {line}" if line == again else f"lines {line} and {again}"
                raise ControllerConfigError(
                    f"{self.source}:{again}: key {key!r} given twice in one mapping, on {lines} "
                    f"({first_key.value}: {_shown(first_value)}, then "
                    f"{key_node.value}: {_shown(value_node)}); YAML would keep the last one "
                    "without a word; expected each key once"
                )
            seen[key] = (key_node, value_node)
        return super().construct_mapping(node, deep=deep)


def parse_yaml(text: str, source: str) -> Any:
    """The YAML document in ``text``; ControllerConfigError on a syntax error or repeated key."""
    loader = UniqueKeyLoader(text)
    loader.source = source
    try:
        return loader.get_single_data()
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        where = f"{source}:{mark.line + 1}:{mark.column + 1}" if mark else source
        problem = getattr(err, "problem", None) or str(err)
        raise ControllerConfigError(f"{where}: YAML syntax error: {problem}") from None
    finally:
        loader.dispose()


def read_config_file(path: str | os.PathLike[str] | None) -> tuple[str, str]:
    """(text, source) of the controller config at ``path`` (None: the shipped one); a clear
    ControllerConfigError for a path that is empty, a directory, missing, unreadable, not UTF-8.
    """
    if path is None:
        source = default_config_path()
        shipped = resources.files("smartcar_gym") / "config" / DEFAULT_CONFIG
        return shipped.read_text("utf-8"), source
    if not isinstance(path, str | os.PathLike):
        raise TypeError(
            f"controller config path={path!r}: expected the path (str or os.PathLike) of an "
            f"ArbotiX driver YAML file, or None for the shipped {DEFAULT_CONFIG}"
        )
    source = os.fspath(path)
    if not str(source).strip():
        raise ControllerConfigError(
            f"controller config path is empty ({source!r}); expected the path of an ArbotiX "
            f"driver YAML file, or None for the shipped {DEFAULT_CONFIG}"
        )
    if os.path.isdir(source):
        found = sorted(p.name for p in Path(source).iterdir()
                       if p.is_file() and p.suffix.lower() in (".yaml", ".yml"))
        held = f"it holds {', '.join(found)}" if found else "it holds no .yaml file"
        raise ControllerConfigError(
            f"{source}: is a directory; expected an ArbotiX driver YAML file; {held}"
        )
    try:
        with open(source, encoding="utf-8") as stream:
            return stream.read(), str(source)
    except FileNotFoundError:
        raise ControllerConfigError(f"{source}: controller config file not found") from None
    except UnicodeDecodeError as err:
        raise ControllerConfigError(
            f"{source}: not UTF-8 text (byte {err.start}): expected an ArbotiX driver YAML"
        ) from None
    except OSError as err:
        raise ControllerConfigError(f"{source}: cannot read: {err.strerror}") from None
