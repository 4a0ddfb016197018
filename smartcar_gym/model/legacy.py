"""Upgrade ROS-indigo-era xacro, whose tags had no ``xacro:`` prefix, for today's xacro.

Indigo's xacro accepted ``<property>``, ``<include>``, ``<macro>``... and calls of defined
macros (``<smartcar_body/>``) without the ``xacro:`` prefix. Today's xacro passes them through
as plain XML, so such a file expands to a robot without links. We rename the tags on the
parsed DOM (line numbers of the source stay valid) and collect what was renamed per file, to
emit one :class:`LegacyXacroWarning` per file.
"""

from __future__ import annotations

import warnings
import xml.dom.minidom
from collections.abc import Iterable

from smartcar_gym.model.errors import LegacyXacroWarning

#: Unprefixed tag -> attribute it must carry to count as xacro (guards plain XML look-alikes).
LEGACY_TAGS: dict[str, str] = {
    "property": "name",
    "include": "filename",
    "macro": "name",
    "arg": "name",
    "if": "value",
    "unless": "value",
    "insert_block": "name",
    "call": "macro",
    "element": "xacro:name",
    "attribute": "name",
}

#: URDF and Gazebo-extension element names never taken for an unprefixed macro call.
URDF_ELEMENTS = frozenset(
    "robot link joint inertial origin mass inertia visual collision geometry box cylinder "
    "sphere capsule mesh material color texture parent child axis calibration dynamics limit "
    "mimic safety_controller transmission type actuator hardwareInterface mechanicalReduction "
    "gazebo plugin sensor ros2_control hardware param state_interface command_interface "
    "version".split()
)


def legacy_tag_names(tags: Iterable[str]) -> list[str]:
    """The unprefixed xacro tag names among ``tags``, unique, in order of appearance."""
    found: list[str] = []
    for tag in tags:
        if tag in LEGACY_TAGS and tag not in found:
            found.append(tag)
    return found


def upgrade_tags(doc: xml.dom.minidom.Document) -> list[str]:
    """Prefix the unprefixed xacro tags of ``doc`` in place; return the tag names renamed."""
    renamed: list[str] = []
    stack = [doc.documentElement]
    while stack:
        node = stack.pop()
        tag = node.tagName
        if tag in LEGACY_TAGS and node.hasAttribute(LEGACY_TAGS[tag]):
            node.tagName = node.nodeName = f"xacro:{tag}"
            renamed.append(tag)
        children = [c for c in node.childNodes if c.nodeType == c.ELEMENT_NODE]
        stack.extend(reversed(children))
    return renamed


def is_call_candidate(tag: str) -> bool:
    """Whether an element named ``tag`` may be an unprefixed call (if such a macro exists)."""
    return ":" not in tag and tag not in URDF_ELEMENTS and tag not in LEGACY_TAGS


class LegacyReport:
    """What was upgraded, per file, in the order files were read."""

    def __init__(self) -> None:
        self.tags: dict[str, list[str]] = {}
        self.calls: dict[str, list[str]] = {}

    def add_tags(self, file: str, tags: Iterable[str]) -> None:
        """Record renamed structural tags of ``file``."""
        self.tags.setdefault(file, []).extend(tags)

    def add_call(self, file: str, macro: str) -> None:
        """Record an unprefixed call of ``macro`` found in ``file``."""
        self.calls.setdefault(file, []).append(macro)

    def messages(self) -> list[str]:
        """One message per file that needed upgrading."""
        result = []
        for file in dict.fromkeys([*self.tags, *self.calls]):
            parts = []
            tags = list(dict.fromkeys(self.tags.get(file, [])))
            calls = list(dict.fromkeys(self.calls.get(file, [])))
            if tags:
                parts.append("tags " + ", ".join(f"<{t}>" for t in tags))
            if calls:
                parts.append("macro calls " + ", ".join(f"<{c}/>" for c in calls))
            if parts:
                result.append(
                    f"{file}: ROS-indigo xacro: added the xacro: prefix to {' and '.join(parts)}"
                    " (today's xacro ignores unprefixed tags); update the file"
                )
        return result

    def warn(self) -> None:
        """Emit one LegacyXacroWarning per upgraded file."""
        for message in self.messages():
            warnings.warn(message, LegacyXacroWarning, stacklevel=4)
