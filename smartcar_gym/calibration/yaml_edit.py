"""Write a calibrated arbotix YAML: the same file with two values changed, comments kept.

The values are replaced in the text where YAML's parser found them (block or flow style, quoted
or not), so the layout and every comment stay as they were; a comment at the top says what was
changed, from what, and how.
"""

from __future__ import annotations

import warnings

import yaml

from smartcar_gym.controller import ArbotixConfig, parse_controller_config
from smartcar_gym.controller.config_yaml import parse_yaml


def _value_node(mapping: yaml.Node, key: str, where: str) -> yaml.Node:
    if isinstance(mapping, yaml.MappingNode):
        for key_node, value_node in mapping.value:
            if isinstance(key_node, yaml.ScalarNode) and key_node.value == key:
                return value_node
    raise ValueError(f"{where}: no {key!r} found to replace")


def format_values(base_width_m: float, ticks_meter: float) -> tuple[str, str]:
    """How the two values are written: 0.1 mm of track, 0.1 tick per metre."""
    return f"{base_width_m:.4f}", f"{round(ticks_meter, 1):g}"


def calibrated_text(text: str, config: ArbotixConfig, base_width_m: float, ticks_meter: float,
                    note: str) -> str:
    """``text`` (the YAML ``config`` was read from) with ``base_width`` and ``ticks_meter``
    of its diff_controller replaced, and ``note`` (lines) as a comment at the top.

    The result is read back and checked to hold the new values.
    """
    source = config.source
    root = yaml.compose(text, Loader=yaml.SafeLoader)
    controller = _value_node(_value_node(root, "controllers", source), config.name,
                             f"{source}: controllers")
    where = f"{source}: controllers.{config.name}"
    width, ticks = format_values(base_width_m, ticks_meter)
    nodes = sorted(((_value_node(controller, "base_width", where), width),
                    (_value_node(controller, "ticks_meter", where), ticks)),
                   key=lambda item: item[0].start_mark.index, reverse=True)
    out = text
    for node, value in nodes:  # from the end, so that earlier indices stay valid
        out = out[:node.start_mark.index] + value + out[node.end_mark.index:]
    header = "".join(f"# {line}".rstrip() + "\n" for line in note.splitlines())
    out = header + out
    with warnings.catch_warnings():  # the same warnings as when it was read: said already
        warnings.simplefilter("ignore")
        check = parse_controller_config(parse_yaml(out, source), source)
    if (f"{check.base_width_m:.4f}", f"{round(check.ticks_meter, 1):g}") != (width, ticks):
        raise ValueError(f"{source}: the calibrated file does not read back as written")
    return out
