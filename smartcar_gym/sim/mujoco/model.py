"""One robot as MuJoCo sees it: its URDF compiled by MuJoCo's own URDF importer into an MjSpec.

``car_spec`` reads the URDF the pybullet body loads (``model.contact.simulated_urdf``: the same
masses, inertias and wheel collision shapes) with ``fusestatic`` off (so ``base_link`` and the
fixed links keep their names and the root can move) and gives the root link a free joint.
Geoms are sorted into groups the facade relies on:

* ``GROUP_WORLD`` (0): the ground and static obstacles;
* ``GROUP_COLLISION`` (1): the robot's collision shapes (what rays hit);
* ``GROUP_VISUAL`` (2): the robot's visuals (rendered, never collide, never hit by rays);
* ``GROUP_HIDDEN`` (3): collision shapes hidden from rays (``Body.hide_from_rays``).

Robot collision geoms get ``priority`` 1, ``condim`` 3 (sliding friction only, as pybullet's
default contact) and ``CONTACT_SOLREF`` / ``CONTACT_SOLIMP``: in a contact with the ground or an
obstacle the robot's geom decides all contact parameters, and the facade sets its friction to
the product of the two bodies' coefficients (pybullet's rule).
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import mujoco

from smartcar_gym.model.contact import DEFAULT_FRICTION  # noqa: F401 (pybullet's default)
from smartcar_gym.model.errors import ModelError

GROUP_WORLD, GROUP_COLLISION, GROUP_VISUAL, GROUP_HIDDEN = 0, 1, 2, 3
ROBOT_PRIORITY = 1
#: the robot's contacts' (time constant s, damping ratio): stiffer than MuJoCo's (0.02, 1)
CONTACT_SOLREF = (0.005, 1.0)
#: the robot's contacts' solver impedance: harder than MuJoCo's (0.9, 0.95, 0.001, 0.5, 2)
CONTACT_SOLIMP = (0.95, 0.99, 0.001, 0.5, 2.0)
#: MuJoCo's compiler options for our URDFs: keep the fixed links, keep primitive visuals
_COMPILER = '<mujoco><compiler fusestatic="false" discardvisual="{discard}"/></mujoco>'
_VISUAL_MESH = re.compile(r"<visual\b(?:(?!</visual>).)*<mesh\b", re.S)


def car_spec(urdf_path: str | os.PathLike, free: bool = True) -> mujoco.MjSpec:
    """The MjSpec of the robot in ``urdf_path``: its root link with a free joint (unless not
    ``free``), geoms sorted into the groups above.

    Visuals are kept when they are all primitives (MuJoCo reads no .dae); otherwise the
    collision shapes stand in for them in pictures. A file MuJoCo cannot read or compile
    raises ``ModelError`` naming the file and MuJoCo's reason.
    """
    path = Path(urdf_path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ModelError(f"cannot read the URDF for MuJoCo: {exc.strerror}", file=path) from None
    return car_spec_from_text(text, path, free)


def car_spec_from_text(text: str, source: str | os.PathLike, free: bool = True) -> mujoco.MjSpec:
    """``car_spec`` of URDF ``text`` (e.g. ``model.contact.simulated_urdf(model)``); relative
    mesh paths are read from ``source``'s folder, errors name ``source``."""
    path = Path(source)
    discard = "true" if _VISUAL_MESH.search(text) else "false"
    text = re.sub(r"(<robot\b[^>]*>)", lambda m: m.group(1) + _COMPILER.format(discard=discard),
                  text, count=1)
    try:
        spec = mujoco.MjSpec.from_string(text)
        spec.modelfiledir = str(path.parent)
        spec.compile()  # refuse a model MuJoCo cannot compile here, naming the file
    except ValueError as exc:
        reason = " ".join(str(exc).split())
        raise ModelError(f"MuJoCo cannot compile this URDF: {reason}", file=path) from None
    root = spec.worldbody.first_body()
    if root is None:
        raise ModelError("MuJoCo found no link in this URDF", file=path)
    if free:
        root.add_freejoint()
    for geom in spec.geoms:
        if geom.contype == 0 and geom.conaffinity == 0:
            geom.group = GROUP_VISUAL
        else:
            geom.group = GROUP_COLLISION
            geom.priority = ROBOT_PRIORITY
            geom.condim = 3
            geom.solref, geom.solimp = CONTACT_SOLREF, CONTACT_SOLIMP
    return spec


def link_frictions(urdf_path: str | os.PathLike) -> dict[str, float]:
    """Each link's lateral friction coefficient as pybullet reads it (``model.contact``)."""
    from smartcar_gym.model.contact import link_frictions as read

    return read(Path(urdf_path).read_text(encoding="utf-8"), str(urdf_path))


def has_visuals(spec: mujoco.MjSpec) -> bool:
    """True if the robot spec kept its visual geoms."""
    return any(g.group == GROUP_VISUAL for g in spec.geoms)
